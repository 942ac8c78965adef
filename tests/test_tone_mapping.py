"""The "OLS Tone Mapping" compositor group vs the numpy twin of the sample's formulas."""
from importlib import import_module

import numpy as np
import pytest

from render_util import empty_scene, render_rgb

bpy = pytest.importorskip("bpy")
WIDTH, HEIGHT = 64, 4


def hdr_ramp():
    """Luminance from 1e-3 to 1e2 left to right; rows of different chroma."""
    lum = np.logspace(-3, 2, WIDTH)
    tints = np.array([[1.0, 1.0, 1.0], [1.0, 0.5, 0.2], [0.2, 0.5, 1.0], [0.9, 1.0, 0.3]])
    return lum[None, :, None] * tints[:, None, :]          # (HEIGHT, WIDTH, 3), row 0 at the top


def composite(pkg, tmp_path, rgb, **inputs):
    nodes = import_module(pkg.__name__ + ".addon.nodes")
    scene = empty_scene(width=WIDTH, height=HEIGHT, samples=1)
    camera = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    image = bpy.data.images.new("ramp", WIDTH, HEIGHT, alpha=True, float_buffer=True)
    image.colorspace_settings.is_data = True               # before filling: it regenerates the buffer
    rgba = np.ones((HEIGHT, WIDTH, 4), np.float32)
    rgba[..., :3] = rgb[::-1]                               # image rows bottom to top
    image.pixels.foreach_set(rgba.ravel())
    group = nodes.build_tone_mapping_group()
    tree = bpy.data.node_groups.new("test compositing", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    source = tree.nodes.new("CompositorNodeImage")
    source.image = image
    node = tree.nodes.new("CompositorNodeGroup")
    node.node_tree = group
    output = tree.nodes.new("NodeGroupOutput")
    tree.links.new(source.outputs["Image"], node.inputs["Image"])
    tree.links.new(node.outputs["Image"], output.inputs[0])
    for name, value in inputs.items():
        node.inputs[name].default_value = value
    scene.compositing_node_group = tree
    scene.render.use_compositing = True
    return render_rgb(scene, tmp_path / "tone.exr")


@pytest.mark.parametrize("auto_exposure", [True, False])
def test_every_operator_matches_the_sample_formula(addon_package, tmp_path, auto_exposure):
    twin = import_module(addon_package.__name__ + ".addon.post.tone_mapping")
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
    twin = import_module(addon_package.__name__ + ".addon.post.tone_mapping")
    rgb = hdr_ramp()
    results = [twin.tone_map(rgb, op) for op in twin.OPERATORS]
    for i in range(len(results)):
        for j in range(i + 1, len(results)):
            assert np.abs(results[i] - results[j]).max() > 0.01
    assert twin.adapted_luminance(1.0, 2.0, 0.0) == 1.0
    assert twin.adapted_luminance(1.0, 2.0, 1.0) == pytest.approx(1.0 + (1 - np.exp(-1.0)))
