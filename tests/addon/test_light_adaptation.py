"""Light adaptation across frames: the twin's formula, the "OLS Tone Mapping" group with a
previous luminance and a weight vs the twin, and animations rendered headless (one animation job,
and frame by frame) vs the twin applied to the raw frames in sequence."""
import math
from pathlib import Path

import numpy as np
import pytest

from render_util import render_rgb
from scenes import composite, hdr_ramp, sample_scene
from extension import extension_module, names

bpy = pytest.importorskip("bpy")
FPS = 4                       # 1/4 s per frame: weight 1 - exp(-0.25) = 0.22, well away from 0 and 1
FRAMES = (1, 2, 3)
SUN_STRENGTH = (10.0, 80.0, 80.0)   # the sun's strength jumps 8x after frame 1



def test_twin_adapts_the_average_luminance(addon_package):
    twin = extension_module("lut_gen.passes.tone_mapping")
    assert twin.adaptation_weight(0.0) == 0.0
    assert twin.adaptation_weight(0.25) == pytest.approx(1 - math.exp(-0.25))
    assert twin.adaptation_weight(1e3) == pytest.approx(1.0)
    assert twin.adapt(0.1, 0.5, 0.25) == pytest.approx(0.2)
    assert twin.adapted_luminance(0.1, 0.5, 0.25) == pytest.approx(0.1 + 0.4 * (1 - math.exp(-0.25)))
    rgb = hdr_ramp()
    measured = twin.log_average_luminance(rgb)
    adapted = twin.tone_map(rgb, "REINHARD", average_luminance=measured, previous_luminance=0.02,
                            adaptation_weight=0.3)
    want = twin.tone_map(rgb, "REINHARD", average_luminance=twin.adapt(0.02, measured, 0.3))
    np.testing.assert_allclose(adapted, want)
    plain = twin.tone_map(rgb, "REINHARD", average_luminance=measured)
    np.testing.assert_allclose(twin.tone_map(rgb, "REINHARD", average_luminance=measured,
                                             previous_luminance=0.02, adaptation_weight=1.0), plain)
    assert np.abs(adapted - plain).max() > 0.05          # a darker previous frame over-exposes


def test_inputs_follow_a_sequence_of_frames(addon_package):
    adaptation = extension_module("addon.scene.frame.adaptation")
    twin = extension_module("lut_gen.passes.tone_mapping")
    inputs = lambda frame, last, **kw: adaptation.inputs_for_frame(  # noqa: E731
        frame, last, 0.3, **{"enabled": True, "frame_step": 1, "seconds_per_frame": 0.25, **kw})
    assert inputs(5, 4) == (0.3, pytest.approx(1 - math.exp(-0.25)))
    assert inputs(5, 4, enabled=False)[1] == 1.0
    for last in (None, 5, 6, 2):                # nothing before, a re-render, backwards, a jump
        assert inputs(5, last) == (twin.FIXED_AVERAGE_LUMINANCE, 1.0)
    assert inputs(7, 4, frame_step=3)[1] == pytest.approx(1 - math.exp(-0.75))
    assert adaptation.frame_seconds(24, 1.001) == pytest.approx(1.001 / 24)


@pytest.mark.parametrize("pixel_type", ["FLOAT", "HALF"])
def test_reads_the_pixel_of_an_uncompressed_exr(addon_package, tmp_path, pixel_type):
    OpenEXR = pytest.importorskip("OpenEXR")
    adaptation = extension_module("addon.scene.frame.adaptation")
    dtype = np.float32 if pixel_type == "FLOAT" else np.float16
    path = tmp_path / "one.exr"
    header = {"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"V": np.full((3, 2), 0.1234, dtype)}) as exr:
        exr.write(str(path))
    assert adaptation.read_exr_pixel(path) == pytest.approx(float(dtype(0.1234)))
    header["compression"] = OpenEXR.ZIP_COMPRESSION
    with OpenEXR.File(header, {"V": np.full((3, 2), 0.5, dtype)}) as exr:
        exr.write(str(tmp_path / "zip.exr"))
    with pytest.raises(ValueError):
        adaptation.read_exr_pixel(tmp_path / "zip.exr")


@pytest.mark.parametrize("auto_exposure", [True, False])
def test_group_with_adaptation_matches_the_twin(addon_package, tmp_path, auto_exposure):
    twin = extension_module("lut_gen.passes.tone_mapping")
    rgb = hdr_ramp()
    measured = twin.log_average_luminance(rgb) if auto_exposure else twin.FIXED_AVERAGE_LUMINANCE
    for operator, previous, weight in (("UNCHARTED2", 0.02, 0.3), ("REINHARD", 3.0, 0.6)):
        got = composite(addon_package, tmp_path, rgb, **{
            "Operator": float(twin.OPERATORS.index(operator)), "Auto Exposure": float(auto_exposure),
            "Previous Luminance": previous, "Adaptation Weight": weight})
        want = twin.tone_map(rgb, operator, average_luminance=measured, previous_luminance=previous,
                             adaptation_weight=weight)
        plain = twin.tone_map(rgb, operator, average_luminance=measured)
        err = np.abs(twin.srgb_encode(got) - twin.srgb_encode(want)).max()
        assert err <= 1e-3, (operator, err)
        assert np.abs(twin.srgb_encode(want) - twin.srgb_encode(plain)).max() > 0.1


def read_exr(path):
    import OpenEXR
    with OpenEXR.File(str(path)) as exr:
        return np.asarray(exr.channels()["RGBA"].pixels[..., :3], dtype=np.float64)


def animated_scene(pkg, tmp_path):
    """The wired sample at 32 x 18 px, tone mapping alone, the sun 8x brighter from frame 2 on."""
    scene = sample_scene(pkg)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    scene.ols.enable_light_scattering = False         # the tone mapping alone (aerial: test_aerial_pass)
    scene.ols.tone_map_exr = True                     # the frames are read back as OpenEXR
    scene.render.resolution_x, scene.render.resolution_y = 32, 18
    scene.cycles.samples = 2
    scene.cycles.seed = 1
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    sun = extension_module("addon.scene.sun").find_sun(scene)
    for frame, strength in zip(FRAMES, SUN_STRENGTH):
        sun.data.energy = strength
        sun.data.keyframe_insert("energy", frame=frame)
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    return scene


def raw_frames(scene, tmp_path):
    frames = []
    for frame in FRAMES:
        scene.frame_set(frame)
        frames.append(render_rgb(scene, tmp_path / f"raw_{frame}.exr"))
    return frames


def twin_sequence(twin, raw, adapt: bool):
    """Tone-mapped frames (Uncharted 2, auto exposure) and the luminance each used."""
    weight = twin.adaptation_weight(1.0 / FPS)
    out, used, previous = [], [], None
    for rgb in raw:
        measured = twin.log_average_luminance(rgb)
        average = measured if previous is None or not adapt else twin.adapt(previous, measured, weight)
        out.append(twin.tone_map(rgb, "UNCHARTED2", average_luminance=average))
        used.append(average)
        previous = average
    return out, used


def render_animation(scene, tmp_path, name, frames=FRAMES):
    scene.render.use_compositing = True
    scene.render.filepath = str(tmp_path / f"{name}_####")
    scene.frame_start, scene.frame_end = frames[0], frames[-1]
    bpy.ops.render.render(animation=True)
    return [read_exr(tmp_path / f"{name}_{frame:04d}.exr") for frame in frames]


def render_frame_by_frame(scene, tmp_path, name, frames=FRAMES):
    out = []
    for frame in frames:
        scene.frame_set(frame)
        out.append(render_rgb(scene, tmp_path / f"{name}_{frame}.exr", composite=True))
    return out


def assert_frames_match(twin, got, want, label):
    for frame, g, w in zip(FRAMES, got, want):
        err = np.abs(twin.srgb_encode(g) - twin.srgb_encode(w)).max()
        assert err <= 2e-3, (label, frame, err)


def test_animation_adapts_to_a_brightness_jump(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    twin = extension_module("lut_gen.passes.tone_mapping")
    scene = animated_scene(addon_package, tmp_path)
    tone = scene.compositing_node_group.nodes["OLS Tone Mapping"]
    raw = raw_frames(scene, tmp_path)
    adapted, used = twin_sequence(twin, raw, adapt=True)
    plain, _ = twin_sequence(twin, raw, adapt=False)
    # The jump is seen: frame 2 adapted is brighter than frame 2 exposed for its own luminance.
    assert twin.srgb_encode(adapted[1]).mean() > twin.srgb_encode(plain[1]).mean() + 0.1
    assert 0.05 < twin.srgb_encode(plain[0]).mean() < 0.95

    scene.ols.light_adaptation = True
    got = render_animation(scene, tmp_path, "on")
    assert_frames_match(twin, got, adapted, "animation")
    assert scene[names.ADAPTED_FRAME_KEY] == FRAMES[-1]
    assert scene[names.ADAPTED_LUMINANCE_KEY] == pytest.approx(used[-1], rel=1e-3)
    assert tone.inputs["Adaptation Weight"].default_value == 1.0      # the viewport sees the plain frame

    assert_frames_match(twin, render_frame_by_frame(scene, tmp_path, "stills"), adapted, "frame by frame")

    # An animation rendered in two jobs continues where the first one stopped.
    split = render_animation(scene, tmp_path, "first", FRAMES[:2]) + render_animation(scene, tmp_path, "second", FRAMES[2:])
    assert_frames_match(twin, split, adapted, "two jobs")

    # Frames that do not follow each other start afresh.
    jump = render_frame_by_frame(scene, tmp_path, "jump", frames=(1, 3))
    assert np.abs(twin.srgb_encode(jump[1]) - twin.srgb_encode(plain[2])).max() <= 2e-3

    scene.ols.light_adaptation = False
    assert_frames_match(twin, render_animation(scene, tmp_path, "off"), plain, "adaptation off")

    # The luminance files are read and removed; unwiring removes the File Output node and the state.
    output = scene.compositing_node_group.nodes[names.ADAPTED_LUMINANCE_NODE]
    assert not list(Path(output.directory).glob("*.exr"))
    extension_module("addon.scene.setup.wiring").unwire_scene(scene)
    assert names.ADAPTED_FRAME_KEY not in scene and names.ADAPTED_LUMINANCE_KEY not in scene


def test_plan_arithmetic(addon_package):
    plan_mod = extension_module("addon.scene.frame.adaptation_plan")
    adaptation = extension_module("addon.scene.frame.adaptation")
    twin = extension_module("lut_gen.passes.tone_mapping")
    assert plan_mod.adapted_sequence([1.0, 3.0, 3.0], 0.5) == [1.0, 2.0, 2.5]
    plan = plan_mod.check_plan(dict(version=1, start=10, end=14, step=2, weight=0.5, adapted=[1.0, 2.0, 2.5],
                                    signature="x"))
    assert adaptation.inputs_from_plan(plan, 10) == (twin.FIXED_AVERAGE_LUMINANCE, 1.0)   # the first frame
    assert adaptation.inputs_from_plan(plan, 14) == (2.0, 0.5)
    assert adaptation.inputs_from_plan(plan, 13) is None and adaptation.inputs_from_plan(plan, 16) is None
    for bad in (dict(plan, version=2), dict(plan, adapted=[1.0, float("nan"), 1.0]), dict(plan, adapted=[1.0]),
                dict(plan, weight="x"), dict(plan, step=0), [1, 2]):
        with pytest.raises(plan_mod.PlanError):
            plan_mod.check_plan(bad)
    # (1 - w)^n < 1e-6: at 24 fps (w = 0.041) 13.8 s of frames
    assert plan_mod.history_frames(twin.adaptation_weight(1 / 24)) == 332
    assert plan_mod.history_frames(1.0) == 1


def test_chunks_rendered_apart_adapt_like_one_job(addon_package, tmp_path, monkeypatch, capsys):
    """A farm renders chunks of frames in fresh processes: with the measured plan, frames 1-4 as
    one job and as two chunks that know nothing of each other's frames are identical."""
    import json
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    adaptation = extension_module("addon.scene.frame.adaptation")
    plan_mod = extension_module("addon.scene.frame.adaptation_plan")
    scene = animated_scene(addon_package, tmp_path)
    scene.ols.light_adaptation = True
    scene.frame_start, scene.frame_end = 1, 4
    plan = plan_mod.build(scene, progress=None)
    assert plan["start"] == 1 and plan["end"] == 4 and len(plan["adapted"]) == 4
    assert plan["adapted"][0] < plan["adapted"][1] < plan["adapted"][2]        # adapting to the jump
    frames = (1, 2, 3, 4)
    one_job = render_animation(scene, tmp_path, "one", frames)
    chunks = []
    for chunk in ((1, 2), (3, 4)):
        adaptation.forget(scene)                     # a fresh process: no frame rendered before
        chunks += render_animation(scene, tmp_path, f"chunk{chunk[0]}_", chunk)
    for frame, a, b in zip(frames, one_job, chunks):
        assert np.abs(a - b).max() <= 1e-5, frame
    # Without the plan the second chunk starts afresh: its first frame differs.
    text = scene[names.ADAPTATION_PLAN_KEY]
    plan_mod.forget(scene)
    adaptation.forget(scene)
    fresh = render_animation(scene, tmp_path, "fresh", (3, 4))
    assert np.abs(fresh[0] - one_job[2]).max() > 1e-3
    # A damaged plan, or one made for another state of the scene, is not used, with one line.
    for stored, words in (("{not json", "damaged"), (text, "another state of the scene")):
        scene[names.ADAPTATION_PLAN_KEY] = stored
        if words.startswith("another"):
            scene.ols.middle_gray = 0.2
        capsys.readouterr()
        adaptation.forget(scene)
        again = render_animation(scene, tmp_path, "stale", (3, 4))
        assert words in capsys.readouterr().out
        assert np.abs(again[0] - one_job[2]).max() > 1e-3
    assert json.loads(text)["signature"] != plan_mod.signature(scene)
