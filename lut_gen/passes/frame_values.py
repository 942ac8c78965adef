"""The layout of the "OLS Frame Values" image: the per-frame numbers of the scattering passes
(camera, sun, shadow cascades, epipolar frame), one pixel per row, written by ``pack`` before
each frame and read back by the frame-values node group, whose twin is ``unpack``.
"""
from __future__ import annotations

import numpy as np

from ..clouds.shafts import ROWS as CLOUD_ROWS
from ..clouds.veil import ROWS as VEIL_ROWS

MAX_CASCADES = 8
VECTOR_ROWS = (["Camera Position", "Camera Forward", "Camera Right", "Camera Up", "Tan Half FOV", "Sun Direction",
                "Light Right", "Light Up"]
               + [f"Cascade {i} {part}" for i in range(MAX_CASCADES) for part in ("Center", "Half")]
               + ["Epipolar Axis 1", "Epipolar Axis 2", "Epipolar Phi", "Epipolar Theta", "Epipolar Depth",
                  "Epipolar Grid", "Epipolar Air Grid"]
               + list(CLOUD_ROWS) + list(VEIL_ROWS))
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


def unpack(pixels) -> dict:
    """What the frame-values group outputs for the (len(ROWS), 1, 4) ``pixels``: each vector row
    as three floats and each scalar by name."""
    pixels = np.asarray(pixels, dtype=np.float32)
    values = {name: pixels[row, 0, :3].copy() for row, name in enumerate(VECTOR_ROWS)}
    values.update({name: float(pixels[len(VECTOR_ROWS), 0, c]) for c, name in enumerate(SCALARS)})
    return values
