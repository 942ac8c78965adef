"""Table coordinates of Yusov 2013, eqs. (4)-(7) and Listing 2, and their inverses.

All coordinates here are *texel indices* x in [0, N-1] of a table axis with N nodes:
node i holds the value at x = i, a look-up at x blends nodes floor(x) and floor(x)+1.
A GPU/Blender texture coordinate for the same point is (x + 0.5) / N.

Axes of the 4D scattering table, in this order:
  h      height above ground,     u_h = sqrt(h / H_atm)                    (Yusov 2013 eq. 4)
  alpha  cos view zenith c_a,     horizon-split power-0.2 mapping          (Yusov 2013 eq. 5, Listing 2)
  phi    cos sun zenith c_s,      Bruneton's arctan mapping                (Yusov 2013 eq. 6)
  theta  cos sun-view angle c_t,  power-1.5 mapping of gamma = theta / pi  (Yusov 2013 eq. 7)

Yusov 2013 eq. (6) as printed puts tan(1.26*1.1) outside the arctan; Bruneton's code (and the
only version that maps [-0.1975, 1] onto [0, 1]) multiplies inside: atan(c * tan(1.386)) / 1.1.

Yusov 2013 eq. (7) with power 1.5 packs sun-view nodes around the sun for the Mie forward peak. The
tables no longer hold that peak (single Mie scattering is stored without its phase function, which
is applied per look-up), and the power left a 30 deg gap around 90 deg whose node kinks showed in
the twilight sky at +-105 deg from the sun. Power 1 spaces the 16 nodes 12 deg apart: the single
table's error against the spectral reference is the same with either power (median 0.23% on uniform
random rays) and the twilight kinks shrink to about 1% of slope per 0.5 deg.
"""
from __future__ import annotations

import math

import numpy as np

from ..model.geometry import GROUND_RAY_SCALE_M, ground_ray_scale

ALPHA_POWER = 0.2          # Yusov 2013 eq. (5)
THETA_POWER = 1.0          # Yusov 2013 eq. (7) used 1.5; see the module docstring
SUN_ZENITH_MIN_COS = -0.1975   # Yusov 2013 eq. (6): sun more than ~101 deg from zenith clamps here
_PHI_ANGLE = 1.26 * 1.1
_PHI_TAN = math.tan(_PHI_ANGLE)


def cos_horizon(height_m, earth_radius: float):
    """Cosine of the zenith angle of the geometric horizon seen from height h (<= 0)."""
    h = np.maximum(np.asarray(height_m, dtype=np.float64), 0.0)
    return -np.sqrt(h * (2.0 * earth_radius + h)) / (earth_radius + h)


# -- height (Yusov 2013 eq. 4) -----------------------------------------------
#
# With a fog layer the height axis is logarithmic instead: u = ln(1 + h/k) / ln(1 + H/k) with
# k = FOG_KNEE_SHARE x the fog's scale height. Yusov 2013 eq. (4)'s square root puts the first row
# 83 m up at 32 rows, above a 50 m fog, and the geometric blend between the ground's row (in the
# fog) and that one (above it) was 20% off for a camera 2 m up, 40% at 30 m.

FOG_KNEE_SHARE = 0.5


def fog_knee(params):
    """k of the logarithmic height axis for params with fog, None for Yusov 2013 eq. (4)'s."""
    return FOG_KNEE_SHARE * params.fog_height if params.has_fog else None


def height_to_x(height_m, n: int, atmosphere_height: float, knee=None):
    h = np.clip(np.asarray(height_m, dtype=np.float64), 0.0, atmosphere_height)
    if knee is None:
        u = np.sqrt(h / atmosphere_height)
    else:
        u = np.log1p(h / knee) / math.log1p(atmosphere_height / knee)
    return u * (n - 1)


def x_to_height(x, n: int, atmosphere_height: float, knee=None):
    u = np.asarray(x, dtype=np.float64) / (n - 1)
    if knee is None:
        return u * u * atmosphere_height
    return knee * np.expm1(u * math.log1p(atmosphere_height / knee))


# -- view zenith (Yusov 2013 eq. 5, Listing 2) -------------------------------

def view_zenith_to_x(cos_view_zenith, height_m, n: int, earth_radius: float, above_horizon=None):
    """Texel x on the alpha axis and the horizon flag used.

    ``above_horizon`` forces the half of the table (the flag of an earlier look-up on the same
    ray, Yusov 2013 Listing 2); None decides per ray from c_a > c_h.
    """
    c = np.asarray(cos_view_zenith, dtype=np.float64)
    c_h = cos_horizon(height_m, earth_radius)
    if above_horizon is None:
        above = c > c_h
    else:
        above = np.broadcast_to(np.asarray(above_horizon, dtype=bool), np.broadcast(c, c_h).shape)
    half = n // 2
    t_above = np.clip((c - c_h) / (1.0 - c_h), 0.0, 1.0) ** ALPHA_POWER
    t_below = np.clip((c_h - c) / np.maximum(c_h + 1.0, 1e-12), 0.0, 1.0) ** ALPHA_POWER
    x = np.where(above, half + t_above * (half - 1), t_below * (half - 1))
    return x, np.asarray(above)


def x_to_view_zenith(x, height_m, n: int, earth_radius: float):
    """Inverse of view_zenith_to_x: (cos view zenith, above_horizon flag) of texel x."""
    x = np.asarray(x, dtype=np.float64)
    half = n // 2
    c_h = cos_horizon(height_m, earth_radius)
    above = x >= half
    t = np.where(above, (x - half) / (half - 1), x / (half - 1)) ** (1.0 / ALPHA_POWER)
    c = np.where(above, c_h + t * (1.0 - c_h), c_h - t * (c_h + 1.0))
    return c, above


# -- sun zenith (Yusov 2013 eq. 6) -------------------------------------------

def sun_zenith_to_x(cos_sun_zenith, n: int):
    c = np.maximum(np.asarray(cos_sun_zenith, dtype=np.float64), SUN_ZENITH_MIN_COS)
    u = 0.5 * (np.arctan(c * _PHI_TAN) / 1.1 + (1.0 - 0.26))
    return np.clip(u, 0.0, 1.0) * (n - 1)


def x_to_sun_zenith(x, n: int):
    u = np.asarray(x, dtype=np.float64) / (n - 1)
    return np.tan((2.0 * u - (1.0 - 0.26)) * 1.1) / _PHI_TAN


# -- sun-view angle (Yusov 2013 eq. 7) ---------------------------------------

def sun_view_to_x(cos_sun_view, n: int):
    gamma = np.arccos(np.clip(np.asarray(cos_sun_view, dtype=np.float64), -1.0, 1.0)) / math.pi
    d = 2.0 * (gamma - 0.5)
    u = 0.5 + 0.5 * np.sign(d) * np.abs(d) ** THETA_POWER
    return u * (n - 1)


def x_to_sun_view(x, n: int):
    u = np.asarray(x, dtype=np.float64) / (n - 1)
    d = 2.0 * (u - 0.5)
    gamma = 0.5 + 0.5 * np.sign(d) * np.abs(d) ** (1.0 / THETA_POWER)
    return np.cos(gamma * math.pi)


def clamp_sun_view(cos_view_zenith, cos_sun_zenith, cos_sun_view):
    """Clamp c_t into the range that a view and a sun direction with these zeniths allow."""
    ca, cs = np.asarray(cos_view_zenith), np.asarray(cos_sun_zenith)
    sin_prod = np.sqrt(np.clip(1.0 - ca * ca, 0.0, 1.0) * np.clip(1.0 - cs * cs, 0.0, 1.0))
    return np.clip(cos_sun_view, ca * cs - sin_prod, ca * cs + sin_prod)


def world_to_x(params, dims, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view, above_horizon=None):
    """4D texel coordinates (xh, xa, xs, xt) and the horizon flag for a look-up."""
    n_h, n_a, n_s, n_t = dims
    h = np.clip(np.asarray(height_m, dtype=np.float64), 0.0, params.atmosphere_height)
    xh = height_to_x(h, n_h, params.atmosphere_height, fog_knee(params))
    xa, above = view_zenith_to_x(cos_view_zenith, h, n_a, params.earth_radius, above_horizon)
    xs = sun_zenith_to_x(cos_sun_zenith, n_s)
    xt = sun_view_to_x(cos_sun_view, n_t)
    return xh, xa, xs, xt, above


def grid_axes(params, dims):
    """World values at the table nodes: heights (n_h,), cos view zenith (n_h, n_a),
    above-horizon flags (n_a,), cos sun zenith (n_s,), cos sun-view (n_t,)."""
    n_h, n_a, n_s, n_t = dims
    heights = x_to_height(np.arange(n_h), n_h, params.atmosphere_height, fog_knee(params))
    cos_view, above = x_to_view_zenith(np.arange(n_a)[None, :], heights[:, None], n_a, params.earth_radius)
    cos_sun = x_to_sun_zenith(np.arange(n_s), n_s)
    cos_sun_view = x_to_sun_view(np.arange(n_t), n_t)
    return heights, cos_view, above[0], cos_sun, cos_sun_view


def ground_ray_length(params, height_m):
    """l of the ground-ray scale (geometry.ground_ray_scale) for rays from ``height_m``:
    GROUND_RAY_SCALE_M, or in fog the fog's extinction length at that height where shorter.

    In fog the light along a ground ray saturates within an extinction length (256 m in a 1 km
    fog), not within 20 km: divided by the 20 km scale it fell like 1 / d across the rows
    near the ground, and a camera 2 m up (between the rows at 0 and 7 m of a 50 m fog) saw
    ground rays just below the horizon 1.6-4.5x too bright against brute force. Above the fog
    the length grows back to GROUND_RAY_SCALE_M with the fog's thinning."""
    if not params.has_fog:
        return GROUND_RAY_SCALE_M
    h = np.maximum(np.asarray(height_m, dtype=np.float64), 0.0)
    return np.minimum(GROUND_RAY_SCALE_M, np.exp(np.minimum(h / params.fog_height, 50.0)) / params.fog)


def look_up_scale(params, height_m, cos_view_zenith, above_horizon):
    """(...) factor a 4D look-up is multiplied by: geometry.ground_ray_scale of the ray."""
    h = np.clip(np.asarray(height_m, dtype=np.float64), 0.0, params.atmosphere_height)
    r = params.earth_radius + h
    return ground_ray_scale(r, np.asarray(cos_view_zenith, dtype=np.float64), ~np.asarray(above_horizon),
                            params.earth_radius, ground_ray_length(params, h))


def grid_scale(params, dims):
    """(n_h, n_a, 1, 1, 1) look_up_scale at the 4D table's nodes."""
    heights, cos_view, above, _, _ = grid_axes(params, dims)
    return look_up_scale(params, heights[:, None], cos_view, above[None, :])[:, :, None, None, None]


# -- 1D tables: optical depth and ambient skylight (texel-centre convention) ---------------
# These follow the sample's look-ups literally: texture coordinate = h / H_atm and
# c * 0.5 + 0.5, linear filtering with clamp, i.e. node i sits at (i + 0.5) / N.

def centre_nodes(n: int):
    return (np.arange(n) + 0.5) / n


def unit_to_centre_x(u, n: int):
    u = np.asarray(u)
    u = u if u.dtype == np.float32 else u.astype(np.float64)
    return np.clip(u * u.dtype.type(n) - u.dtype.type(0.5), 0.0, n - 1)
