"""Optics of one column of cloud: a homogeneous slab of optical thickness tau, lit from above by
the sun (unit irradiance perpendicular to the beam, zenith cosine mu_s) and seen at zenith
cosine mu_v, from below (the light it lets through) or from above (the light it reflects).

Two parts, each chosen for what it gets right:
- **single scattering**, exact for the slab, with the cloud phase function: it carries the
  silver lining toward the sun and the edges of thin clouds, which depend on the phase
  function's forward peak;
- **all higher orders** from the delta-Eddington two-stream solution for a conservative slab
  (Joseph, Wiscombe & Weinman 1976; Meador & Weaver 1980): the diffuse fluxes of a thick cloud
  are set by its transport optical depth tau (1 - g), and the two-stream solution is within a
  few percent of exact there. Its flux leaves with the angular shape of the Monte Carlo path
  tracer's higher orders (a table over tau, sun and view zenith: the series in azimuth of its
  logarithm, four terms);
- **diffuse light** (the skylight on the top, the ground's on the base) leaves with the shape of
  the two parts above integrated over the sky (diffuse_shares).
Checked against a Monte Carlo path tracer of the same slab (lut_gen/verify/slab_monte_carlo.py,
tests/numpy_only/test_cloud_slab.py).
"""
from __future__ import annotations

import functools
import math
import json
import os

import numpy as np

from ..model.cloud_medium import ASYMMETRY, PHASE_LOBES, phase  # noqa: F401 (slab.phase, slab.PHASE_LOBES)

LOG_TERMS = 4           # the higher orders' log-cosine series in azimuth: 1, cos(phi), cos(2 phi), cos(3 phi)
MIN_COS = 0.02          # grazing rays: cosines below this are held here (a slab's path is finite)

# The higher orders' table: optical thicknesses (log2-spaced; thicker slabs take the last node's
# angular shape, which has converged by then) and zenith cosines of the sun and of the view.
TABLE_TAUS = tuple(2.0 ** k for k in range(-2, 7))
TABLE_COS = tuple(np.round(np.linspace(0.05, 1.0, 8), 4))
TABLE_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "higher_orders.json")


SERIES_BELOW = 1e-3     # |b - a| under which _exp_ratio takes its series (float32-safe in the nodes)


def _exp_ratio(a, b):
    """(exp(-a) - exp(-b)) / (b - a), symmetric in a and b: exp(-m) (1 - exp(-d)) / d with
    m = min(a, b) and d = |b - a| (no overflow); for small d the series 1 - d / 2 + d^2 / 6,
    which the node group takes too (float32 cancels there)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    d = np.abs(b - a)
    small = d < SERIES_BELOW
    safe = np.where(small, 1.0, d)
    return np.exp(-np.minimum(a, b)) * np.where(small, 1.0 - d / 2.0 + d * d / 6.0, -np.expm1(-safe) / safe)


def single_scattering(tau, cos_sun, cos_view, cos_sun_view, below: bool):
    """Singly scattered radiance leaving the slab toward the viewer, per unit sun irradiance.
    ``cos_sun``, ``cos_view``: zenith cosines of the sun and of the line of sight, both taken
    positive (from the slab's normal on the viewer's side for the view); ``cos_sun_view``: the
    cosine between the view direction (eye to cloud) and the direction toward the sun, which is
    the scattering angle's: the sun straight behind a cloud seen from below is forward scattering."""
    mu_s = np.maximum(cos_sun, MIN_COS)
    mu_v = np.maximum(cos_view, MIN_COS)
    p = phase(cos_sun_view)
    if below:
        # p / mu_v int_0^tau exp(-t / mu_s) exp(-(tau - t) / mu_v) dt
        return p * tau / mu_v * _exp_ratio(tau / mu_v, tau / mu_s)
    return p * mu_s / (mu_s + mu_v) * -np.expm1(-tau * (1.0 / mu_s + 1.0 / mu_v))


# Delta-Eddington scaling: the forward peak's share f = g^2 goes straight on, the rest scatters
# with the reduced asymmetry.
DELTA_FRACTION = ASYMMETRY ** 2
SCALED_ASYMMETRY = (ASYMMETRY - DELTA_FRACTION) / (1.0 - DELTA_FRACTION)


def two_stream(tau, cos_sun):
    """(reflected, diffusely transmitted) flux per unit incident flux of a conservative slab,
    delta-Eddington. The direct beam exp(-tau / mu_s) is not in either."""
    mu_s = np.maximum(cos_sun, MIN_COS)
    f, g = DELTA_FRACTION, SCALED_ASYMMETRY
    tau_scaled = (1.0 - f) * tau
    gamma1 = 0.75 * (1.0 - g)
    gamma3 = (2.0 - 3.0 * g * mu_s) / 4.0
    reflected = (gamma1 * tau_scaled + (gamma3 - gamma1 * mu_s) * -np.expm1(-tau_scaled / mu_s)) / (1.0 + gamma1 * tau_scaled)
    transmitted = np.maximum(1.0 - reflected - np.exp(-tau / mu_s), 0.0)
    return reflected, transmitted


class CloudTableError(ValueError):
    """The higher orders' table shipped with lut_gen is missing or damaged."""


@functools.lru_cache(maxsize=1)
def higher_order_series() -> np.ndarray:
    """(2, n_tau, n_sun, n_view, LOG_TERMS): [0] seen from below, [1] from above, the cosine
    series in azimuth of the log of the higher orders' radiance over the delta-Eddington flux's
    (lut_gen.verify.slab_monte_carlo.log_cosine_series); read-only."""
    try:
        with open(TABLE_PATH) as f:
            data = json.load(f)
        series = np.asarray(data["log_series"], dtype=np.float64)
    except (OSError, ValueError, KeyError) as error:
        raise CloudTableError(f"the cloud table {TABLE_PATH} is missing or damaged ({error}); "
                              "reinstall the extension or run scripts/gen_cloud_table.py") from None
    if series.shape != (2, len(TABLE_TAUS), len(TABLE_COS), len(TABLE_COS), LOG_TERMS) or not np.all(np.isfinite(series)):
        raise CloudTableError(f"the cloud table {TABLE_PATH} has the wrong shape or non-finite values; "
                              "reinstall the extension or run scripts/gen_cloud_table.py")
    series.flags.writeable = False
    return series


def table_coordinates(tau, cos_sun, cos_view):
    """(tau node below, its upper neighbour's weight, sun texel, view texel): continuous texel
    coordinates (centres at i + 0.5) of the cosines, clamped to the outer centres, and the
    log2-spaced tau axis' node and weight (clamped at both ends)."""
    n_tau = len(TABLE_TAUS)
    x_tau = np.clip(np.log2(np.maximum(tau, 1e-12)) - math.log2(TABLE_TAUS[0]), 0.0, n_tau - 1.0)
    low = np.minimum(np.floor(x_tau), n_tau - 2)
    return low, x_tau - low, cos_texel(cos_sun), cos_texel(cos_view)


def cos_texel(cosine):
    """Continuous texel coordinate (centres at i + 0.5) of a zenith cosine on TABLE_COS,
    clamped to the outer centres."""
    n_cos = len(TABLE_COS)
    return np.clip((cosine - TABLE_COS[0]) / (TABLE_COS[-1] - TABLE_COS[0]) * (n_cos - 1), 0.0, n_cos - 1.0) + 0.5


def _bilinear(table, side, node, ts, tv):
    """Bilinear look-up (Blender's Linear) of the (n_sun, n_view, terms) blocks
    ``table[side, node]``, per element, at texel coordinates (ts, tv)."""
    fs, fv = ts - 0.5, tv - 0.5
    s0 = np.clip(np.floor(fs), 0, table.shape[2] - 2).astype(int)
    v0 = np.clip(np.floor(fv), 0, table.shape[3] - 2).astype(int)
    ws, wv = (fs - s0)[..., None], (fv - v0)[..., None]
    return ((1 - ws) * ((1 - wv) * table[side, node, s0, v0] + wv * table[side, node, s0, v0 + 1])
            + ws * ((1 - wv) * table[side, node, s0 + 1, v0] + wv * table[side, node, s0 + 1, v0 + 1]))


def higher_orders(tau, cos_sun, cos_view, cos_azimuth, reflected):
    """Second and higher orders leaving the slab toward the viewer, per unit sun irradiance: the
    delta-Eddington diffuse flux spread with the Monte Carlo table's angular shape.
    ``cos_azimuth``: between the line of sight's and the sun's horizontal directions;
    ``reflected`` (per element): the sun on the viewer's side, which picks the table's side."""
    tau, cos_sun, cos_view, cos_azimuth, reflected = np.broadcast_arrays(
        *(np.asarray(a, dtype=np.float64) for a in (tau, cos_sun, cos_view, cos_azimuth)), np.asarray(reflected))
    side = reflected.astype(int)
    series = higher_order_series()
    low, weight, ts, tv = table_coordinates(tau, cos_sun, cos_view)
    low = low.astype(int)
    lower = _bilinear(series, side, low, ts, tv)
    upper = _bilinear(series, side, low + 1, ts, tv)
    terms = lower + (upper - lower) * weight[..., None]
    cos2 = 2.0 * cos_azimuth ** 2 - 1.0
    shape = np.exp(terms[..., 0] + terms[..., 1] * cos_azimuth + terms[..., 2] * cos2
                   + terms[..., 3] * (2.0 * cos_azimuth * cos2 - cos_azimuth))
    mu_s = np.maximum(cos_sun, MIN_COS)
    back, through = two_stream(tau, cos_sun)
    return shape * mu_s * np.where(side == 1, back, through) / np.pi


def diffuse_two_stream(tau):
    """(reflected, diffusely transmitted) fraction of diffuse (sky) light falling on the slab."""
    f, g = DELTA_FRACTION, SCALED_ASYMMETRY
    x = 0.75 * (1.0 - g) * (1.0 - f) * np.asarray(tau, dtype=np.float64)
    reflected = x / (1.0 + x)
    return reflected, np.maximum(1.0 - reflected - np.exp(-2.0 * np.asarray(tau)), 0.0)


# The diffuse ratios' optical thicknesses: half-octaves over the higher orders' range (octaves
# read tau 2.5 2% bright).
DIFFUSE_TAUS_PER_OCTAVE = 2
DIFFUSE_TAUS = tuple(TABLE_TAUS[0] * 2.0 ** (k / DIFFUSE_TAUS_PER_OCTAVE)
                     for k in range(DIFFUSE_TAUS_PER_OCTAVE * (len(TABLE_TAUS) - 1) + 1))
# The diffuse shapes' quadrature over the lit face's hemisphere of incident directions.
DIFFUSE_ZENITHS = 24        # Gauss-Legendre in the incident zenith cosine
DIFFUSE_AZIMUTHS = 48


def _diffuse_radiance(tau, cos_view, reflected: bool):
    """(n,) radiance leaving a slab of optical thickness ``tau`` (n,) at zenith cosine
    ``cos_view`` (n,) under a sky of unit radiance on its lit face, scattered light only: the
    collimated response ``radiance`` (single scattering and the Monte Carlo table's higher
    orders) integrated over the incident directions."""
    x, w = np.polynomial.legendre.leggauss(DIFFUSE_ZENITHS)
    mu_s, w = 0.5 * (x + 1.0), 0.5 * w
    azimuth = (np.arange(DIFFUSE_AZIMUTHS) + 0.5) * 2.0 * math.pi / DIFFUSE_AZIMUTHS
    tau = np.asarray(tau, dtype=np.float64)[:, None, None]
    mu_v = np.maximum(np.asarray(cos_view, dtype=np.float64), MIN_COS)[:, None, None]
    mu_s, cos_az = mu_s[None, :, None], np.cos(azimuth)[None, None, :]
    across = np.sqrt(1.0 - mu_v ** 2) * np.sqrt(1.0 - mu_s ** 2) * cos_az
    # The view leaves the lit face (reflected) or the other one; its direction's cosine with the
    # direction toward each source.
    cos_sun_view = (-mu_v * mu_s if reflected else mu_v * mu_s) + across
    shape = np.broadcast_shapes(tau.shape, mu_s.shape, cos_az.shape)
    out = radiance(tau, mu_s, mu_v, cos_sun_view, np.broadcast_to(cos_az, shape), np.full(shape, reflected))
    return np.einsum("nsa,s->n", out, w) * (2.0 * math.pi / DIFFUSE_AZIMUTHS)


@functools.lru_cache(maxsize=1)
def diffuse_ratios() -> np.ndarray:
    """(2, n_tau, n_cos): [0] let through, [1] reflected, the radiance a slab of optical
    thickness DIFFUSE_TAUS sends out toward zenith cosine TABLE_COS under a uniform sky on its
    lit face, over the isotropic radiance of the delta-Eddington diffuse flux
    (diffuse_two_stream / pi); read-only.

    The two-stream fluxes leave a cloud isotropically, but a thick cloud's base is
    limb-darkened (by the path tracer, 70 deg from the zenith 0.72x the isotropic radiance,
    20 deg from it 1.2x) and a thin cloud's top under a uniform sky limb-brightened (1.4x at
    70 deg). From below a deck looking up 20 deg under a low sun, where the skylight on its top
    is most of its light, the isotropic shares came out 1.29x the atmosphere tracer's."""
    n_tau = len(DIFFUSE_TAUS)
    taus = np.repeat(np.asarray(DIFFUSE_TAUS, dtype=np.float64), len(TABLE_COS))
    cosines = np.tile(np.asarray(TABLE_COS, dtype=np.float64), n_tau)
    back, through = diffuse_two_stream(taus)
    ratios = np.stack([_diffuse_radiance(taus, cosines, False) / np.maximum(through, 1e-12),
                       _diffuse_radiance(taus, cosines, True) / np.maximum(back, 1e-12)])
    ratios = ratios.reshape(2, n_tau, len(TABLE_COS))
    ratios.flags.writeable = False
    return ratios


def diffuse_tau_coordinate(tau):
    """The node coordinate of ``tau`` on DIFFUSE_TAUS, clamped to its ends."""
    x = (np.log2(np.maximum(tau, 1e-12)) - math.log2(DIFFUSE_TAUS[0])) * DIFFUSE_TAUS_PER_OCTAVE
    return np.clip(x, 0.0, len(DIFFUSE_TAUS) - 1.0)


def diffuse_shares(tau, cos_view):
    """(reflected, let through): the radiance toward zenith cosine ``cos_view`` (taken
    positive) of a slab under diffuse light of unit irradiance on its lit face, times pi (the
    fluxes of diffuse_two_stream where they leave isotropically), with diffuse_ratios' angular
    shape: linear in log2(tau) between its nodes and in the view cosine (clamped at the ends;
    thicker slabs keep the last node's shape)."""
    tau = np.asarray(tau, dtype=np.float64)
    ratios = diffuse_ratios()
    x_tau = diffuse_tau_coordinate(tau)
    low = np.minimum(np.floor(x_tau), len(DIFFUSE_TAUS) - 2).astype(int)
    weight = x_tau - low
    fv = cos_texel(np.asarray(cos_view, dtype=np.float64)) - 0.5
    v0 = np.clip(np.floor(fv), 0, ratios.shape[2] - 2).astype(int)
    wv = fv - v0

    def at(side, node):
        return (1.0 - wv) * ratios[side, node, v0] + wv * ratios[side, node, v0 + 1]
    back, through = diffuse_two_stream(tau)
    shape = [at(side, low) + (at(side, low + 1) - at(side, low)) * weight for side in (0, 1)]
    return back * shape[1], through * shape[0]


def cos_azimuth(cos_view, cos_sun, cos_sun_view):
    """Cosine of the azimuth between the line of sight and the sun, from signed zenith cosines
    and their mutual cosine (1 where either is vertical: the azimuth is then moot)."""
    across = np.sqrt(np.maximum(1.0 - cos_view ** 2, 0.0) * np.maximum(1.0 - cos_sun ** 2, 0.0))
    return np.where(across > 1e-6, np.clip((cos_sun_view - cos_view * cos_sun) / np.maximum(across, 1e-6), -1.0, 1.0), 1.0)


def radiance(tau, cos_sun, cos_view, cos_sun_view, cos_az, reflected):
    """All orders, per unit sun irradiance. ``cos_sun``, ``cos_view``: absolute zenith cosines."""
    single = np.where(reflected, single_scattering(tau, cos_sun, cos_view, cos_sun_view, below=False),
                      single_scattering(tau, cos_sun, cos_view, cos_sun_view, below=True))
    return single + higher_orders(tau, cos_sun, cos_view, cos_az, reflected)


TABLE_ROWS = 3 * len(TABLE_COS)     # the table image: two sides of higher orders, the diffuse block


def table_pixels() -> np.ndarray:
    """The slab's tables as an RGBA float image (rows bottom to top) for the node group:
    - the higher orders: row side * n_cos + sun node, column tau node * n_cos + view node, RGBA
      the four terms of the log series (the image is channel-packed: its alpha is data). Within
      one tau node's block the image's bilinear filtering at texel coordinates clamped to the
      block's outer centres is _bilinear's;
    - the diffuse ratios (diffuse_ratios) above them: row 2 n_cos + view node, column tau node,
      R let through, G reflected (DIFFUSE_TAUS nodes). One bilinear fetch blends both axes as
      diffuse_shares."""
    series = higher_order_series()
    diffuse = diffuse_ratios()
    n_cos, n_tau = len(TABLE_COS), len(TABLE_TAUS)
    pixels = np.ones((TABLE_ROWS, n_tau * n_cos, 4), dtype=np.float32)
    for side in range(2):
        for node in range(n_tau):
            pixels[side * n_cos:(side + 1) * n_cos, node * n_cos:(node + 1) * n_cos] = series[side, node]
    pixels[2 * n_cos:, :len(DIFFUSE_TAUS), 0] = diffuse[0].T
    pixels[2 * n_cos:, :len(DIFFUSE_TAUS), 1] = diffuse[1].T
    return pixels
