""""OLS Frame Values": the per-frame numbers of the scattering passes (camera, sun, shadow
cascades) read from a small image, one pixel per value.

Why an image and not group inputs: in an animation render Blender copies compositor inputs into
the render's depsgraph before our handlers for that frame run, so inputs set there arrive one
frame late; image pixels are read when the compositor runs (measured in bpy 5.0.1). The add-on
writes the image before each frame renders (addon.scene.frame.frame_update.update_frame) and on every
interactive change. The image's layout and its numpy reader (the twin) are
lut_gen/passes/frame_values.py.
"""
from __future__ import annotations

from ...lut_gen.passes.frame_values import ROWS, SCALARS, VECTOR_ROWS
from .builder import group_io, new_group
from ..scene import names


def is_current(tree, image) -> bool:
    """Whether ``tree`` is this version's group reading ``image``: it does not depend on the
    light shafts' layout, so their rebuilds keep it."""
    return (tree is not None and tree.get(names.ROWS_KEY) == repr(ROWS)
            and any(node.bl_idname == "CompositorNodeImage" and node.image == image for node in tree.nodes))


def build_frame_values_group(image):
    """Outputs named as the inputs of the aerial and light-shaft groups they feed. The "Image"
    input only gives the outputs the render's size (each pixel reads the same value)."""
    tree = new_group(names.FRAME_VALUES_GROUP, "CompositorNodeTree")
    tree[names.ROWS_KEY] = repr(ROWS)
    outputs = [(name, "NodeSocketVector", None) for name in VECTOR_ROWS] + [(n, "NodeSocketFloat", None) for n in SCALARS]
    g, gin, gout = group_io(tree, [("Image", "NodeSocketColor", (0.0, 0.0, 0.0, 1.0))], outputs)
    coordinates = g.node("CompositorNodeImageCoordinates")
    g.links.new(gin.outputs["Image"], coordinates.inputs["Image"])
    zero = g.vscale(coordinates.outputs["Normalized"], 0.0)

    def row(index):
        return g.image(image, g.vmath("ADD", zero, (0.5, (index + 0.5) / len(ROWS), 1.0)), interpolation="Closest")
    for index, name in enumerate(VECTOR_ROWS):
        g.links.new(row(index), gout.inputs[name])
    for name, value in zip(SCALARS, g.separate(row(len(VECTOR_ROWS)))):
        g.links.new(value, gout.inputs[name])
    return tree
