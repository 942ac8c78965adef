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

The noise alone costs accuracy: at 16 steps the mean error grew by 6% (bench/bench_jitter.py).
Interleaved gradient noise spreads the offsets of every 3 x 3 neighbourhood over [0, 1), so the
mean of a pixel's neighbours is a march of nine interleaved offsets, nine times finer: averaging
the shafts' darkening over the 3 x 3 block (``neighbourhood_mean``) keeps the gain against the
bands and removes most of the noise. Only neighbours at nearly the same ray length count, so a
pillar's darkening never bleeds into the sky beside it.
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


RADIUS = 1              # the 3 x 3 block the noise is spread over
LENGTH_TOLERANCE = 0.05  # neighbours whose ray is within 5% of the pixel's length count


def shifted(image, dy: int, dx: int):
    """``image`` (H, W, ...) moved by (dy, dx) pixels, zeros where nothing moved in (the
    compositor's Translate with Clip)."""
    out = np.zeros_like(image)
    height, width = image.shape[:2]
    out[max(dy, 0):height + min(dy, 0), max(dx, 0):width + min(dx, 0)] = \
        image[max(-dy, 0):height + min(-dy, 0), max(-dx, 0):width + min(-dx, 0)]
    return out


def neighbour_offsets():
    return [(dy, dx) for dy in range(-RADIUS, RADIUS + 1) for dx in range(-RADIUS, RADIUS + 1)]


def neighbourhood_mean(values, length):
    """(H, W, C) mean of ``values`` over each pixel's 3 x 3 block, counting only the pixels
    inside the image whose ray ``length`` (H, W) is within LENGTH_TOLERANCE of the pixel's own."""
    values = np.asarray(values, dtype=np.float64)
    length = np.asarray(length, dtype=np.float64)
    inside = np.ones_like(length)
    total, weight = np.zeros_like(values), np.zeros_like(length)
    for dy, dx in neighbour_offsets():
        near = shifted(inside, dy, dx) * (np.abs(shifted(length, dy, dx) - length) < LENGTH_TOLERANCE * length)
        total += near[..., None] * shifted(values, dy, dx)
        weight += near
    return total / np.maximum(weight, 1.0)[..., None]
