"""The light-shaft compositor pass ("OLS Aerial Perspective" + "OLS Light Shafts" as wired by
Set Up Scene) on a small Cycles render of the sample, against its numpy twin
lut_gen.passes.scattering_pass fed the same render passes and the same shadow cascades: every one of
the sample's 3 x 3 scattering modes, light shafts visibly present, Show Cascades, and the
cases where the pass cannot run."""
import numpy as np
import pytest

from render_util import render_rgb, save_png
from scenes import Twin, render_passes, sample_scene
from extension import extension_module, names

bpy = pytest.importorskip("bpy")

WIDTH, HEIGHT = 160, 90
MODES = [(s, m) for s in ("NONE", "INTEGRATION", "LUT") for m in ("NONE", "OCCLUDED", "UNOCCLUDED")]


def low_sun_scene(pkg, tmp_path, monkeypatch, steps=16):
    """The sample with the sun 5 degrees up straight ahead, behind the ridge, wired with draft
    tables; the tone mapping is muted so the composite is the scattering pass itself."""
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    scene = sample_scene(pkg)
    sun_mod = extension_module("addon.scene.sun")
    sun_mod.set_sun_angles(sun_mod.find_sun(scene), 5.0, 0.0)
    settings = scene.ols
    settings.num_integration_steps = steps
    settings.num_cascades = 4
    settings.first_cascade_to_ray_march = 1
    settings.shadow_map_resolution = "512"
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.cycles.samples = 4
    scene.cycles.seed = 3
    scene.compositing_node_group.nodes["OLS Tone Mapping"].mute = True
    return scene






def relative_error(seen, twin):
    return np.abs(seen - twin).sum(axis=-1) / np.maximum(twin.sum(axis=-1), 1e-4)


@pytest.mark.parametrize("technique", ["EPIPOLAR_SAMPLING", "BRUTE_FORCE"])
def test_shafts_in_fog_match_the_twin(addon_package, tmp_path, monkeypatch, technique):
    """A 2 km fog of 100 m scale height over the sample's valley: the fog's own single scattering
    (its table, its phase; its density in the march) and extinction in every part of the pass,
    and the ridge's shadow cut out of the fog."""
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch)
    scene.ols.fog_visibility, scene.ols.fog_height = 2000.0, 100.0
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    scene.compositing_node_group.nodes["OLS Tone Mapping"].mute = True
    scene.ols.scattering_technique = technique
    passes = render_passes(addon_package, scene, tmp_path)
    twin = Twin(addon_package, scene, passes)
    assert twin.luts.params.has_fog
    for single, multiple in (("LUT", "UNOCCLUDED"), ("INTEGRATION", "OCCLUDED")):
        scene.ols.single_scattering_mode, scene.ols.multiple_scattering_mode = single, multiple
        seen = render_rgb(scene, tmp_path / f"fog_{single}.exr", composite=True)[::-1]
        expected = twin()
        error = relative_error(seen, expected)
        print(technique, single, multiple, "fog: median", np.median(error), "p99", np.percentile(error, 99))
        # Measured: medians 0.5-3e-6; p99 2e-5 (LUT) and 3e-4 / 1.4e-3 (INTEGRATION, epipolar /
        # brute force). The INTEGRATION tail is scattered sky pixels just over the ridge, toward
        # the sun: rays that graze the ridge's shadow, where a step's shadow test flips between
        # float32 and float64, and the fog's forward peak (g = 0.85) makes each step toward the
        # sun weigh a hundred times what it does in clear air.
        assert np.median(error) <= 1e-4 and np.percentile(error, 99) <= 5e-3
    save_png(tmp_path / "fog_shafts.png", seen[::-1], 1.0)
    darker = (twin(enable_light_shafts=False) - expected).sum(axis=-1)
    assert (darker > 0.01 * np.maximum(expected.sum(axis=-1), 1e-6)).mean() > 0.05


@pytest.mark.parametrize("technique", ["EPIPOLAR_SAMPLING", "BRUTE_FORCE"])
def test_every_scattering_mode_matches_the_twin_and_shafts_show(addon_package, tmp_path, monkeypatch, technique):
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch)
    scene.ols.scattering_technique = technique
    passes = render_passes(addon_package, scene, tmp_path)
    # The render rebuilt the groups for the technique (render_pre; the UI's depsgraph update).
    assert scene.compositing_node_group.nodes["OLS Light Shafts"].node_tree["ols_layout"].find(technique) >= 0
    raw, position, depth = passes
    geometry = depth < 1e9
    assert 0.2 < geometry.mean() < 0.9                        # terrain and sky in view
    twin = Twin(addon_package, scene, passes)
    errors, tails = {}, {}
    for single, multiple in MODES:
        scene.ols.single_scattering_mode, scene.ols.multiple_scattering_mode = single, multiple
        seen = render_rgb(scene, tmp_path / f"{single}_{multiple}.exr", composite=True)[::-1]
        expected = twin()
        assert np.isfinite(seen).all()
        error = relative_error(seen, expected)
        errors[single, multiple] = float(np.median(error))
        tails[single, multiple] = float(np.percentile(error, 99))
        if (single, multiple) == ("LUT", "UNOCCLUDED"):
            save_png(tmp_path / "shafts.png", seen[::-1], 1.0)
            save_png(tmp_path / "unshadowed.png", twin(enable_light_shafts=False)[::-1], 1.0)
            unshadowed = twin(enable_light_shafts=False)
            shadow_effect = unshadowed - expected
    print(technique, "median relative error per mode:", errors, "p99:", tails)
    # Measured: medians 0.5-3e-6, p99 1.4e-5 to 1.1e-4 (float32 against float64).
    assert max(errors.values()) <= 1e-4, errors
    assert max(tails.values()) <= 1e-3, tails
    if technique == "EPIPOLAR_SAMPLING":
        # The sample with the low sun behind the ridge: epipolar against brute force at the same
        # steps, shadow maps and modes, in display values (the bar: PSNR >= 40 dB).
        brute = twin(scattering_technique="BRUTE_FORCE")
        psnr = extension_module("lut_gen.verify.display").display_psnr(expected, brute)
        print("epipolar vs brute force PSNR", psnr)
        assert psnr >= 40.0
    # The same pass from the command line, on the passes saved to EXR and the saved inputs.
    frame_update = extension_module("addon.scene.frame.frame_update")
    frame_update.export_pass_inputs(scene, tmp_path / "inputs.npz")
    cli = extension_module("lut_gen.cli")
    luts_dir = extension_module("addon.baking").bake_if_needed(addon_package.lut_gen.AtmosphereParams(), "draft")
    assert cli.main(["pass", "--luts", str(luts_dir), "--passes", str(tmp_path / "passes.exr"),
                     "--inputs", str(tmp_path / "inputs.npz"), "--out", str(tmp_path / "cli.exr")]) == 0
    from_cli = read_exr(tmp_path / "cli.exr")[::-1]
    np.testing.assert_allclose(from_cli, expected, rtol=1e-5, atol=1e-7)
    if technique == "EPIPOLAR_SAMPLING":          # the other technique from the same saved inputs
        assert cli.main(["pass", "--luts", str(luts_dir), "--passes", str(tmp_path / "passes.exr"), "--technique",
                         "brute-force", "--inputs", str(tmp_path / "inputs.npz"), "--out", str(tmp_path / "bf.exr")]) == 0
        np.testing.assert_allclose(read_exr(tmp_path / "bf.exr")[::-1], brute, rtol=1e-5, atol=1e-7)
        # Hostile input gets one line and status 1, before any work.
        common = ["pass", "--luts", str(luts_dir), "--passes", str(tmp_path / "passes.exr"), "--out",
                  str(tmp_path / "bad.exr")]
        assert cli.main([*common, "--inputs", str(tmp_path / "inputs.npz"), "--steps", "1000000"]) == 1
        with np.load(tmp_path / "inputs.npz") as data:
            fields = dict(data)
        fields["camera_position"] = np.array([np.nan, 0.0, 2.0])
        np.savez(tmp_path / "nan_inputs.npz", **fields)
        assert cli.main([*common, "--inputs", str(tmp_path / "nan_inputs.npz")]) == 1
        assert not (tmp_path / "bad.exr").exists()
        (tmp_path / "file").write_text("x")
        unwritable = tmp_path / "file" / "out.exr"
        assert cli.main([*common[:-1], str(unwritable), "--inputs", str(tmp_path / "inputs.npz")]) == 1
        long_name = tmp_path / ("n" * 241 + ".exr")             # 245 characters: the temporary name fits
        assert cli.main([*common[:-1], str(long_name), "--inputs", str(tmp_path / "inputs.npz")]) == 0
        assert long_name.exists()
    # Light shafts are present: the ridge's shadow takes light out of the air over the valley
    # and in the sky around the sun, unevenly across the columns of the image.
    darker = shadow_effect.sum(axis=-1)
    assert (darker > 0.01 * np.maximum(expected.sum(axis=-1), 1e-6)).mean() > 0.05
    column_effect = darker.mean(axis=0)
    assert column_effect.max() > 2.0 * max(column_effect.min(), 1e-9)


@pytest.mark.parametrize("technique", ["EPIPOLAR_SAMPLING", "BRUTE_FORCE"])
def test_without_occluders_the_pass_equals_the_unshadowed_result(addon_package, tmp_path, monkeypatch, technique):
    """With no shadow casters the cascades end 20 m out: the epipolar tables do too, and the air
    beyond them counts as lit, as it does for brute force."""
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=8)
    scene.ols.scattering_technique = technique
    scene.ols.single_scattering_mode, scene.ols.multiple_scattering_mode = "LUT", "UNOCCLUDED"
    for obj in scene.objects:
        if obj.type == "MESH":
            obj.visible_shadow = False                    # nothing casts shadows in the air
    shafts = render_rgb(scene, tmp_path / "open.exr", composite=True)
    scene.ols.enable_light_shafts = False
    assert scene.compositing_node_group.nodes["OLS Light Shafts"].mute
    plain = render_rgb(scene, tmp_path / "plain.exr", composite=True)
    assert np.median(relative_error(shafts, plain)) < 0.01


def test_show_cascades_tints_the_terrain(addon_package, tmp_path, monkeypatch):
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=4)
    plain = render_rgb(scene, tmp_path / "plain.exr", composite=True)
    scene.ols.show_cascades = True
    tinted = render_rgb(scene, tmp_path / "tinted.exr", composite=True)
    ratio = tinted / np.maximum(plain, 1e-6)
    bottom = ratio[-10:]                                  # near terrain: the smallest cascades
    assert np.abs(bottom - 1).max() > 0.2
    assert np.allclose(ratio[:5], 1.0, atol=1e-4)          # the sky (top rows) is not tinted


def read_exr(path):
    import OpenEXR
    with OpenEXR.File(str(path)) as exr:
        channels = exr.channels()
        return np.asarray((channels["RGBA"] if "RGBA" in channels else channels["RGB"]).pixels[..., :3], float)


def test_animation_frames_get_their_own_camera_sun_and_shadows(addon_package, tmp_path, monkeypatch):
    """Compositor inputs set by handlers reach an animation render a frame late; the per-frame
    values (camera, cascades) go through images instead. Each animation frame must equal a still
    of that frame. (The camera moves along y only: the sky-lighting panorama follows the
    camera's height through handlers that read the scene's original data.)"""
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=4)
    scene.render.resolution_x, scene.render.resolution_y = 48, 27
    scene.cycles.samples = 1
    camera = scene.camera
    for frame, shift in ((1, 0.0), (2, 300.0), (3, 300.0)):
        camera.location.y += shift
        camera.keyframe_insert("location", frame=frame)
    scene.frame_start, scene.frame_end = 1, 3
    scene.frame_set(1)
    scene.render.use_compositing = True
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(tmp_path / "anim_")
    bpy.ops.render.render(animation=True)
    for frame in (1, 2, 3):
        scene.frame_set(frame)
        still = render_rgb(scene, tmp_path / f"still_{frame}.exr", composite=True)
        animated = read_exr(tmp_path / f"anim_{frame:04d}.exr")
        np.testing.assert_allclose(animated, still, rtol=1e-4, atol=1e-6, err_msg=f"frame {frame}")
    assert np.abs(read_exr(tmp_path / "anim_0001.exr") - read_exr(tmp_path / "anim_0002.exr")).mean() > 1e-3


def test_bad_scenes_render_without_nan_and_say_why(addon_package, tmp_path, monkeypatch):
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=4)
    scene.render.resolution_x, scene.render.resolution_y = 48, 27
    scene.cycles.samples = 1
    checks = extension_module("addon.scene.setup.checks")
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert checks.render_problems(scene, depsgraph) == []
    good = render_rgb(scene, tmp_path / "good.exr", composite=True)

    # Epipolar tables too large for memory: brute force runs instead, and the checks say so. At
    # this small render the slices and samples are capped at what its pixels resolve
    # (lut_gen.passes.render_detail), so the tables fit; a 1280 x 720 render uses all 2048 x 2048.
    epipolar_tables = extension_module("addon.scene.frame.epipolar_tables")
    scene.ols.epipolar_slices, scene.ols.samples_per_slice = 2048, 2048
    assert epipolar_tables.technique(extension_module("addon.settings").Sanitized(scene.ols)) == "EPIPOLAR_SAMPLING"
    assert checks.render_problems(scene, depsgraph) == []
    size = scene.render.resolution_x, scene.render.resolution_y
    scene.render.resolution_x, scene.render.resolution_y = 1280, 720
    assert epipolar_tables.technique(extension_module("addon.settings").Sanitized(scene.ols)) == "BRUTE_FORCE"
    assert any("brute force ray marching runs instead" in p for p in checks.render_problems(scene, depsgraph))
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.ols.epipolar_slices, scene.ols.samples_per_slice = 512, 256

    # The epipolar technique marches its tables in numpy: its group reads no shadow-map atlas,
    # and none is packed. Brute force reads it: removed (or emptied), it is rebuilt before the
    # next render, same picture.
    assert scene.ols.scattering_technique == "EPIPOLAR_SAMPLING"
    assert names.SHADOW_MAP_IMAGE not in bpy.data.images
    scene.ols.scattering_technique = "BRUTE_FORCE"
    brute = render_rgb(scene, tmp_path / "brute.exr", composite=True)
    bpy.data.images.remove(bpy.data.images[names.SHADOW_MAP_IMAGE])
    again = render_rgb(scene, tmp_path / "again.exr", composite=True)
    np.testing.assert_allclose(again, brute, rtol=1e-4, atol=1e-6)
    scene.ols.scattering_technique = "EPIPOLAR_SAMPLING"
    back = render_rgb(scene, tmp_path / "back.exr", composite=True)     # the atlas is dropped again
    assert names.SHADOW_MAP_IMAGE not in bpy.data.images and names.SHADOW_CASCADES_IMAGE not in bpy.data.images
    np.testing.assert_allclose(back, good, rtol=1e-4, atol=1e-6)

    # Sun below the horizon: twilight, finite and non-negative.
    sun_mod = extension_module("addon.scene.sun")
    sun_mod.set_sun_angles(sun_mod.find_sun(scene), -4.0, 0.0)
    dusk = render_rgb(scene, tmp_path / "dusk.exr", composite=True)
    assert np.isfinite(dusk).all() and dusk.min() >= 0.0 and dusk.mean() < good.mean()

    # Camera inside the terrain: a message naming the terrain, and still no NaN.
    camera = scene.camera
    origin = camera.matrix_world.translation.copy()
    hit, location, *_ = scene.ray_cast(bpy.context.evaluated_depsgraph_get(), origin, (0.0, 0.0, -1.0))
    assert hit
    camera.location.z = location.z - 10.0
    bpy.context.view_layer.update()
    problems = checks.render_problems(scene, bpy.context.evaluated_depsgraph_get())
    assert any("under the surface" in p and "OLS Terrain" in p for p in problems), problems
    inside = render_rgb(scene, tmp_path / "inside.exr", composite=True)
    assert np.isfinite(inside).all()

    # Missing passes: named (by the checks and by the twin's EXR loader), and the render
    # operator turns them back on.
    scene.view_layers[0].use_pass_position = False
    assert any("Position" in p for p in checks.render_problems(scene))
    with pytest.raises(ValueError, match="missing render passes Position"):
        render_passes(addon_package, scene, tmp_path)
    assert bpy.ops.ols.render(filepath=str(tmp_path / "fixed.png")) == {"FINISHED"}
    assert scene.view_layers[0].use_pass_position


def test_show_sampling_draws_the_epipolar_samples(addon_package, tmp_path, monkeypatch):
    """Thick red dots on the ray-marched samples, thin ones on the interpolated, as the twin draws
    them; off again, the picture is the plain pass."""
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=8)
    scene.ols.epipolar_slices, scene.ols.samples_per_slice = 64, 32
    passes = render_passes(addon_package, scene, tmp_path)
    plain = render_rgb(scene, tmp_path / "plain.exr", composite=True)[::-1]
    scene.ols.show_sampling = True
    dotted = render_rgb(scene, tmp_path / "dotted.exr", composite=True)[::-1]
    expected = Twin(addon_package, scene, passes)()
    red = (dotted[..., 0] > 2.0 * np.maximum(plain.max(axis=-1), 1e-4)) & (dotted[..., 1:].max(axis=-1) == 0.0)
    twin_red = (expected[..., 1:].max(axis=-1) == 0.0) & (expected[..., 0] > 0.0)
    assert 0.02 < red.mean() < 0.9
    assert (red == twin_red).mean() > 0.99
    save_png(tmp_path / "sampling.png", dotted[::-1], 1.0)
    scene.ols.show_sampling = False
    again = render_rgb(scene, tmp_path / "again.exr", composite=True)[::-1]
    np.testing.assert_allclose(again, plain, rtol=1e-5, atol=1e-7)


def test_a_script_changing_the_technique_reaches_an_animations_first_frame(addon_package, tmp_path, monkeypatch):
    """Controls set from a script rebuild the light-shaft groups at the render, not in the
    controls' update callbacks. An animation composites a frame from a depsgraph built before
    render_pre, so frame_change_pre must already have rebuilt them: the frame equals a still of
    the new technique, not of the old one."""
    import OpenEXR
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch)
    epipolar = render_rgb(scene, tmp_path / "epipolar.exr", composite=True)
    scene.ols.scattering_technique = "BRUTE_FORCE"          # no depsgraph update follows here
    scene.frame_start = scene.frame_end = scene.frame_current
    scene.render.use_compositing = True
    scene.render.filepath = str(tmp_path / "anim_####.exr")
    bpy.ops.render.render(animation=True)
    with OpenEXR.File(str(tmp_path / f"anim_{scene.frame_current:04d}.exr")) as exr:
        frame = np.asarray(exr.channels()["RGBA"].pixels[..., :3], dtype=np.float64)
    brute = render_rgb(scene, tmp_path / "brute.exr", composite=True)
    assert np.abs(brute - epipolar).max() > 1e-3 * brute.max()       # the techniques differ here
    np.testing.assert_allclose(frame, brute, rtol=1e-5, atol=1e-6 * brute.max())


def test_a_render_redoes_the_shadow_maps_only_when_something_they_depend_on_changed(
        addon_package, tmp_path, monkeypatch):
    """A second F12 with only a scene setting changed (the Scene reports a geometry update for
    any of its properties) reuses the shadow maps and epipolar tables; moving an occluder or
    hiding it from shadows redoes them."""
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=4)
    shadow_maps = extension_module("addon.scene.frame.shadow_maps")
    calls = []
    original = shadow_maps.rasterise
    monkeypatch.setattr(shadow_maps, "rasterise", lambda *a, **k: calls.append(1) or original(*a, **k))
    first = render_rgb(scene, tmp_path / "first.exr", composite=True)
    assert len(calls) == 1
    scene.ols.middle_gray = 0.25                            # tone mapping (muted here): no shadow input
    scene.render.film_transparent = False
    render_rgb(scene, tmp_path / "same.exr", composite=True)
    assert len(calls) == 1
    terrain = next(o for o in scene.objects if o.type == "MESH")
    terrain.location.z += 300.0                             # the occluders move: new shadows
    moved = render_rgb(scene, tmp_path / "moved.exr", composite=True)
    assert len(calls) == 2
    assert np.abs(moved - first).max() > 1e-3
    terrain.visible_shadow = False
    render_rgb(scene, tmp_path / "unshadowed.exr", composite=True)
    assert len(calls) == 3


def test_new_epipolar_table_sizes_resize_images_and_rebuild_no_group(addon_package, tmp_path, monkeypatch):
    """Slices, samples and steps reach the epipolar group as frame values: dragging one of them
    in the panel resizes the table images (cheap) instead of rebuilding the groups (~1 s), and
    the render at the new sizes still matches the twin."""
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=8)
    scene.ols.scattering_technique = "EPIPOLAR_SAMPLING"
    passes = render_passes(addon_package, scene, tmp_path)
    render_rgb(scene, tmp_path / "first.exr", composite=True)
    wiring = extension_module("addon.scene.setup.wiring")
    builds = []
    original = wiring.build_light_shafts
    monkeypatch.setattr(wiring, "build_light_shafts", lambda *a, **k: builds.append(1) or original(*a, **k))
    twin = Twin(addon_package, scene, passes)
    for slices, samples, steps in ((96, 64, 12), (200, 150, 6)):
        scene.ols.epipolar_slices, scene.ols.samples_per_slice, scene.ols.num_integration_steps = slices, samples, steps
        scene.frame_set(scene.frame_current)                 # the UI's depsgraph update
        lit = bpy.data.images["OLS Epipolar Lit"]
        assert tuple(lit.size) == (samples, (slices + 1) * steps)
        seen = render_rgb(scene, tmp_path / f"s{slices}.exr", composite=True)[::-1]
        assert np.median(relative_error(seen, twin())) <= 1e-3, (slices, samples, steps)
    assert builds == []


def test_in_scattering_tables_are_reused_while_the_camera_and_sun_stay(addon_package, tmp_path, monkeypatch):
    """The epipolar in-scattering tables depend on the camera's position, the sun and the grid,
    not on the geometry: moving an occluder rebuilds the lit-length tables only, and the frame
    equals one built from scratch; moving the camera rebuilds them."""
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=4)
    scene.ols.scattering_technique = "EPIPOLAR_SAMPLING"
    epipolar_air = extension_module("lut_gen.passes.epipolar_air")
    frame_update = extension_module("addon.scene.frame.frame_update")
    calls = []
    original = epipolar_air.build
    monkeypatch.setattr(epipolar_air, "build", lambda *a, **k: calls.append(1) or original(*a, **k))
    render_rgb(scene, tmp_path / "first.exr", composite=True)
    assert len(calls) == 1
    terrain = next(o for o in scene.objects if o.type == "MESH")
    terrain.location.z += 300.0
    reused = render_rgb(scene, tmp_path / "reused.exr", composite=True)
    assert len(calls) == 1
    frame_update.forget()
    fresh = render_rgb(scene, tmp_path / "fresh.exr", composite=True)
    assert len(calls) == 2
    assert np.abs(reused - fresh).max() <= 1e-6 * max(np.abs(fresh).max(), 1e-6)
    scene.camera.location.z += 50.0
    render_rgb(scene, tmp_path / "camera.exr", composite=True)
    assert len(calls) == 3


def test_jitter_steps_offsets_each_pixel_as_the_twin_does(addon_package, tmp_path, monkeypatch):
    """Brute force with Jitter Steps: the compositor's per-pixel offsets (interleaved gradient
    noise of the pixel's coordinates) and its depth-aware 3 x 3 mean of the darkening (Translate
    nodes) match lut_gen.passes.jitter, and they change the picture (the control is not a
    no-op)."""
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=8)
    scene.ols.scattering_technique = "BRUTE_FORCE"
    passes = render_passes(addon_package, scene, tmp_path)
    twin = Twin(addon_package, scene, passes)
    scene.ols.jitter_steps = True
    jittered = render_rgb(scene, tmp_path / "jittered.exr", composite=True)[::-1]
    expected = twin()
    assert np.isfinite(jittered).all()
    error = relative_error(jittered, expected)
    print("jitter: median", np.median(error), "p99", np.percentile(error, 99))
    # float32 noise in the compositor against float64: offsets differ by up to ~1e-4 of a step.
    assert np.median(error) <= 1e-4 and np.percentile(error, 99) <= 1e-2
    plain = twin(jitter_steps=False)
    assert relative_error(plain, expected).max() > 1e-3        # the offsets moved the samples
    scene.ols.jitter_steps = False
    unjittered = render_rgb(scene, tmp_path / "plain.exr", composite=True)[::-1]
    assert np.median(relative_error(unjittered, plain)) <= 1e-4
