"""The Atmosphere Model control (scene.ols.atmosphere_model): Set Up Scene under the analytic
model with no tables at all, the switch to it and back without a re-bake, its sliders, bad
input."""
import math
import time

import numpy as np
import pytest

from extension import extension_module
from render_util import render_rgb
from scenes import sample_scene, shaft_layout

bpy = pytest.importorskip("bpy")


def _small(scene, seed=5):
    scene.render.resolution_x, scene.render.resolution_y = 48, 27
    scene.cycles.samples = 2
    scene.cycles.seed = seed
    scene.ols.auto_exposure = False                     # the same exposure for every variant


def _refuse_baking(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("re-baked")
    monkeypatch.setattr(extension_module("lut_gen.store.cache"), "bake_validated", refuse)


def test_switching_to_analytic_and_back_renders_the_same_pixels_without_a_re_bake(addon_package, tmp_path,
                                                                                   monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    scene = sample_scene(addon_package)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    _small(scene)
    key = scene["ols_bake_key"]
    before = render_rgb(scene, tmp_path / "before.exr", composite=True)
    _refuse_baking(monkeypatch)
    files = sorted((p.name, p.stat().st_mtime_ns) for p in (tmp_path / "cache").rglob("*"))

    started = time.perf_counter()
    scene.ols.atmosphere_model = "ANALYTIC"
    print(f"switch to analytic: {time.perf_counter() - started:.3f} s")
    assert scene["ols_bake_key"] == extension_module("addon.scene.names").ANALYTIC_WIRED
    analytic = render_rgb(scene, tmp_path / "analytic.exr", composite=True)
    assert np.isfinite(analytic).all() and analytic.mean() > 0.05 * before.mean()
    assert np.abs(analytic - before).mean() > 1e-3 * before.mean()        # another model shows

    started = time.perf_counter()
    scene.ols.atmosphere_model = "PRECOMPUTED"
    print(f"switch back to the tables: {time.perf_counter() - started:.3f} s")
    assert scene["ols_bake_key"] == key
    after = render_rgb(scene, tmp_path / "after.exr", composite=True)
    np.testing.assert_allclose(after, before, rtol=0, atol=1e-5)

    # Again: the formula groups come back from the copies kept at the first switch (no node built).
    nodes = extension_module("addon.nodes")
    monkeypatch.setattr(nodes, "build_analytic_sky_group", lambda *a: pytest.fail("rebuilt the analytic sky"))
    started = time.perf_counter()
    scene.ols.atmosphere_model = "ANALYTIC"
    print(f"second switch to analytic: {time.perf_counter() - started:.3f} s")
    again = render_rgb(scene, tmp_path / "analytic_again.exr", composite=True)
    np.testing.assert_allclose(again, analytic, rtol=0, atol=1e-6)
    scene.ols.atmosphere_model = "PRECOMPUTED"
    np.testing.assert_allclose(render_rgb(scene, tmp_path / "after2.exr", composite=True), before, rtol=0, atol=1e-5)
    assert sorted((p.name, p.stat().st_mtime_ns) for p in (tmp_path / "cache").rglob("*")) == files


def test_set_up_with_the_analytic_model_needs_no_tables(addon_package, tmp_path, monkeypatch):
    """An empty, read-only cache directory: Set Up Scene, a slider change and a render read and
    write no table file; the sliders rebuild the groups at once."""
    cache = tmp_path / "cache"
    cache.mkdir()
    cache.chmod(0o555)
    monkeypatch.setenv("OLS_CACHE_DIR", str(cache))
    _refuse_baking(monkeypatch)
    scene = sample_scene(addon_package)
    scene.ols.atmosphere_model = "ANALYTIC"
    started = time.perf_counter()
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    print(f"set up under the analytic model: {time.perf_counter() - started:.3f} s")
    _small(scene)
    aerial = scene.compositing_node_group.nodes["OLS Aerial Perspective"]
    for name in ("Camera Position", "Sun Direction", "Sun Strength"):     # camera and sun per frame
        assert aerial.inputs[name].links[0].from_node.name == "OLS Frame Values", name
    shafts = scene.compositing_node_group.nodes["OLS Light Shafts"]      # the shafts are on, analytic
    assert scene.ols.enable_light_shafts and not shafts.mute and shaft_layout(shafts.node_tree)["analytic"]
    clear = render_rgb(scene, tmp_path / "clear.exr", composite=True)
    assert np.isfinite(clear).all() and clear.mean() > 0.02
    other = "BRUTE_FORCE" if scene.ols.scattering_technique == "EPIPOLAR_SAMPLING" else "EPIPOLAR_SAMPLING"
    scene.ols.scattering_technique = other                  # the other technique: no tables either
    marched = render_rgb(scene, tmp_path / "marched.exr", composite=True)
    assert shafts.node_tree["ols_layout"].find(other) >= 0
    assert np.isfinite(marched).all() and np.abs(marched - clear).mean() < 0.05 * clear.mean()

    started = time.perf_counter()
    scene.ols.aerosol_density = 4.0                      # rebuilt now, no bake started
    print(f"aerosol slider to rebuilt groups: {time.perf_counter() - started:.3f} s")
    hazy = render_rgb(scene, tmp_path / "hazy.exr", composite=True)
    assert np.abs(hazy - clear).mean() > 0.01 * clear.mean()
    assert list(cache.iterdir()) == []
    assert not [image.name for image in bpy.data.images if image.filepath.endswith(".exr")]
    assert not extension_module("addon.baking").showing_preview(scene)
    assert extension_module("addon.scene.tables.wired_bake").table_problem(scene) is None


def test_nan_and_out_of_range_haze_clamp_under_the_analytic_model(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    scene = sample_scene(addon_package)
    scene.ols.atmosphere_model = "ANALYTIC"
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    _small(scene)
    default = render_rgb(scene, tmp_path / "default.exr", composite=True)
    wiring = extension_module("addon.scene.setup.wiring")
    # ID-property writes bypass the controls' ranges and updates, as a script or a driver may
    scene.ols["aerosol_density"] = float("nan")
    wiring.use_model(scene)
    nan = render_rgb(scene, tmp_path / "nan.exr", composite=True)
    np.testing.assert_allclose(nan, default, rtol=0, atol=1e-5)            # NaN reads as the default
    scene.ols["aerosol_density"] = 1e9
    scene.ols["aerosol_absorption"] = -3.0
    wiring.use_model(scene)
    far = render_rgb(scene, tmp_path / "far.exr", composite=True)
    scene.ols["aerosol_density"] = 5.0                                      # the control's maximum
    scene.ols["aerosol_absorption"] = 0.0
    wiring.use_model(scene)
    top = render_rgb(scene, tmp_path / "top.exr", composite=True)
    assert np.isfinite(far).all()
    np.testing.assert_allclose(far, top, rtol=0, atol=1e-5)                # clamped to the range
    assert not math.isclose(float(far.mean()), float(default.mean()), rel_tol=1e-3)


def test_a_headless_render_with_the_analytic_model_needs_no_tables(addon_package, tmp_path, monkeypatch):
    """scripts/render.py --atmosphere-model analytic with an empty, read-only cache: the sample
    renders (not black) and nothing is baked or written there."""
    cache = tmp_path / "cache"
    cache.mkdir()
    cache.chmod(0o555)
    monkeypatch.setenv("OLS_CACHE_DIR", str(cache))
    _refuse_baking(monkeypatch)
    batch = extension_module("addon.batch")
    out = tmp_path / "analytic.exr"
    assert batch.main(["--sample", "--atmosphere-model", "analytic", "--resolution", "48x27", "--samples", "1",
                       "--output", str(out)]) == 0
    assert out.exists() and list(cache.iterdir()) == []
    scene = bpy.context.scene
    assert scene["ols_bake_key"] == extension_module("addon.scene.names").ANALYTIC_WIRED
    image = bpy.data.images.load(str(out))
    pixels = np.array(image.pixels[:]).reshape(27, 48, 4)[..., :3]
    assert np.isfinite(pixels).all() and pixels.mean() > 0.02


def test_there_are_no_tables_to_pack_under_the_analytic_model(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    scene = sample_scene(addon_package)
    scene.ols.atmosphere_model = "ANALYTIC"
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    assert not bpy.ops.ols.pack_tables.poll()
    blend = tmp_path / "analytic.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    batch = extension_module("addon.batch")
    assert batch.main(["--blend", str(blend), "--pack"]) == 1


def test_a_scene_set_up_analytic_gets_the_light_shafts_when_switched_to_the_tables(addon_package, tmp_path,
                                                                                   monkeypatch):
    """Set up under the analytic model (its own shaft groups), then switched to cached tables:
    the tables' shaft groups are built and linked in their place, and the frame renders as a
    scene set up on the tables."""
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    baking = extension_module("addon.baking")
    baking.bake_if_needed(addon_package.lut_gen.AtmosphereParams(), "draft")
    scene = sample_scene(addon_package)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    _small(scene)
    tables = render_rgb(scene, tmp_path / "tables.exr", composite=True)

    scene = sample_scene(addon_package)
    for name in [n for n in bpy.data.node_groups.keys() if n.startswith("OLS ")]:
        bpy.data.node_groups.remove(bpy.data.node_groups[name])
    scene.ols.atmosphere_model = "ANALYTIC"
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    assert shaft_layout(bpy.data.node_groups["OLS Light Shafts"])["analytic"]        # analytic
    _refuse_baking(monkeypatch)
    scene.ols.atmosphere_model = "PRECOMPUTED"
    shafts = scene.compositing_node_group.nodes.get("OLS Light Shafts")
    assert shafts is not None and not shafts.mute and shafts.inputs["Image"].is_linked
    assert not shaft_layout(shafts.node_tree)["analytic"]                              # the tables'
    assert "OLS Analytic March Chunk" not in {n.node_tree.name for n in shafts.node_tree.nodes
                                              if n.type == "GROUP" and n.node_tree}
    _small(scene)
    switched = render_rgb(scene, tmp_path / "switched.exr", composite=True)
    np.testing.assert_allclose(switched, tables, rtol=0, atol=1e-4)
