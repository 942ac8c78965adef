"""Headless rendering (addon/batch.py via scripts/render.py): options, and one-line errors with
exit status 1 for bad input."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from extension import ROOT, extension_module

bpy = pytest.importorskip("bpy")


@pytest.fixture
def batch(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    return extension_module("addon.batch")


def error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert err and err[-1].startswith("error: ")
    return err[-1]


def test_missing_blend(batch, tmp_path, capsys):
    assert batch.main(["--blend", str(tmp_path / "nope.blend"), "--output", str(tmp_path / "o.png")]) == 1
    assert "does not exist" in error_line(capsys)


def test_no_camera_and_no_sun(batch, tmp_path, capsys):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    blend = tmp_path / "empty.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    assert batch.main(["--blend", str(blend), "--output", str(tmp_path / "o.png")]) == 1
    assert "no camera" in error_line(capsys)
    camera = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    assert batch.main(["--blend", str(blend), "--output", str(tmp_path / "o.png")]) == 1
    assert "no Sun lamp" in error_line(capsys)


def test_eevee_without_egl_is_reported(batch, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(batch, "egl_available", lambda: False)
    assert batch.main(["--sample", "--engine", "EEVEE", "--output", str(tmp_path / "o.png")]) == 1
    assert "EEVEE needs EGL" in error_line(capsys)
    # With EGL, one line explains the EGL_BAD_MATCH noise EEVEE prints.
    monkeypatch.setattr(batch, "egl_available", lambda: True)
    assert batch.main(["--blend", str(tmp_path / "missing.blend"), "--engine", "EEVEE",
                       "--output", str(tmp_path / "o.png")]) == 1
    assert capsys.readouterr().out.startswith("EGL probe: using EGL")


def test_damaged_cached_tables_are_baked_again(batch, tmp_path, addon_package):
    """A damaged file in the cache is not a cache hit: the bake is repaired, then rendered."""
    lut_gen = addon_package.lut_gen
    directory = extension_module("addon.baking").bake_if_needed(lut_gen.AtmosphereParams(), "draft")
    path = directory / "multiple_scattering.exr"
    path.write_bytes(path.read_bytes()[:4096])          # header intact, pixels cut off
    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert batch.main(["--sample", "--tables", "draft", "--resolution", "32x18", "--samples", "1",
                       "--output", str(tmp_path / "o.png")]) == 0
    lut_gen.load(directory)                              # whole again


@pytest.fixture
def wired_blend(batch, tmp_path, addon_package):
    """The sample scene wired to draft tables in the test's cache, saved as a .blend."""
    wiring = extension_module("addon.scene.setup.wiring")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    args = batch.parse_args(["--sample", "--tables", "draft", "--output", str(tmp_path / "x.png")])
    scene = batch.prepare(args)
    directory = extension_module("addon.baking").bake_if_needed(addon_package.lut_gen.AtmosphereParams(), "draft")
    wiring.wire_scene(scene, directory, [o for o in scene.objects if o.select_get()], resolution="draft")
    blend = tmp_path / "wired.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    return blend, directory


def render_args(blend, out):
    return ["--blend", str(blend), "--resolution", "32x18", "--samples", "1", "--output", str(out)]


def test_wired_blend_with_damaged_tables_is_repaired_before_it_renders(batch, wired_blend, tmp_path, capsys,
                                                                       addon_package):
    """A truncated table in a wired .blend's cache rendered 99.7% wrong pixels
    with exit 0. Now the file load finds the damage, bakes again, and the render is right."""
    blend, directory = wired_blend
    assert batch.main(render_args(blend, tmp_path / "good.png")) == 0
    # After a render the adaptation read-back node holds no absolute temporary path and is muted,
    # so a .blend saved now writes nothing when rendered without the add-on.
    output = bpy.context.scene.compositing_node_group.nodes["OLS Adapted Luminance"]
    assert output.mute and output.directory == ""
    good = bpy.data.images.load(str(tmp_path / "good.png"))
    want = np.array(good.pixels[:])
    path = directory / "optical_depth.exr"
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    capsys.readouterr()
    assert batch.main(render_args(blend, tmp_path / "again.png")) == 0
    assert "optical_depth.exr" in capsys.readouterr().out          # said what it repaired
    again = bpy.data.images.load(str(tmp_path / "again.png"))
    assert np.abs(np.array(again.pixels[:]) - want).max() <= 2 / 255
    addon_package.lut_gen.load(directory)


def test_wired_blend_with_damaged_tables_that_cannot_be_baked_is_not_rendered(batch, wired_blend, tmp_path,
                                                                              capsys, monkeypatch):
    blend, directory = wired_blend
    path = directory / "optical_depth.exr"
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    (tmp_path / "file").write_text("x")
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "file" / "cache"))     # no bake can be written
    out = tmp_path / "bad.png"
    assert batch.main(render_args(blend, out)) == 1
    line = error_line(capsys)
    assert "optical_depth.exr" in line and "bake the tables again" in line
    assert not out.exists()


FARM_WORKER = """
import sys
sys.path.insert(0, sys.argv[1])
import bpy
from conftest import import_extension
import_extension().register()
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])          # load_post: the repair bake fails
scene = bpy.context.scene
scene.render.resolution_x, scene.render.resolution_y, scene.cycles.samples = 32, 18, 1
scene.frame_start, scene.frame_end = 1, 2
scene.render.filepath = sys.argv[3]
bpy.ops.render.render(animation=True)                   # `blender -b shot.blend -a`
print("rendered")
"""


def test_farm_render_of_damaged_tables_exits_1_before_any_frame(wired_blend, tmp_path):
    """`blender -b shot.blend -a` runs no script of ours, and a handler cannot
    cancel a render. Where the load's repair bake cannot be written, the render's start ends
    the process with one error line and status 1, before a frame is written."""
    blend, directory = wired_blend
    path = directory / "optical_depth.exr"
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    (tmp_path / "file").write_text("x")
    env = {**os.environ, "OLS_CACHE_DIR": str(tmp_path / "file" / "cache")}
    frames = tmp_path / "frames" / "f_"
    result = subprocess.run([sys.executable, "-c", FARM_WORKER, str(ROOT / "tests"), str(blend), str(frames)],
                            capture_output=True, text=True, timeout=600, env=env, cwd=str(ROOT))
    assert result.returncode == 1, result.stdout[-2000:] + result.stderr[-2000:]
    errors = [line for line in result.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and "optical_depth.exr" in errors[0] and "nothing was rendered" in errors[0], result.stderr
    assert "Traceback" not in result.stderr and "rendered" not in result.stdout.split()
    assert not (tmp_path / "frames").exists() or not any((tmp_path / "frames").iterdir())


def test_wired_blend_whose_tables_are_gone_and_cannot_be_baked_is_not_rendered(batch, wired_blend, tmp_path,
                                                                               capsys, monkeypatch):
    """With the tables deleted and the cache unwritable it rendered no sky, exit 0."""
    blend, directory = wired_blend
    for path in directory.glob("*.exr"):
        path.unlink()
    (tmp_path / "file").write_text("x")
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "file" / "cache"))
    out = tmp_path / "gone.png"
    assert batch.main(render_args(blend, out)) == 1
    line = error_line(capsys)
    assert ".exr is missing" in line and "bake the tables again" in line
    assert not out.exists()


def test_render_operator_refuses_deleted_tables(wired_blend, tmp_path):
    """ols.render after the table files were deleted said "Rendered"."""
    blend, directory = wired_blend
    for path in directory.glob("*.exr"):
        path.unlink()
    out = tmp_path / "op.png"
    with pytest.raises(RuntimeError, match=r"\.exr is missing"):
        bpy.ops.ols.render(filepath=str(out))
    assert not out.exists()


@pytest.mark.parametrize("operator", ["bake_luts", "setup_scene"])
def test_bake_tables_and_set_up_scene_repair_a_damaged_bake(wired_blend, addon_package, operator):
    """With a bit-flipped table Bake Tables said "Tables ready" and Set Up
    Scene kept failing until the folder was deleted. Both bake it again in place."""
    blend, directory = wired_blend
    path = directory / "single_scattering.exr"
    data = bytearray(path.read_bytes())
    data[-100] ^= 1
    path.write_bytes(bytes(data))
    scene = bpy.context.scene
    assert "single_scattering.exr" in extension_module("addon.scene.tables.wired_bake").table_problem(scene)
    assert getattr(bpy.ops.ols, operator)(resolution="draft") == {"FINISHED"}
    assert extension_module("addon.scene.tables.wired_bake").table_problem(scene) is None
    assert path.read_bytes() != bytes(data)                        # baked again, in place
    addon_package.lut_gen.load(directory)


PLAIN_RENDER = """
import sys
import bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[1])          # no add-on: what another machine does
scene = bpy.context.scene
scene.render.resolution_x, scene.render.resolution_y, scene.cycles.samples = 32, 18, 1
scene.render.filepath = sys.argv[2]
bpy.ops.render.render(write_still=True)
"""


def test_a_saved_blend_holds_no_temporary_path_and_writes_nothing_without_the_add_on(batch, wired_blend,
                                                                                    tmp_path):
    """The adaptation File Output node saved the system temporary folder in the
    .blend; rendered without the add-on it wrote adapted_luminance_.exr there, following a link
    planted under that name. After a render with light adaptation, the saved file holds no
    temporary path, and a render of it without the add-on writes nothing there."""
    import tempfile
    blend, _ = wired_blend
    bpy.context.scene.ols.light_adaptation = True
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    assert batch.main(render_args(blend, tmp_path / "adapted.png")) == 0
    saved = tmp_path / "after.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(saved))
    data = saved.read_bytes()
    assert bpy.app.tempdir and bpy.app.tempdir.encode() not in data
    assert b"ols_adaptation" not in data
    shared = Path(tempfile.gettempdir())
    target = tmp_path / "precious.txt"
    target.write_text("keep me")
    planted = shared / "adapted_luminance_.exr"
    if planted.exists() or planted.is_symlink():
        pytest.skip(f"{planted} exists already (another process's); not touching it")
    planted.symlink_to(target)
    try:
        before = set(shared.glob("adapted_luminance_*"))
        result = subprocess.run([sys.executable, "-c", PLAIN_RENDER, str(saved), str(tmp_path / "plain.png")],
                                capture_output=True, text=True, timeout=600, cwd=str(tmp_path))
        assert result.returncode == 0, result.stderr[-2000:]
        assert (tmp_path / "plain.png").exists()
        assert target.read_text() == "keep me"
        assert set(shared.glob("adapted_luminance_*")) == before
    finally:
        planted.unlink()


def test_panel_names_damaged_tables(wired_blend):
    """F12 in the UI cannot be stopped by the add-on: the panel shows the problem at its top."""
    from test_addon_register import _draw
    blend, directory = wired_blend
    panel = bpy.types.OLS_PT_atmosphere
    labels = [entry[1] for entry in _draw(panel, bpy.context.scene) if entry[0] == "label"]
    assert not any("fail verification" in text for text in labels)
    path = directory / "single_scattering.exr"
    data = bytearray(path.read_bytes())
    data[-100] ^= 1
    path.write_bytes(bytes(data))
    labels = [entry[1] for entry in _draw(panel, bpy.context.scene) if entry[0] == "label"]
    assert labels[0] == "The tables fail verification:"
    assert "single_scattering.exr" in " ".join(labels[1:]).replace(" ", "")


def test_measure_light_adaptation_refuses_damaged_tables(wired_blend):
    """Its pre-pass renders: with damaged tables it reports them instead (headless, the render's
    start would end the process)."""
    blend, directory = wired_blend
    scene = bpy.context.scene
    scene.ols.light_adaptation = True
    path = directory / "optical_depth.exr"
    data = bytearray(path.read_bytes())
    data[-100] ^= 1
    path.write_bytes(bytes(data))
    with pytest.raises(RuntimeError, match="optical_depth.exr"):
        bpy.ops.ols.measure_adaptation()
    assert "ols_adaptation_plan" not in scene


def test_render_operator_refuses_damaged_tables(wired_blend, tmp_path, addon_package):
    blend, directory = wired_blend
    path = directory / "higher_order_scattering.exr"
    data = bytearray(path.read_bytes())
    data[-100] ^= 1
    path.write_bytes(bytes(data))
    out = tmp_path / "op.png"
    with pytest.raises(RuntimeError, match="higher_order_scattering.exr"):
        bpy.ops.ols.render(filepath=str(out))
    assert not out.exists()


@pytest.mark.parametrize("args, message", [
    (["--resolution=-64x36"], "--resolution must be from 4x4"),
    (["--resolution", "0x0"], "--resolution must be from 4x4"),
    (["--frames", "5-1"], "--frames must run forward"),
])
def test_bad_render_options_are_refused(batch, tmp_path, capsys, args, message):
    out = tmp_path / "f.png"
    assert batch.main(["--sample", "--tables", "draft", "--samples", "1", "--output", str(out), *args]) == 1
    assert message in error_line(capsys)
    assert not list(tmp_path.glob("f*"))


@pytest.mark.parametrize("args", [["--samples", "-1"], ["--sun-elevation", "nan"], ["--sun-azimuth", "inf"]])
def test_bad_numbers_are_usage_errors(batch, tmp_path, args):
    with pytest.raises(SystemExit) as exit_info:
        batch.parse_args(["--sample", "--output", str(tmp_path / "o.png"), *args])
    assert exit_info.value.code == 2


def test_unwritable_output(batch, tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert batch.main(["--sample", "--tables", "draft", "--output", str(tmp_path / "file" / "o.png")]) == 1
    assert "cannot write" in error_line(capsys)


def test_frames_follow_the_animated_sun(batch, tmp_path, addon_package):
    assert batch.main(["--sample", "--tables", "draft", "--resolution", "32x18", "--samples", "1",
                       "--frames", "1-2", "--output", str(tmp_path / "frame_####")]) == 0
    assert sorted(p.name for p in tmp_path.glob("frame_*.png")) == ["frame_0001.png", "frame_0002.png"]
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 100
    scene.ols.animate_sun = True                           # takes the day's frames from the range
    assert (scene.ols.day_start_frame, scene.ols.day_end_frame) == (1, 100)
    scene.frame_start, scene.frame_end = 49, 50            # a farm's chunk: the same sun per frame
    sun = bpy.data.objects["OLS Sun"]
    directions = []
    for frame in (10, 50, 90):
        scene.frame_set(frame)
        directions.append(np.array(sun.matrix_world.col[2][:3]))
    assert directions[1][2] > directions[0][2] and directions[0][0] * directions[2][0] < 0   # rises, crosses
    scene.frame_set(50)
    noon = np.array(sun.data.color)
    scene.frame_set(10)
    morning = np.array(sun.data.color)
    assert morning[2] / morning[0] < noon[2] / noon[0]     # the low morning sun is redder


def test_script_entry_point_runs(tmp_path):
    out = tmp_path / "s.png"
    env = {"OLS_CACHE_DIR": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin"}
    result = subprocess.run([sys.executable, str(ROOT / "scripts" / "render.py"), "--sample", "--tables", "draft",
                             "--resolution", "64x36", "--samples", "2", "--output", str(out)],
                            capture_output=True, text=True, timeout=600, env=env)
    assert result.returncode == 0, result.stderr[-2000:]
    assert out.read_bytes().startswith(b"\x89PNG")
    # Progress, stage by stage, as plain lines: the bake, the scene, the render, the total.
    lines = result.stdout.splitlines()
    for expected in ("scene: building the sample terrain", "bake: single scattering 100%", "scene: wiring",
                     "render: frame 1: ", "render: frame 1 rendered and composited", "total time "):
        assert any(line.startswith(expected) for line in lines), expected
    assert lines[-1] == f"rendered {out}"
    assert "adapted_luminance" not in result.stdout + result.stderr     # a still reads nothing back


def test_output_format_follows_the_extension(batch, tmp_path, capsys):
    """--output x.exr writes OpenEXR (it wrote a PNG named .png and printed x.exr); an extension
    we cannot write is refused before any work."""
    out = tmp_path / "still.exr"
    assert batch.main(["--sample", "--tables", "draft", "--resolution", "32x18", "--samples", "1",
                       "--output", str(out)]) == 0
    assert out.read_bytes()[:4] == b"\x76\x2f\x31\x01"
    assert capsys.readouterr().out.strip().splitlines()[-1] == f"rendered {out}"
    assert batch.main(["--sample", "--tables", "draft", "--output", str(tmp_path / "still.bmp")]) == 1
    assert "--output must end in .png, .jpg, .tif or .exr" in error_line(capsys)
    assert not (tmp_path / "still.bmp").exists()


def test_frames_without_hashes_are_numbered_and_listed(batch, tmp_path, capsys):
    assert batch.main(["--sample", "--tables", "draft", "--resolution", "32x18", "--samples", "1",
                       "--frames", "2-3", "--output", str(tmp_path / "shot.jpg")]) == 0
    written = [tmp_path / "shot_0002.jpg", tmp_path / "shot_0003.jpg"]
    assert sorted(tmp_path.glob("shot*")) == written
    assert capsys.readouterr().out.strip().splitlines()[-1] == "rendered " + " ".join(map(str, written))
    assert written[0].read_bytes()[:2] == b"\xff\xd8"


def read_png(path):
    image = bpy.data.images.load(str(path))
    image.colorspace_settings.name = "Non-Color"                 # the stored display values
    width, height = image.size
    pixels = np.array(image.pixels[:]).reshape(height, width, 4)[::-1, :, :3]
    bpy.data.images.remove(image)
    return pixels


def test_gallery_preset_is_a_real_landscape(batch, tmp_path):
    """The README gallery's golden-hour preset at 160 x 90: not flat, not clipped, no NaN, sky
    above terrain."""
    png, exr = tmp_path / "golden.png", tmp_path / "golden.exr"
    for out in (png, exr):
        assert batch.main(["--sample", "--tables", "draft", "--preset", "golden-hour", "--resolution", "160x90",
                           "--samples", "4", "--output", str(out)]) == 0
    import OpenEXR
    with OpenEXR.File(str(exr)) as f:
        linear = np.asarray(f.channels()["RGBA"].pixels[..., :3] if "RGBA" in f.channels()
                            else f.channels()["RGB"].pixels)
    assert np.isfinite(linear).all() and linear.min() >= 0
    display = read_png(png)
    luminance = display @ np.array([0.2126, 0.7152, 0.0722])
    assert luminance.std() > 0.05                                   # not flat
    assert np.mean(display.max(axis=-1) >= 254 / 255) < 0.02        # under 2% clipped
    sky, ground = display[:15], display[-15:]
    assert sky.mean() > ground.mean() + 0.1                         # a bright sky over darker land
    assert ground.mean() > 0.05                                     # the terrain is lit, not black
    assert sky[..., 2].mean() > sky[..., 0].mean() * 0.8            # no colour cast gone wild


def test_air_presets_set_the_haze_from_the_panel_and_the_command_line(batch, addon_package):
    """An air preset sets the aerosol density for its aerosol optical depth at 550 nm
    (lut_gen.model.air_presets), from the panel's Air Preset and from --preset; the looks'
    presets leave it."""
    air = addon_package.lut_gen.model.air_presets
    settings = extension_module("addon.settings")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.collection.objects.link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
    scene.ols.air_preset = "HAZY_SUMMER_DAY"
    assert abs(air.aerosol_optical_depth(settings.atmosphere_params(scene.ols)) - 0.3) < 1e-4
    scene.ols.air_preset = "CLEAN_MOUNTAIN_AIR"
    assert abs(air.aerosol_optical_depth(settings.atmosphere_params(scene.ols)) - 0.03) < 1e-4
    scene.ols.aerosol_density = 1.0
    batch.apply_options(scene, batch.parse_args(["--preset", "hazy-summer-day", "--output", "x.png"]))
    assert abs(air.aerosol_optical_depth(settings.atmosphere_params(scene.ols)) - 0.3) < 1e-4
    batch.apply_options(scene, batch.parse_args(["--preset", "noon", "--output", "x.png"]))
    assert abs(scene.ols.aerosol_density - 2.7273) < 1e-3


def test_morning_fog_preset_from_the_panel_and_the_command_line(batch, addon_package):
    """"Morning fog" sets the fog (300 m visibility, 50 m deep) and keeps the haze; a haze preset
    clears it again; an unknown preset is refused by the parser with the choices named."""
    settings = extension_module("addon.settings")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.collection.objects.link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
    scene.ols.aerosol_density = 2.0
    scene.ols.air_preset = "MORNING_FOG"
    params = settings.atmosphere_params(scene.ols)
    assert params.has_fog and params.fog_visibility == 300.0 and params.fog_height == 50.0
    assert params.aerosol_density == 2.0
    scene.ols.air_preset = "HAZY_SUMMER_DAY"
    assert not settings.atmosphere_params(scene.ols).has_fog
    batch.apply_options(scene, batch.parse_args(["--preset", "morning-fog", "--output", "x.png"]))
    assert settings.atmosphere_params(scene.ols).fog_visibility == 300.0
    # Visibility between 0 and 100 m reads as 100 m; 0 is no fog; NaN reads as the default (none).
    scene.ols.fog_visibility = 20.0
    assert settings.atmosphere_params(scene.ols).fog_visibility == 100.0
    scene.ols["fog_visibility"] = float("nan")
    assert not settings.atmosphere_params(scene.ols).has_fog
    with pytest.raises(SystemExit):
        batch.parse_args(["--preset", "morning-mist", "--output", "x.png"])
