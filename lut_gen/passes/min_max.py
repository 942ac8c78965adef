"""Min/max mipmaps of the shadow cascades: a shadow test that skips the PCF taps of points that
are surely lit or surely in shadow (the epipolar technique's "1D min/max optimization", made
2D because the table rays are marched in world space). The answer is exactly
shadow_map.visibility's; only the work differs.

Per cascade, the stored sun depths are max- and min-filtered over the PCF footprint (the 3 x 3
texels around a point's texel hold its bilinear taps; clamped at the edges like the taps) and
reduced over BLOCK x BLOCK texel blocks. A point at or above its block's largest depth (minus the bias) passes every tap;
one below its block's smallest fails every tap. Only the rest are tested tap by tap.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .shadow_map import Camera, ShadowCascades, locate, tap_fraction

BLOCK_SHIFT = 3
BLOCK = 1 << BLOCK_SHIFT


@dataclass
class MinMaxMaps:
    """(cascades, blocks, blocks) largest and smallest stored depth per block, PCF-dilated."""
    high: np.ndarray
    low: np.ndarray
    smooth: bool


def build(cascades: ShadowCascades, smooth: bool) -> MinMaxMaps:
    depths = np.asarray(cascades.depths, dtype=np.float32)      # exact: the maps are stored as float32
    return MinMaxMaps(_block_reduce(depths, np.maximum, smooth), _block_reduce(depths, np.minimum, smooth), smooth)


def allocate(count: int, resolution: int, smooth: bool) -> MinMaxMaps:
    """Maps for ``count`` cascades of ``resolution`` texels, to be filled cascade by cascade
    (fill_cascade): the same maps as build's once every cascade is in."""
    blocks = -(-resolution // BLOCK)
    return MinMaxMaps(np.empty((count, blocks, blocks), np.float32), np.empty((count, blocks, blocks), np.float32),
                      smooth)


def fill_cascade(maps: MinMaxMaps, index: int, depths: np.ndarray):
    """Cascade ``index``'s part of ``maps`` from its map (res, res) (a render_cascades
    on_cascade: each cascade's blocks reduce on its own, so the maps equal build's)."""
    depths = np.asarray(depths, dtype=np.float32)[None]
    maps.high[index] = _block_reduce(depths, np.maximum, maps.smooth)[0]
    maps.low[index] = _block_reduce(depths, np.minimum, maps.smooth)[0]


def _block_reduce(depths, combine, dilate: bool) -> np.ndarray:
    """(cascades, blocks, blocks) ``combine`` (np.maximum or np.minimum) of the depths of each
    BLOCK x BLOCK block, with ``dilate`` also of the texels bordering it: a square that holds
    every bilinear PCF tap of the block's points. Reduces over reshaped views (a padded copy only where
    the resolution is not a multiple of BLOCK): the whole-map copies and pads this replaced cost
    5.9 s at 6 cascades of 4096, 0.35 s at 1024."""
    n, res = depths.shape[:2]
    blocks = -(-res // BLOCK)
    size = blocks * BLOCK
    if size != res:
        depths = np.pad(depths, ((0, 0), (0, size - res), (0, size - res)), mode="edge")
    rows = combine.reduce(depths.reshape(n, blocks, BLOCK, size), axis=2)              # (n, blocks, size)
    if dilate and blocks > 1:
        combine(rows[:, 1:], depths[:, BLOCK - 1:size - 1:BLOCK], out=rows[:, 1:])       # the row above
        combine(rows[:, :-1], depths[:, BLOCK::BLOCK], out=rows[:, :-1])                 # the row below
    out = combine.reduce(rows.reshape(n, blocks, blocks, BLOCK), axis=3)                # (n, blocks, blocks)
    if dilate and blocks > 1:
        combine(out[:, :, 1:], rows[:, :, BLOCK - 1:size - 1:BLOCK], out=out[:, :, 1:])  # the column left
        combine(out[:, :, :-1], rows[:, :, BLOCK::BLOCK], out=out[:, :, :-1])           # the column right
    return out


def visibility(cascades: ShadowCascades, maps: MinMaxMaps, points, camera: Camera, best_search: bool = True,
               first_cascade: int = 0) -> np.ndarray:
    """shadow_map.visibility (with PCF as ``maps`` was built), skipping decided points' taps."""
    tested, cascade, y, x, depth, bias = locate(cascades, points, camera, best_search, first_cascade)
    res = cascades.resolution
    # One flat block index for both maps, blocks by shifts: integer division and three-index
    # gathers were a third of this test's own time.
    blocks = maps.high.shape[-1]
    block_row = np.clip(np.floor(y).astype(np.int64), 0, res - 1) >> BLOCK_SHIFT
    block_column = np.clip(np.floor(x).astype(np.int64), 0, res - 1) >> BLOCK_SHIFT
    block = (cascade * blocks + block_row) * blocks + block_column
    lit = np.where(depth >= np.take(maps.high, block) - bias, 1.0, 0.0)
    undecided = tested & (depth >= np.take(maps.low, block) - bias) & (lit == 0.0)
    if undecided.any():
        lit[undecided] = tap_fraction(cascades, cascade[undecided], y[undecided], x[undecided],
                                      depth[undecided], bias[undecided], maps.smooth)
    return np.where(tested, lit, 1.0)
