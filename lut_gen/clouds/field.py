"""The cloud field: one tileable map, made from the seed alone, that every part reads (the world
shader, the shadow layer, the light shafts and their numpy twins), so that all of them and every
farm worker see the same clouds.

The map holds, per texel, the texel's rank in [0, 1] (the noise after histogram equalisation):
the fraction of the map above a threshold t is then exactly 1 - t, which is what makes
``coverage`` the fraction of the sky covered for any seed. The noise is spectral fBm (random
phases on a power-law spectrum, periodic by construction) mixed with inverted Worley noise on a
periodic lattice of feature points, which gives rounded, billowy cells. Blender's Noise Texture
cannot be reproduced in numpy, so nothing is built on it.

One map tile spans TILE_FEATURES cloud features: TILE_FEATURES * cloud_scale metres.
"""
from __future__ import annotations

import functools

import numpy as np

MAP_SIZE = 512
TILE_FEATURES = 8            # features across one tile: the noise's lowest frequency
SOFTNESS = 0.15              # rank range over which a cloud's edge thins to nothing
FBM_WEIGHT = 0.6             # the rest is inverted Worley noise


def _spectral_fbm(rng, size: int) -> np.ndarray:
    fx = np.fft.fftfreq(size) * size
    k = np.hypot(*np.meshgrid(fx, fx, indexing="ij"))
    # Power-law amplitude (fBm with H = 0.5: amplitude ~ k^-1.5) from the features' frequency up.
    amplitude = np.where(k >= TILE_FEATURES * 0.5, np.power(np.maximum(k, 1.0), -1.5), 0.0)
    phases = rng.random((size, size)) * 2.0 * np.pi
    field = np.real(np.fft.ifft2(amplitude * np.exp(1j * phases)))
    return (field - field.mean()) / max(field.std(), 1e-12)


def _worley(rng, size: int, cells: int) -> np.ndarray:
    """Distance to the nearest of one random feature point per lattice cell, periodic."""
    points = np.stack(np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij"), -1) + rng.random((cells, cells, 2))
    points = points.reshape(-1, 2) / cells
    coords = (np.arange(size) + 0.5) / size
    y, x = np.meshgrid(coords, coords, indexing="ij")
    nearest = np.full((size, size), np.inf)
    for py, px in points:
        dy = np.abs(y - py)
        dx = np.abs(x - px)
        d = np.hypot(np.minimum(dy, 1.0 - dy), np.minimum(dx, 1.0 - dx))
        np.minimum(nearest, d, out=nearest)
    return nearest * cells


def cloud_map(seed: int, size: int = MAP_SIZE) -> np.ndarray:
    """(size, size) float32 ranks in [0, 1], tileable in both axes, a function of ``seed`` only."""
    rng = np.random.default_rng(np.uint32(int(seed) & 0xFFFFFFFF))
    fbm = _spectral_fbm(rng, size)
    worley = _worley(rng, size, TILE_FEATURES)
    worley = (worley - worley.mean()) / max(worley.std(), 1e-12)
    noise = FBM_WEIGHT * fbm - (1.0 - FBM_WEIGHT) * worley
    ranks = np.empty(noise.size)
    ranks[np.argsort(noise, axis=None, kind="stable")] = np.arange(noise.size)
    return (ranks / (noise.size - 1)).reshape(size, size).astype(np.float32)


@functools.lru_cache(maxsize=4)
def cached_map(seed: int) -> np.ndarray:
    """cloud_map(seed), made once per process (read-only): the numpy passes' copy of the map
    the add-on packs into the .blend."""
    ranks = cloud_map(seed)
    ranks.setflags(write=False)
    return ranks


def threshold(coverage):
    """The rank below which a texel is clear: coverage 0 clears every texel, 1 makes the whole
    layer full thickness, and in between the covered fraction (thickness over half) is coverage
    within SOFTNESS / 2 (exactly at 0.5)."""
    return (1.0 - coverage) * (1.0 + SOFTNESS) - SOFTNESS


def thickness_fraction(rank, coverage):
    """The fraction of the layer's thickness a column of cloud fills, 0 to 1."""
    return np.clip((rank - threshold(coverage)) / SOFTNESS, 0.0, 1.0)


def map_uv(x, y, scale, offset):
    """Map coordinates (tiles, wrapping at 1) of world x, y (metres) for ``cloud_scale`` and
    ``cloud_offset`` (x, y metres: moving it moves the clouds by minus it, the wind's drift)."""
    tile = TILE_FEATURES * scale
    return (np.asarray(x) + offset[0]) / tile, (np.asarray(y) + offset[1]) / tile


def sample(cloud, u, v):
    """Bilinear, wrapping look-up at map coordinates (u, v), with texel centres at
    (i + 0.5) / size: Blender's Image Texture with Linear interpolation and Repeat extension.
    Rows are v (bottom to top, as the image's pixels), columns u."""
    rows, cols = cloud.shape
    fu = np.asarray(u, dtype=np.float64) * cols - 0.5
    fv = np.asarray(v, dtype=np.float64) * rows - 0.5
    iu, iv = np.floor(fu), np.floor(fv)
    wu, wv = fu - iu, fv - iv
    # Flat indices into the raveled map, wrapped without a second modulo: the light shafts
    # sample it millions of times per frame (3x faster than 2D fancy indexing).
    iu0, iv0 = iu.astype(np.int64) % cols, iv.astype(np.int64) % rows
    iu1 = np.where(iu0 == cols - 1, 0, iu0 + 1)
    row0 = iv0 * cols
    row1 = np.where(iv0 == rows - 1, 0, row0 + cols)
    flat = np.asarray(cloud).ravel()
    low = flat[row0 + iu0] * (1 - wu) + flat[row0 + iu1] * wu
    high = flat[row1 + iu0] * (1 - wu) + flat[row1 + iu1] * wu
    return low + wv * (high - low)


def fraction_nodes(coverage: float, band_nodes: int = 8):
    """(fractions, weights): a quadrature of the map's columns' thickness fractions, weights
    summing to 1. The map's ranks are uniform on [0, 1] and the fraction is a clamped ramp of
    the rank (thickness_fraction): none below the threshold, full above it plus SOFTNESS,
    linear between, so the clear columns, the band's midpoints and the full column integrate
    any function of it."""
    cut = float(threshold(coverage))
    low, high = min(max(cut, 0.0), 1.0), min(max(cut + SOFTNESS, 0.0), 1.0)
    ranks = low + (np.arange(band_nodes) + 0.5) / band_nodes * (high - low)
    fractions = np.concatenate([[0.0], thickness_fraction(ranks, coverage), [1.0]])
    weights = np.concatenate([[low], np.full(band_nodes, (high - low) / band_nodes), [1.0 - high]])
    return fractions, weights


def column_mean(coverage: float, function, band_nodes: int = 8):
    """The mean of ``function(thickness fraction)`` over the map's columns (fraction_nodes);
    nodes of no weight are not evaluated."""
    fractions, weights = fraction_nodes(coverage, band_nodes)
    return sum(w * function(f) for f, w in zip(fractions, weights) if w > 0)
