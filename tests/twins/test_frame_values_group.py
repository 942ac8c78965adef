"""The "OLS Frame Values" group against its twin (lut_gen.passes.frame_values.unpack): random
values packed into the image come out of every output of the group unchanged."""
import numpy as np
import pytest

from extension import extension_module
from render_util import empty_scene, render_rgb

bpy = pytest.importorskip("bpy")


def test_frame_values_group_outputs_what_unpack_reads(addon_package, tmp_path):
    layout = extension_module("lut_gen.passes.frame_values")
    nodes = extension_module("addon.nodes")
    rng = np.random.default_rng(7)
    values = {name: rng.uniform(-5.0, 5.0, 3) for name in layout.VECTOR_ROWS}
    values.update({name: float(rng.uniform(0.5, 50.0)) for name in layout.SCALARS})
    pixels = layout.pack(values)
    want = layout.unpack(pixels)
    for name in values:
        np.testing.assert_allclose(want[name], values[name], rtol=1e-6)

    scene = empty_scene(width=4, height=2, samples=1)
    camera = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    image = bpy.data.images.new("frame values", 1, len(layout.ROWS), alpha=True, float_buffer=True)
    image.colorspace_settings.is_data = True
    image.pixels.foreach_set(pixels.ravel())
    group = nodes.build_frame_values_group(image)
    tree = bpy.data.node_groups.new("test compositing", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    node = tree.nodes.new("CompositorNodeGroup")
    node.node_tree = group
    size = tree.nodes.new("CompositorNodeRGB")          # only gives the outputs a size
    tree.links.new(size.outputs[0], node.inputs["Image"])
    combine = tree.nodes.new("CompositorNodeCombineColor")
    output = tree.nodes.new("NodeGroupOutput")
    tree.links.new(combine.outputs[0], output.inputs[0])
    scene.compositing_node_group = tree
    scene.render.use_compositing = True
    for row, name in enumerate(list(layout.VECTOR_ROWS[::7]) + list(layout.SCALARS)):
        socket = node.outputs[name]
        if name in layout.SCALARS:
            for channel in range(3):
                tree.links.new(socket, combine.inputs[channel])
            seen = render_rgb(scene, tmp_path / f"{row}.exr", composite=True)
            np.testing.assert_allclose(seen, want[name], rtol=1e-5)
        else:
            separate = tree.nodes.new("ShaderNodeSeparateXYZ")
            tree.links.new(socket, separate.inputs[0])
            for channel in range(3):
                tree.links.new(separate.outputs[channel], combine.inputs[channel])
            seen = render_rgb(scene, tmp_path / f"{row}.exr", composite=True)
            np.testing.assert_allclose(seen.reshape(-1, 3), np.broadcast_to(want[name], seen.reshape(-1, 3).shape), rtol=1e-5, atol=1e-6)
