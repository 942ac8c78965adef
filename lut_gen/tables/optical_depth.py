"""Net densities (Rayleigh, Mie, ozone) along a ray to the top of the atmosphere, read from the
baked optical-depth table: what every transmittance of the tables, the ground and the passes is
made from."""
from __future__ import annotations

import numpy as np

from . import parameterization as par
from ..model.atmosphere import AtmosphereParams
from .interpolation import interpolate

# Net density stored where a ray hits the Earth (the sample's convention): any extinction
# turns it into a transmittance of exactly 0. Needs 32-bit float storage.
EARTH_HIT_NET_DENSITY = 1e20


def below_first_row_factors(params: AtmosphereParams, height_m, n_heights: int) -> np.ndarray:
    """(..., 3) factors for the net densities of points below the optical-depth table's first
    row (a texel centre, H_atm / 2N up: 39 m at 1024 rows), where the look-up clamps: the
    Rayleigh and Mie columns grow as exp(dh / H) going down, ozone (high up) does not."""
    first_row = params.atmosphere_height / (2 * n_heights)
    below = np.maximum(first_row - np.asarray(height_m, dtype=np.float64), 0.0)
    return np.stack([np.exp(below / params.rayleigh_scale_height), np.exp(below / params.mie_scale_height),
                     np.ones_like(below)], axis=-1)


def horizon_safe_cos(params: AtmosphereParams, height_m, cos_zenith, n_heights: int, n_cos: int) -> np.ndarray:
    """The zenith cosine to read the optical-depth table at: for rays above the horizon, at
    least the first cos node above the horizon of the lower height row the look-up blends.
    Filtering otherwise mixes the EARTH_HIT_NET_DENSITY texels just below the horizon into rays
    just above it (transmittance 0 for rays within a texel, 0.002 in cosine, of grazing: a dark
    or bright line along the horizon). Rays that hit the Earth keep their cosine."""
    height = np.asarray(height_m, dtype=np.float64)
    cos_zenith = np.asarray(cos_zenith, dtype=np.float64)
    row = np.maximum(np.floor(height / params.atmosphere_height * n_heights - 0.5), 0.0)
    lower_row_height = (row + 0.5) * params.atmosphere_height / n_heights
    node = np.ceil((par.cos_horizon(lower_row_height, params.earth_radius) * 0.5 + 0.5) * n_cos - 0.5)
    first_node_above = (node + 0.5) / n_cos * 2.0 - 1.0
    above = cos_zenith >= par.cos_horizon(height, params.earth_radius)
    return np.where(above, np.maximum(cos_zenith, first_node_above), cos_zenith)


def table_net_density(params: AtmosphereParams, optical_depth: np.ndarray, height_m, cos_zenith,
                      packed=None) -> np.ndarray:
    """(..., 3) net densities to the top read from an optical-depth table (float64)."""
    n_h, n_c = optical_depth.shape[:2]
    height = np.asarray(height_m, dtype=np.float64)
    xh = par.unit_to_centre_x(height / params.atmosphere_height, n_h)
    cos_zenith = horizon_safe_cos(params, height, cos_zenith, n_h, n_c)
    xc = par.unit_to_centre_x(cos_zenith * 0.5 + 0.5, n_c)
    net = interpolate(optical_depth, (xh, xc), packed=packed).astype(np.float64)
    return net * below_first_row_factors(params, height, n_h)
