"""The optical-depth table baked: net Rayleigh, Mie, ozone and fog densities from (height, cos
zenith) to the top of the atmosphere, the transmittance every other stage of the bake reads
(lut_gen.tables.optical_depth reads the table back).

Nodes sit at texel centres; rays into the Earth hold EARTH_HIT_NET_DENSITY, and the fog's
column is stored divided by fog_column_scale (optical_depth's module docstring says why)."""
from __future__ import annotations

from typing import Optional

import numpy as np

from . import parameterization as par
from ..model.atmosphere import AtmosphereParams
from ..model.geometry import clustered_nodes, distance_to_sphere_exit, radius_along
from .bake_parallel import Progress, parallel_rows
from .optical_depth import EARTH_HIT_NET_DENSITY, lowest_height
from .view_rays import density_profiles

OPTICAL_DEPTH_STEPS = 48        # nodes per optical-depth ray (clustered toward low heights)


def bake_optical_depth(params: AtmosphereParams, n_height: int, n_cos: int,
                       steps: int = OPTICAL_DEPTH_STEPS, progress: Optional[Progress] = None) -> np.ndarray:
    """(n_height, n_cos, 4) net densities to the top, the fog's divided by fog_column_scale;
    EARTH_HIT_NET_DENSITY where blocked. Nodes at texel centres: h = (i + 0.5) / n * H_atm,
    c = 2 (j + 0.5) / n - 1."""
    heights = par.centre_nodes(n_height) * params.atmosphere_height
    cosines = par.centre_nodes(n_cos) * 2.0 - 1.0
    out = np.zeros((n_height, n_cos, 4), dtype=np.float32)
    rows = max(1, (1 << 19) // (n_cos * steps))
    starts = list(range(0, n_height, rows))

    def fill(chunk):
        sl = slice(starts[chunk], starts[chunk] + rows)
        h = heights[sl, None]
        out[sl] = net_densities(params, h, cosines[None, :], steps)
        hits = cosines[None, :] < par.cos_horizon(h, params.earth_radius)
        out[sl, :, :4 if params.has_fog else 3][hits] = EARTH_HIT_NET_DENSITY

    parallel_rows(fill, len(starts), progress or (lambda *a: None), "optical depth")
    return out


def net_densities(params: AtmosphereParams, h, cos_zenith, steps: int) -> np.ndarray:
    """(..., 4) float32 net densities to the top of rays from heights ``h`` (..., 1) at zenith
    cosines (..., n), the fog's divided by fog_column_scale; rays into the Earth not marked."""
    r = params.earth_radius + h
    length = distance_to_sphere_exit(r, cos_zenith, params.top_radius)
    s = clustered_nodes(r, cos_zenith, length, steps).astype(np.float32)
    node_heights = _height_along(params, h, r, cos_zenith, s)
    weights = _trapezoid_weights(s)
    rayleigh, mie, ozone, fog = density_profiles(params, node_heights)
    heights_clamped = np.maximum(node_heights, np.float32(0.0))
    out = np.zeros(np.broadcast(h, cos_zenith).shape + (4,), np.float32)
    out[..., 0] = _exponential_segments_integral(rayleigh, heights_clamped, params.rayleigh_scale_height, s)
    out[..., 1] = _exponential_segments_integral(mie, heights_clamped, params.mie_scale_height, s)
    out[..., 2] = np.einsum("...k,...k->...", ozone, weights) if ozone is not None else 0.0
    if fog is not None:
        # Divided by the lowest point's density in the integral itself: the column of a fog
        # 20 m thick seen from 5 km up underflows float32, its ratio does not.
        lowest = lowest_height(params, h, cos_zenith)
        relative = np.exp((lowest[..., None].astype(np.float32) - heights_clamped) * np.float32(1.0 / params.fog_height))
        out[..., 3] = _exponential_segments_integral(relative, heights_clamped, params.fog_height, s)
    return out


def _height_along(params, h, r, cos_zenith, s):
    """Height at distance s along rays from (h, r = R + h); float32-safe form of |P| - R."""
    h, r, c = (np.asarray(v, dtype=np.float64)[..., None] for v in (h, r, cos_zenith))
    s = s.astype(np.float32)
    rise = s * (s + (2.0 * r * c).astype(np.float32))
    return h.astype(np.float32) + rise / (radius_along(r, c, s).astype(np.float32) + r.astype(np.float32))


def _exponential_segments_integral(density, heights, scale_height: float, s):
    """Integral along the last axis of density = exp(-height / scale_height), taken as
    exponential in s between its samples (exact on a straight vertical ray). The trapezoid
    rule on the same 48 nodes overestimated the Mie column by 1% (Rayleigh 0.15%), which a low
    sun's transmittance turns into several percent."""
    a, b = density[..., :-1], density[..., 1:]
    # log(b / a) without a log: the densities are exponentials of the heights.
    log_ratio = (heights[..., :-1] - heights[..., 1:]) * np.float32(1.0 / scale_height)
    small = np.abs(log_ratio) < np.float32(1e-3)
    # (b - a) / log(b / a), with its series where the segment barely changes height.
    mean = np.where(small, 0.5 * (a + b), (b - a) / np.where(small, np.float32(1.0), log_ratio))
    return np.einsum("...k,...k->...", mean, np.diff(s, axis=-1).astype(np.float32))


def _trapezoid_weights(s):
    """Trapezoid-rule weights of the samples s (..., n) along the last axis."""
    ds = np.diff(s, axis=-1)
    weights = np.zeros_like(s)
    weights[..., :-1] += 0.5 * ds
    weights[..., 1:] += 0.5 * ds
    return weights

