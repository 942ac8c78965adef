"""The air between the camera and the cloud layer as a per-frame panorama: sky.AirTerms (T times
the sun's colour at the cloud, T times the skylight there, T times the sky behind the cloud, T
times the ground's light on the cloud base, and the clouds' mean shade on the air in front of
them, air_shade.py) for every view direction, which the "OLS Clouds" node group reads in six
texture fetches instead of its 4D sky look-up and four optical-depth look-ups per camera ray
(those made clouds cost 60% of a render; bench/bench_clouds.py) and the shade's dozen 4D
look-ups and its integral along the ray. The terms depend on the sun, the camera height and the
layer (its height, and its mean over the map for the shade) only, and vary slowly across the
sky, so a small panorama holds them; the sharp part (the column met, from the cloud map) stays
per ray.

Layout: an atlas of len(TILES) tiles stacked bottom to top (sky.AirTerms' fields), each W x H pixels
plus a copy of its first and last rows on either side, so that Blender's Linear/Repeat look-up
never blends two tiles or the two poles. Column i looks at azimuth ((i + 0.5) / W - 0.5) 2 pi
from +Y toward +X, as the lighting panoramas. Row j of a tile at s = 2 (j + 0.5) / H - 1 looks
at elevation sign(s) s^2 90 deg: rows crowd at the horizon, where the distance to the layer and
with it T change fastest (the first row above it is 0.0014 deg high, those at the zenith 1.4
deg; the same crowding in the zenith cosine left the zenith rows 10 deg high, 2% off there).
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..tables.lookup import Luts
from . import field, sky
from .layer import CloudLayer

SIZE = (256, 256)            # W, H of one tile
TILES = tuple(f.name for f in dataclasses.fields(sky.AirTerms))     # bottom to top


def atlas_shape(size=SIZE):
    width, height = size
    return len(TILES) * (height + 2), width


def v_of_cos(cos_view):
    """The tile's v (0 bottom .. 1 top) of a view zenith cosine."""
    elevation = np.arcsin(np.clip(np.asarray(cos_view, dtype=np.float64), -1.0, 1.0))
    return 0.5 + 0.5 * np.sign(elevation) * np.sqrt(np.abs(elevation) / (0.5 * np.pi))


def atlas_uv(directions, tile: int, size=SIZE):
    """Image coordinates (u, v) in the atlas of unit ``directions`` (..., 3) in tile ``tile``."""
    directions = np.asarray(directions, dtype=np.float64)
    width, height = size
    u = np.arctan2(directions[..., 0], directions[..., 1]) / (2 * np.pi) + 0.5
    v = (tile * (height + 2) + 1 + v_of_cos(directions[..., 2]) * height) / (len(TILES) * (height + 2))
    return u, v


@functools.lru_cache(maxsize=2)
def directions(size=SIZE) -> np.ndarray:
    """(H, W, 3) unit view directions of one tile's pixels, read-only."""
    width, height = size
    azimuth = ((np.arange(width) + 0.5) / width - 0.5) * 2 * np.pi
    s = 2.0 * (np.arange(height) + 0.5) / height - 1.0
    cos_view = np.sin(np.sign(s) * s * s * 0.5 * np.pi)
    cos_view, azimuth = np.meshgrid(cos_view, azimuth, indexing="ij")
    across = np.sqrt(1.0 - cos_view ** 2)
    d = np.stack([np.sin(azimuth) * across, np.cos(azimuth) * across, cos_view], axis=-1)
    d.flags.writeable = False
    return d


def _within_reach(params, layer: CloudLayer, camera_height: float, d: np.ndarray) -> np.ndarray:
    """``d`` with the elevations clamped to the rays that meet the layer before the ground:
    below it, those above the ground's horizon; above it, those below the layer's limb. A ray
    the node group shades then never blends with a pixel it could not see (from above, the limb
    blended with empty pixels was 12% off)."""
    radius = params.earth_radius + max(camera_height, 0.0)
    if camera_height < layer.middle:
        low, high = -np.sqrt(max(1.0 - (params.earth_radius / radius) ** 2, 0.0)) + 1e-9, 1.0
    else:
        low, high = -1.0, -np.sqrt(max(1.0 - ((params.earth_radius + layer.middle) / radius) ** 2, 0.0)) - 1e-9
    z = np.clip(d[..., 2], low, high)
    across = np.sqrt(np.maximum(1.0 - z * z, 0.0) / np.maximum(1.0 - d[..., 2] ** 2, 1e-30))
    return np.stack([d[..., 0] * across, d[..., 1] * across, z], axis=-1)


def compute(luts: Luts, layer: CloudLayer, camera_height: float, sun, size=SIZE) -> np.ndarray:
    """(3 (H + 2), W, 3) float32 atlas, rows bottom to top (as the image's pixels)."""
    terms = sky.air_terms(luts, layer, camera_height, _within_reach(luts.params, layer, camera_height,
                                                                     directions(size)), sun)
    tiles = []
    for name in TILES:
        tile = getattr(terms, name)
        tiles += [tile[:1], tile, tile[-1:]]
    return np.concatenate(tiles, axis=0).astype(np.float32)


def lookup(atlas: np.ndarray, size=SIZE):
    """The node group's read of the atlas: a function of rays (n, 3) giving their sky.AirTerms,
    bilinear with Blender's texel centres (field.sample)."""
    def terms(rays):
        values = []
        for tile in range(len(TILES)):
            u, v = atlas_uv(rays, tile, size)
            values.append(np.stack([field.sample(atlas[..., c], u, v) for c in range(3)], axis=-1))
        return sky.AirTerms(*values)
    return terms
