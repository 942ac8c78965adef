"""Min/max mipmaps of the shadow cascades: a shadow test that skips the PCF taps of points that
are surely lit or surely in shadow (the epipolar technique's "1D min/max optimization", made
2D because the table rays are marched in world space). The answer is exactly
shadow_map.visibility's; only the work differs.

Per cascade, the stored sun depths are max- and min-filtered over the PCF footprint (the texel
and its four neighbours, clamped at the edges like the taps) and reduced over BLOCK x BLOCK
texel blocks. A point at or above its block's largest depth (minus the bias) passes every tap;
one below its block's smallest fails every tap. Only the rest are tested tap by tap.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .shadow_map import PCF_OFFSETS, Camera, ShadowCascades, locate, tap_fraction

BLOCK = 8


@dataclass
class MinMaxMaps:
    """(cascades, blocks, blocks) largest and smallest stored depth per block, PCF-dilated."""
    high: np.ndarray
    low: np.ndarray
    smooth: bool


def build(cascades: ShadowCascades, smooth: bool) -> MinMaxMaps:
    depths = np.asarray(cascades.depths, dtype=np.float32)      # exact: the maps are stored as float32
    if smooth:
        padded = np.pad(depths, ((0, 0), (1, 1), (1, 1)), mode="edge")
        res = cascades.resolution
        high, low = depths.copy(), depths.copy()
        for dx, dy in PCF_OFFSETS[1:]:
            shifted = padded[:, 1 + dy:1 + dy + res, 1 + dx:1 + dx + res]
            np.maximum(high, shifted, out=high)
            np.minimum(low, shifted, out=low)
    else:
        high = low = depths
    n, res = len(depths), cascades.resolution
    blocks = -(-res // BLOCK)
    pad = blocks * BLOCK - res
    high = np.pad(high, ((0, 0), (0, pad), (0, pad)), mode="edge").reshape(n, blocks, BLOCK, blocks, BLOCK)
    low = np.pad(low, ((0, 0), (0, pad), (0, pad)), mode="edge").reshape(n, blocks, BLOCK, blocks, BLOCK)
    return MinMaxMaps(high.max(axis=(2, 4)), low.min(axis=(2, 4)), smooth)


def visibility(cascades: ShadowCascades, maps: MinMaxMaps, points, camera: Camera, best_search: bool = True,
               first_cascade: int = 0) -> np.ndarray:
    """shadow_map.visibility (with PCF as ``maps`` was built), skipping decided points' taps."""
    tested, cascade, row, column, depth, bias = locate(cascades, points, camera, best_search, first_cascade)
    res = cascades.resolution
    block_row, block_column = np.clip(row, 0, res - 1) // BLOCK, np.clip(column, 0, res - 1) // BLOCK
    lit = np.where(depth >= maps.high[cascade, block_row, block_column] - bias, 1.0, 0.0)
    undecided = tested & (depth >= maps.low[cascade, block_row, block_column] - bias) & (lit == 0.0)
    if undecided.any():
        lit[undecided] = tap_fraction(cascades, cascade[undecided], row[undecided], column[undecided],
                                      depth[undecided], bias[undecided], maps.smooth)
    return np.where(tested, lit, 1.0)
