"""Net densities (Rayleigh, Mie, ozone, fog) along a ray to the top of the atmosphere, read from
the baked optical-depth table: what every transmittance of the tables, the ground and the passes
is made from.

The fog column is stored divided by the fog's density at the ray's lowest point
(fog_column_scale): a fog of 20-50 m scale height thins by e^-2 to e^-4 between two of the
table's rows (78 m apart at 1024 rows), so the raw column interpolated between rows was up to
30% off halfway, while the column divided by that density (about H_fog / cos zenith) is smooth.
The look-up multiplies the density of its own lowest point back in, exactly."""
from __future__ import annotations

import numpy as np

from . import parameterization as par
from ..model.atmosphere import AtmosphereParams
from .interpolation import interpolate

# Net density stored where a ray hits the Earth (the sample's convention): any extinction
# turns it into a transmittance of exactly 0. Needs 32-bit float storage.
EARTH_HIT_NET_DENSITY = 1e20


def below_first_row_factors(params: AtmosphereParams, height_m, n_heights: int) -> np.ndarray:
    """(..., 4) factors for the net densities of points below the optical-depth table's first
    row (a texel centre, H_atm / 2N up: 39 m at 1024 rows), where the look-up clamps: the
    Rayleigh and Mie columns grow as exp(dh / H) going down, ozone (high up) does not, and the
    fog's is rescaled by fog_column_scale instead."""
    first_row = params.atmosphere_height / (2 * n_heights)
    below = np.maximum(first_row - np.asarray(height_m, dtype=np.float64), 0.0)
    ones = np.ones_like(below)
    return np.stack([np.exp(below / params.rayleigh_scale_height), np.exp(below / params.mie_scale_height),
                     ones, ones], axis=-1)


def lowest_height(params: AtmosphereParams, height_m, cos_zenith):
    """Height of the lowest point of the ray to the top: the start for rays going up, the
    tangent point for rays going down (0 for rays that reach the ground)."""
    h = np.maximum(np.asarray(height_m, dtype=np.float64), 0.0)
    c = np.asarray(cos_zenith, dtype=np.float64)
    r = params.earth_radius + h
    # r sin(zenith) - R as (r^2 sin^2 - R^2) / (r sin + R): float-safe near the ground.
    sin = np.sqrt(np.maximum(1.0 - c * c, 0.0))
    tangent = (h * (h + 2.0 * params.earth_radius) - (r * c) ** 2) / (r * sin + params.earth_radius)
    return np.where(c >= 0.0, h, np.clip(tangent, 0.0, h))


def fog_column_scale(params: AtmosphereParams, height_m, cos_zenith):
    """The fog's density at the ray's lowest point: the stored fog column times this is the
    column (see the module docstring)."""
    return np.exp(-lowest_height(params, height_m, cos_zenith) / params.fog_height)


def horizon_safe_cos(params: AtmosphereParams, height_m, cos_zenith, n_heights: int, n_cos: int) -> np.ndarray:
    """The zenith cosine to read the optical-depth table at: for rays above the horizon, at
    least the first cos node above the horizon of the lower height row the look-up blends.
    Filtering otherwise mixes the EARTH_HIT_NET_DENSITY texels just below the horizon into rays
    just above it (transmittance 0 for rays within a texel, 0.002 in cosine, of grazing: a dark
    or bright line along the horizon). Rays that hit the Earth keep their cosine."""
    cos_zenith = np.asarray(cos_zenith, dtype=np.float64)
    horizon, first_node_above = horizon_floor(params, height_m, n_heights, n_cos)
    return np.where(cos_zenith >= horizon, np.maximum(cos_zenith, first_node_above), cos_zenith)


def horizon_floor(params: AtmosphereParams, height_m, n_heights: int, n_cos: int):
    """(cos of the horizon at ``height_m``, the first cos node above the horizon of the lower
    height row a look-up there blends): horizon_safe_cos's bounds."""
    height = np.asarray(height_m, dtype=np.float64)
    row = np.maximum(np.floor(height / params.atmosphere_height * n_heights - 0.5), 0.0)
    lower_row_height = (row + 0.5) * params.atmosphere_height / n_heights
    node = np.ceil((par.cos_horizon(lower_row_height, params.earth_radius) * 0.5 + 0.5) * n_cos - 0.5)
    return par.cos_horizon(height, params.earth_radius), (node + 0.5) / n_cos * 2.0 - 1.0


def table_net_density(params: AtmosphereParams, optical_depth: np.ndarray, height_m, cos_zenith,
                      packed=None) -> np.ndarray:
    """(..., 4) net densities to the top read from an optical-depth table (float64)."""
    n_h, n_c = optical_depth.shape[:2]
    height = np.asarray(height_m, dtype=np.float64)
    xh = par.unit_to_centre_x(height / params.atmosphere_height, n_h)
    safe_cos = horizon_safe_cos(params, height, cos_zenith, n_h, n_c)
    xc = par.unit_to_centre_x(safe_cos * 0.5 + 0.5, n_c)
    net = interpolate(optical_depth, (xh, xc), packed=packed).astype(np.float64)
    net = net * below_first_row_factors(params, height, n_h)
    if params.has_fog:
        net[..., 3] = np.minimum(net[..., 3] * fog_column_scale(params, height, cos_zenith), EARTH_HIT_NET_DENSITY)
    return net
