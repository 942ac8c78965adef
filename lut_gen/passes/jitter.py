"""Jittered march steps (the demoscene ray marcher's trick): each pixel's brute-force march
takes its samples at (k + offset) x step instead of the step centres, with an offset in [0, 1)
that changes from pixel to pixel. A march of few steps counts a shaft's lit length in whole
steps, so neighbouring pixels whose rays cross a shadow edge at nearly the same distance
round it the same way and the sky shows bands; with the offset they round it differently,
and the bands become fine noise that averages out over a few pixels.

The offset is interleaved gradient noise (Jimenez 2014, "Next Generation Post Processing in
Call of Duty: Advanced Warfare"): a closed form of the pixel coordinates whose values are
spread evenly over every 3 x 3 neighbourhood (blue-noise-like), cheap in compositor nodes and
exact in numpy, with no texture to ship. It depends on the pixel alone, so every frame and
every farm chunk gets the same pattern. The node group's twin: addon.nodes.jitter.
"""
from __future__ import annotations

import numpy as np

# fract(MAGIC_Z * fract(MAGIC_X x + MAGIC_Y y)) at integer pixel coordinates (x, y).
MAGIC_X, MAGIC_Y, MAGIC_Z = 0.06711056, 0.00583715, 52.9829189
CENTRE = 0.5            # the offset without jitter: the step centres


def interleaved_gradient_noise(x, y) -> np.ndarray:
    """Values in [0, 1) at pixel coordinates ``x``, ``y`` (column, row from the bottom)."""
    inner = MAGIC_X * np.asarray(x, dtype=np.float64) + MAGIC_Y * np.asarray(y, dtype=np.float64)
    return np.mod(MAGIC_Z * np.mod(inner, 1.0), 1.0)


def step_offsets(height: int, width: int, enabled: bool = True) -> np.ndarray:
    """(height, width) offsets of the march steps within their steps, rows bottom to top (as
    the render passes): the noise when ``enabled``, else CENTRE everywhere."""
    if not enabled:
        return np.full((height, width), CENTRE)
    y, x = np.mgrid[0:height, 0:width]
    return interleaved_gradient_noise(x, y)
