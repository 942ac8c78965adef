"""The "OLS Tone Mapping" compositor group vs the numpy twin of the sample's formulas."""

import numpy as np
import pytest

from render_util import render_rgb
from scenes import RAMP_HEIGHT, RAMP_WIDTH, composite, hdr_ramp, sample_scene
from extension import extension_module

bpy = pytest.importorskip("bpy")
WIDTH, HEIGHT = RAMP_WIDTH, RAMP_HEIGHT






@pytest.mark.parametrize("auto_exposure", [True, False])
def test_every_operator_matches_the_sample_formula(addon_package, tmp_path, auto_exposure):
    twin = extension_module("lut_gen.passes.tone_mapping")
    rgb = hdr_ramp()
    average = twin.log_average_luminance(rgb) if auto_exposure else None
    for index, operator in enumerate(twin.OPERATORS):
        settings = dict(middle_gray=0.25, white_point=2.5, luminance_saturation=0.8)
        got = composite(addon_package, tmp_path, rgb, **{
            "Operator": float(index), "Middle Gray": settings["middle_gray"], "White Point": settings["white_point"],
            "Luminance Saturation": settings["luminance_saturation"], "Auto Exposure": float(auto_exposure)})
        want = twin.tone_map(rgb, operator, average_luminance=average, **settings)
        err = np.abs(twin.srgb_encode(got) - twin.srgb_encode(want)).max()
        assert err <= 1e-3, (operator, err)
        assert np.ptp(twin.srgb_encode(want)) > 0.3          # the ramp spans the display range


def test_operators_differ(addon_package):
    twin = extension_module("lut_gen.passes.tone_mapping")
    rgb = hdr_ramp()
    results = [twin.tone_map(rgb, op) for op in twin.OPERATORS]
    for i in range(len(results)):
        for j in range(i + 1, len(results)):
            assert np.abs(results[i] - results[j]).max() > 0.01
    assert twin.adapted_luminance(1.0, 2.0, 0.0) == 1.0
    assert twin.adapted_luminance(1.0, 2.0, 1.0) == pytest.approx(1.0 + (1 - np.exp(-1.0)))




def test_setup_inserts_tone_mapping_and_unwire_restores_the_users_tree(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    scene = sample_scene(addon_package)
    tree = bpy.data.node_groups.new("My Compositing", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    layers = tree.nodes.new("CompositorNodeRLayers")
    blur = tree.nodes.new("CompositorNodeBlur")
    output = tree.nodes.new("NodeGroupOutput")
    tree.links.new(layers.outputs["Image"], blur.inputs["Image"])
    tree.links.new(blur.outputs["Image"], output.inputs[0])
    scene.compositing_node_group = tree
    scene.view_settings.view_transform = "AgX"

    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    node = tree.nodes["OLS Tone Mapping"]
    aerial = tree.nodes["OLS Aerial Perspective"]
    shafts = tree.nodes["OLS Light Shafts"]
    assert output.inputs[0].links[0].from_node == node and node.inputs["Image"].links[0].from_node == blur
    assert blur.inputs["Image"].links[0].from_node == shafts       # the atmosphere before the user's nodes
    assert shafts.inputs["Image"].links[0].from_node == aerial
    assert aerial.inputs["Image"].links[0].from_node == layers
    assert scene.view_settings.view_transform == "Standard"
    scene.ols.tone_mapping_operator = "REINHARD"
    assert node.inputs["Operator"].default_value == 1.0
    scene.ols.middle_gray = 0.3
    assert node.inputs["Middle Gray"].default_value == pytest.approx(0.3)

    wiring = extension_module("addon.scene.setup.wiring")
    wiring.unwire_scene(scene)
    assert "OLS Tone Mapping" not in tree.nodes and output.inputs[0].links[0].from_node == blur
    assert not any(n.name.startswith("OLS") for n in tree.nodes)
    assert scene.view_settings.view_transform == "AgX" and scene.compositing_node_group == tree


def test_tone_mapped_sample_render_matches_the_twin(addon_package, tmp_path, monkeypatch):
    """The whole chain: a render of the wired sample, tone mapped by the compositor, equals the
    numpy operator applied to the same render without compositing."""
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    twin = extension_module("lut_gen.passes.tone_mapping")
    scene = sample_scene(addon_package)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    assert bpy.data.node_groups.get("OLS Compositing") == scene.compositing_node_group
    scene.ols.enable_light_scattering = False           # tone mapping alone (aerial: test_aerial_pass)
    scene.ols.tone_map_exr = True                       # render_rgb reads OpenEXR
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    scene.cycles.samples = 4
    scene.cycles.seed = 1
    raw = render_rgb(scene, tmp_path / "raw.exr")
    mapped = render_rgb(scene, tmp_path / "mapped.exr", composite=True)
    want = twin.tone_map(raw, "UNCHARTED2", average_luminance=twin.log_average_luminance(raw))
    assert np.abs(twin.srgb_encode(mapped) - twin.srgb_encode(want)).max() <= 2e-3
    assert 0.05 < twin.srgb_encode(mapped).mean() < 0.95
    # The panel's controls reach the render.
    scene.ols.tone_mapping_operator = "REINHARD"
    scene.ols.white_point = 5.0
    scene.ols.middle_gray = 0.4
    reinhard = render_rgb(scene, tmp_path / "reinhard.exr", composite=True)
    want = twin.tone_map(raw, "REINHARD", middle_gray=0.4, white_point=5.0,
                         average_luminance=twin.log_average_luminance(raw))
    assert np.abs(twin.srgb_encode(reinhard) - twin.srgb_encode(want)).max() <= 2e-3
