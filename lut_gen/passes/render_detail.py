"""Level of detail of the per-frame light-shaft data for the render's size in pixels.

The sun's shadow maps and the epipolar tables are made in numpy before each frame, and their
cost grows with their size, not the render's. A small render (a preview at 25 %, a thumbnail,
a 64 x 36 test) cannot resolve more than its pixels show, so past these caps a larger setting
costs seconds a frame and changes nothing a pixel can hold:

- Epipolar slices: neighbouring slices are at most perimeter / slices pixels apart (where they
  meet the screen's border, farthest from the epipole; nearer it they converge). Past the
  screen's perimeter in pixels, 2 (W + H), they are less than a pixel apart everywhere.
- Samples per slice: a slice crosses at most the screen's diagonal. The samples are even in
  angle, and a perspective camera stretches angles toward the screen's edge (1 / cos^2 of the
  angle off the axis: 1.2 at a 50 mm lens's corners, 2.3 at 90 degrees of field of view), so
  twice the diagonal keeps them under a pixel apart up to about 90 degrees of field of view.
- Shadow-map texels: a cascade covers the frustum up to its far split, so at its far split a
  texel is about (render width / resolution) of a pixel's footprint, and at its near split
  the cascades' depth ratio (3.2 for 6 logarithmic cascades over 10 m - 10 km) times that.
  At SHADOW_TEXELS_PER_PIXEL texels per pixel of the larger side a texel stays under half a
  pixel's footprint; finer maps only resample the same shafts.

The caps apply only to renders smaller than the settings need: 2048 slices x 2048 samples
and 4096-texel maps are all used from 1024 x 576 pixels up (4096-texel maps from 257 pixels on the
larger side up, 2048 from 129).
"""
from __future__ import annotations

import math

SHADOW_TEXELS_PER_PIXEL = 8
SMALLEST_SHADOW_MAP = 512           # the panel's smallest
SMALLEST_EPIPOLAR = 32              # the panel's smallest slices and samples


def render_size(resolution_x: int, resolution_y: int, percentage: float = 100.0) -> tuple[int, int]:
    """(width, height) in pixels of a render of resolution_x x resolution_y at ``percentage``."""
    scale = percentage / 100.0
    return max(int(resolution_x * scale), 1), max(int(resolution_y * scale), 1)


def shadow_map_resolution(requested: int, width: int, height: int) -> int:
    """Texels a side of the shadow maps of a width x height render: ``requested``, at most the
    power of two at or above SHADOW_TEXELS_PER_PIXEL x the larger side (never under 512)."""
    needed = SHADOW_TEXELS_PER_PIXEL * max(int(width), int(height), 1)
    cap = max(SMALLEST_SHADOW_MAP, 1 << (needed - 1).bit_length())
    return min(int(requested), cap)


def epipolar_slices(requested: int, width: int, height: int) -> int:
    """Epipolar slices of a width x height render: ``requested``, at most its perimeter."""
    return min(int(requested), max(SMALLEST_EPIPOLAR, 2 * (int(width) + int(height))))


def epipolar_samples(requested: int, width: int, height: int) -> int:
    """Samples per epipolar slice: ``requested``, at most twice the render's diagonal."""
    return min(int(requested), max(SMALLEST_EPIPOLAR, math.ceil(2.0 * math.hypot(width, height))))


def capped_fields(width: int, height: int) -> dict:
    """{scene.ols name: function of the requested value} for a width x height render."""
    return {"shadow_map_resolution": lambda value: str(shadow_map_resolution(int(value), width, height)),
            "epipolar_slices": lambda value: epipolar_slices(value, width, height),
            "samples_per_slice": lambda value: epipolar_samples(value, width, height)}
