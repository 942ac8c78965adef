"""The light-shaft compositor pass ("OLS Aerial Perspective" + "OLS Light Shafts" as wired by
Set Up Scene) on a small Cycles render of the sample, against its numpy twin
lut_gen.scattering_pass fed the same render passes and the same shadow cascades: every one of
the sample's 3 x 3 scattering modes, light shafts visibly present, Show Cascades, and the
cases where the pass cannot run."""
from importlib import import_module

import numpy as np
import pytest

from render_util import render_rgb, save_png
from test_aerial_pass import compositor_output
from test_tone_mapping import sample_scene

bpy = pytest.importorskip("bpy")

WIDTH, HEIGHT = 160, 90
MODES = [(s, m) for s in ("NONE", "INTEGRATION", "LUT") for m in ("NONE", "OCCLUDED", "UNOCCLUDED")]


def low_sun_scene(pkg, tmp_path, monkeypatch, steps=16):
    """The sample with the sun 5 degrees up straight ahead, behind the ridge, wired with draft
    tables; the tone mapping is muted so the composite is the scattering pass itself."""
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    scene = sample_scene(pkg)
    sun_mod = import_module(pkg.__name__ + ".addon.scene.sun")
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


def render_passes(scene, tmp_path):
    """Raw image, position and depth of the render (rows bottom to top, as the twin wants)."""
    tree = scene.compositing_node_group
    raw = render_rgb(scene, tmp_path / "raw.exr")
    compositor_output(scene, lambda t, layers: layers.outputs["Position"])
    position = render_rgb(scene, tmp_path / "position.exr", composite=True)

    def depth_image(t, layers):
        combine = t.nodes.new("CompositorNodeCombineColor")
        for name in ("Red", "Green", "Blue"):
            t.links.new(layers.outputs["Depth"], combine.inputs[name])
        return combine.outputs["Image"]
    compositor_output(scene, depth_image)
    depth = render_rgb(scene, tmp_path / "depth.exr", composite=True)[..., 0]
    scene.compositing_node_group = tree
    return raw[::-1], position[::-1], depth[::-1]


class Twin:
    """lut_gen.scattering_pass with the scene's camera, sun, tables and shadow cascades."""

    def __init__(self, pkg, scene, passes):
        self.pkg, self.scene, self.passes = pkg, scene, passes
        ops = import_module(pkg.__name__ + ".addon.ops")
        self.luts = pkg.lut_gen.load(ops.bake_if_needed(pkg.lut_gen.AtmosphereParams(), "draft"))
        self.shadow_maps = import_module(pkg.__name__ + ".addon.scene.shadow_maps")
        sun_mod = import_module(pkg.__name__ + ".addon.scene.sun")
        self.sun = sun_mod.direction_to_sun(sun_mod.find_sun(scene))
        self.camera = self.shadow_maps.camera_model(scene)

    def cascades(self):
        return self.shadow_maps.render(self.scene, bpy.context.evaluated_depsgraph_get())

    def __call__(self, **overrides):
        settings = self.scene.ols
        fields = self.pkg.lut_gen.scattering_pass.PassSettings.__dataclass_fields__
        values = {name: getattr(settings, name) for name in fields if hasattr(settings, name)}
        values.update(sun_strength=10.0, **overrides)
        pass_settings = self.pkg.lut_gen.scattering_pass.PassSettings(**values)
        return self.pkg.lut_gen.scattering_pass.scattering_pass(
            self.luts, *self.passes, self.camera, self.sun, self.cascades(), pass_settings)


def relative_error(seen, twin):
    return np.abs(seen - twin).sum(axis=-1) / np.maximum(twin.sum(axis=-1), 1e-4)


def test_every_scattering_mode_matches_the_twin_and_shafts_show(addon_package, tmp_path, monkeypatch):
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch)
    passes = render_passes(scene, tmp_path)
    raw, position, depth = passes
    geometry = depth < 1e9
    assert 0.2 < geometry.mean() < 0.9                        # terrain and sky in view
    twin = Twin(addon_package, scene, passes)
    errors = {}
    for single, multiple in MODES:
        scene.ols.single_scattering_mode, scene.ols.multiple_scattering_mode = single, multiple
        seen = render_rgb(scene, tmp_path / f"{single}_{multiple}.exr", composite=True)[::-1]
        expected = twin()
        assert np.isfinite(seen).all()
        errors[single, multiple] = float(np.median(relative_error(seen, expected)))
        if (single, multiple) == ("LUT", "UNOCCLUDED"):
            save_png(tmp_path / "shafts.png", seen[::-1], 1.0)
            save_png(tmp_path / "unshadowed.png", twin(enable_light_shafts=False)[::-1], 1.0)
            unshadowed = twin(enable_light_shafts=False)
            shadow_effect = unshadowed - expected
    print("median relative error per mode:", errors)
    assert max(errors.values()) <= 0.03, errors
    # Light shafts are present: the ridge's shadow takes light out of the air over the valley
    # and in the sky around the sun, unevenly across the columns of the image.
    darker = shadow_effect.sum(axis=-1)
    assert (darker > 0.01 * np.maximum(expected.sum(axis=-1), 1e-6)).mean() > 0.05
    column_effect = darker.mean(axis=0)
    assert column_effect.max() > 2.0 * max(column_effect.min(), 1e-9)


def test_without_occluders_the_pass_equals_the_unshadowed_result(addon_package, tmp_path, monkeypatch):
    scene = low_sun_scene(addon_package, tmp_path, monkeypatch, steps=8)
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
