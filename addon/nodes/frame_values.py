""""OLS Frame Values": the per-frame numbers of the scattering passes (camera, sun, shadow
cascades) read from a small image, one pixel per value.

Why an image and not group inputs: in an animation render Blender copies compositor inputs into
the render's depsgraph before our handlers for that frame run, so inputs set there arrive one
frame late; image pixels are read when the compositor runs (measured in bpy 5.0.1). The add-on
writes the image before each frame renders (addon.scene.compositor.update_frame) and on every
interactive change.
"""
from __future__ import annotations

import numpy as np

from .builder import group_io, new_group

GROUP_NAME = "OLS Frame Values"
MAX_CASCADES = 8
VECTOR_ROWS = (["Camera Position", "Camera Forward", "Camera Right", "Camera Up", "Tan Half FOV", "Sun Direction",
                "Light Right", "Light Up"]
               + [f"Cascade {i} {part}" for i in range(MAX_CASCADES) for part in ("Center", "Half")]
               + ["Epipolar Axis 1", "Epipolar Axis 2", "Epipolar Phi", "Epipolar Theta", "Epipolar Depth",
                  "Epipolar Grid", "Epipolar Air Grid"])
SCALAR_ROW = "Scalars"       # x: sun strength, y: far depth of the last cascade, z: sky depth
ROWS = VECTOR_ROWS + [SCALAR_ROW]
SCALARS = ("Sun Strength", "Far Depth", "Sky Depth")


def pack(values: dict, previous=None) -> np.ndarray:
    """(len(ROWS), 1, 4) float32 pixels; names absent from ``values`` keep ``previous``."""
    table = np.zeros((len(ROWS), 1, 4), dtype=np.float32) if previous is None else previous.copy()
    table[..., 3] = 1.0
    for row, name in enumerate(VECTOR_ROWS):
        if name in values:
            table[row, 0, :3] = values[name]
    for component, name in enumerate(SCALARS):
        if name in values:
            table[len(VECTOR_ROWS), 0, component] = values[name]
    return table


ROWS_KEY = "ols_rows"        # on the group: the rows it was built for (see is_current)


def is_current(tree, image) -> bool:
    """Whether ``tree`` is this version's group reading ``image``: it does not depend on the
    light shafts' layout, so their rebuilds keep it."""
    return (tree is not None and tree.get(ROWS_KEY) == repr(ROWS)
            and any(node.bl_idname == "CompositorNodeImage" and node.image == image for node in tree.nodes))


def build_frame_values_group(image):
    """Outputs named as the inputs of the aerial and light-shaft groups they feed. The "Image"
    input only gives the outputs the render's size (each pixel reads the same value)."""
    tree = new_group(GROUP_NAME, "CompositorNodeTree")
    tree[ROWS_KEY] = repr(ROWS)
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
