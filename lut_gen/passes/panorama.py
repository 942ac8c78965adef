"""The sky and the lit ground as equirectangular panoramas for one sun direction and camera
height: Luts.sky_radiance ("multiple" table) and Luts.ground_radiance on every pixel, the same
numbers (measured equal to the bit) for a fraction of the work. The add-on recomputes them on
every sun move (addon/scene/frame/skylight.py): the per-pixel look-ups took 0.44 s a move for the
default tables, this 0.065 s (bench/bench_skylight.py).

Pixel (i, j) of a W x H panorama (rows bottom to top) looks at azimuth ((i + 0.5) / W - 0.5) 2 pi
from +Y toward +X and elevation ((j + 0.5) / H - 0.5) pi.

Over one panorama the height and the sun zenith are fixed, and the view zenith (with its horizon
flag and ground-ray scale) is fixed per row; only the sun-view angle changes from pixel to pixel.
So the 4D look-up reads its 2 x 2 height and sun-zenith node slices once, their two view-zenith
nodes once per row, and per pixel only the two sun-view nodes of its row; interpolate blends the
linear axes before the geometric ones (height, sun zenith), and so does this, in its order.
"""
from __future__ import annotations

import functools

import numpy as np

from ..tables import ground as ground_light
from ..tables import parameterization as par
from ..tables.interpolation import axis_weights, gather, geometric_lerp, packed_rows
from ..tables.lookup import Luts, with_phases


@functools.lru_cache(maxsize=2)
def directions(width: int, height: int) -> np.ndarray:
    """(height, width, 3) unit view directions of the panorama's pixels, read-only: kept for
    the next sun move (computing them was a tenth of its time)."""
    azimuth = ((np.arange(width) + 0.5) / width - 0.5) * 2 * np.pi
    elevation = ((np.arange(height) + 0.5) / height - 0.5) * np.pi
    elevation, azimuth = np.meshgrid(elevation, azimuth, indexing="ij")
    d = np.stack([np.sin(azimuth) * np.cos(elevation), np.cos(azimuth) * np.cos(elevation),
                  np.sin(elevation)], axis=-1)
    d.flags.writeable = False
    return d


def _nodes(x, n: int):
    """The two nodes and the upper node's weight of one coordinate on an n-node axis."""
    low, weight = axis_weights(x, n)
    return [int(low), min(int(low) + 1, n - 1)], weight


# Pixels per pass of the per-pixel steps: their dozen temporaries then stay in the CPU cache
# (the default panorama's sky in 52 ms against 77-100 ms in one pass; 4096 to 16384 measured
# the same).
BLOCK = 4096


def sky(luts: Luts, height_m: float, cos_view_zenith, cos_sun_zenith: float, cos_sun_view) -> np.ndarray:
    """(H, W, 3) luts.sky_radiance(height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view) for
    ``cos_view_zenith`` (H, 1), one per row, and ``cos_sun_view`` (H, W). Each pixel sums the same
    float32 products in the same order as interpolate, hence the same numbers to the bit."""
    params, (n_h, n_a, n_s, n_t) = luts.params, luts.dims
    cos_sun_view = par.clamp_sun_view(cos_view_zenith, cos_sun_zenith, cos_sun_view)
    xh, xa, xs, xt, above = par.world_to_x(params, luts.dims, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view)
    heights, w_h = _nodes(xh, n_h)
    suns, w_s = _nodes(xs, n_s)
    # (n_a, n_t, height node, sun node, table, 3): the stored, the single Mie (and fog) table side
    # by side, so that every step below runs once for all, with the geometric axes outermost.
    tables = (luts.multiple, luts.single_mie) + (() if luts.single_fog is None else (luts.single_fog,))
    corners = np.stack([table[np.ix_(heights, np.arange(n_a), suns)] for table in tables])
    corners = corners.transpose(2, 4, 1, 3, 0, 5)
    channels = corners[0, 0].size
    rows, width = xt.shape
    a_low, w_a = axis_weights(xa.reshape(-1), n_a)
    # Per row and sun-view node, both view-zenith nodes in one record: a pixel reads two.
    per_row = np.stack([corners[a_low], corners[np.minimum(a_low + 1, n_a - 1)]], axis=2)
    packed, record = packed_rows(per_row.reshape(rows * n_t, 2 * channels))
    t_low, w_t = axis_weights(xt, n_t)
    first = np.arange(rows)[:, None] * n_t
    lower_index, upper_index = (first + t_low).ravel(), (first + np.minimum(t_low + 1, n_t - 1)).ravel()
    w_a, w_t = np.repeat(w_a, width), w_t.ravel()
    scale = np.repeat(par.look_up_scale(params, height_m, cos_view_zenith, above).astype(np.float32).ravel(), width)
    cos_sun_view = cos_sun_view.ravel()
    out = np.empty((rows * width, 3), dtype=np.float32)
    for start in range(0, len(out), BLOCK):
        pixels = slice(start, start + BLOCK)
        lower = gather(packed, record, lower_index[pixels])[:, :2 * channels].reshape(-1, 2, channels)
        upper = gather(packed, record, upper_index[pixels])[:, :2 * channels].reshape(-1, 2, channels)
        a, t = w_a[pixels, None], w_t[pixels, None]
        blend = ((1.0 - a) * (1.0 - t)) * lower[:, 0]
        blend += ((1.0 - a) * t) * upper[:, 0]
        blend += (a * (1.0 - t)) * lower[:, 1]
        blend += (a * t) * upper[:, 1]
        # Corner-major: each geometric blend then reads two contiguous halves (twice as fast).
        blend = np.ascontiguousarray(blend.T).reshape(corners.shape[2:] + (-1,))
        blend = geometric_lerp(blend[0], blend[1], w_h)
        blend = geometric_lerp(blend[0], blend[1], w_s)
        radiance = with_phases(params, blend[0].T, blend[1].T, cos_sun_view[pixels],
                               blend[2].T if len(tables) > 2 else None)
        out[pixels] = radiance * scale[pixels, None]
    return out.reshape(rows, width, 3)


def ground(luts: Luts, height_m: float, cos_view_zenith, cos_sun_zenith: float, cos_sun_view) -> np.ndarray:
    """(H, W, 3) luts.ground_radiance(...) with the arguments of sky(). Only the rows that hit the
    ground are looked up (the others are 0), with one view zenith per row, which ground_radiance
    broadcasts: the optical depth to the ground point, the same along a row, is read once a
    row instead of once a pixel."""
    cos_view_zenith = np.asarray(cos_view_zenith, dtype=np.float64)
    out = np.zeros(np.shape(cos_sun_view) + (3,), dtype=np.float32)
    clipped = np.clip(height_m, 0.0, luts.params.atmosphere_height)     # as ground_radiance's rows
    hits = ground_light.hits_ground(luts.params, clipped, cos_view_zenith[:, 0])
    if hits.any():
        out[hits] = luts.ground_radiance(height_m, cos_view_zenith[hits], cos_sun_zenith, cos_sun_view[hits])
    return out


def panoramas(luts: Luts, sun_direction, camera_height: float, size):
    """(sky, ground): (H, W, 3) sky radiance and lit-ground radiance (0 above the horizon) per
    unit sun of a ``size`` = (W, H) panorama, rows bottom to top, for a camera at
    ``camera_height`` (below 0: at 0)."""
    d = directions(*size)
    sun = np.asarray(sun_direction, dtype=np.float64)
    view = (max(camera_height, 0.0), d[:, :1, 2], sun[2], d @ sun)
    return sky(luts, *view), ground(luts, *view)
