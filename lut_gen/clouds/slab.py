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
  few percent of exact there. Its diffuse flux, less the part single scattering already carries,
  leaves isotropically.
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

FOURIER_TERMS = 3       # the higher orders' azimuthal cosine series: 1, cos(phi), cos(2 phi)
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
def higher_order_ratios() -> np.ndarray:
    """(2, n_tau, n_sun, n_view, 3): [0] seen from below, [1] from above, the cosine-series
    coefficients in azimuth (lut_gen.verify.slab_monte_carlo.higher_order_table) over the
    delta-Eddington flux's radiance; read-only."""
    try:
        with open(TABLE_PATH) as f:
            data = json.load(f)
        ratio = np.asarray(data["ratio"], dtype=np.float64)
    except (OSError, ValueError, KeyError) as error:
        raise CloudTableError(f"the cloud table {TABLE_PATH} is missing or damaged ({error}); "
                              "reinstall the extension or run scripts/gen_cloud_table.py") from None
    if ratio.shape != (2, len(TABLE_TAUS), len(TABLE_COS), len(TABLE_COS), FOURIER_TERMS) or not np.all(np.isfinite(ratio)):
        raise CloudTableError(f"the cloud table {TABLE_PATH} has the wrong shape or non-finite values; "
                              "reinstall the extension or run scripts/gen_cloud_table.py")
    ratio.flags.writeable = False
    return ratio


def table_coordinates(tau, cos_sun, cos_view):
    """(tau node below, its upper neighbour's weight, sun texel, view texel): continuous texel
    coordinates (centres at i + 0.5) of the cosines, clamped to the outer centres, and the
    log2-spaced tau axis' node and weight (clamped at both ends)."""
    n_cos, n_tau = len(TABLE_COS), len(TABLE_TAUS)
    x_tau = np.clip(np.log2(np.maximum(tau, 1e-12)) - math.log2(TABLE_TAUS[0]), 0.0, n_tau - 1.0)
    low = np.minimum(np.floor(x_tau), n_tau - 2)

    def texel(c):
        return np.clip((c - TABLE_COS[0]) / (TABLE_COS[-1] - TABLE_COS[0]) * (n_cos - 1), 0.0, n_cos - 1.0) + 0.5
    return low, x_tau - low, texel(cos_sun), texel(cos_view)


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
    ratio = higher_order_ratios()
    low, weight, ts, tv = table_coordinates(tau, cos_sun, cos_view)
    low = low.astype(int)
    lower = _bilinear(ratio, side, low, ts, tv)
    upper = _bilinear(ratio, side, low + 1, ts, tv)
    terms = lower + (upper - lower) * weight[..., None]
    shape = terms[..., 0] + terms[..., 1] * cos_azimuth + terms[..., 2] * (2.0 * cos_azimuth ** 2 - 1.0)
    mu_s = np.maximum(cos_sun, MIN_COS)
    back, through = two_stream(tau, cos_sun)
    return shape * mu_s * np.where(side == 1, back, through) / np.pi


def diffuse_two_stream(tau):
    """(reflected, diffusely transmitted) fraction of diffuse (sky) light falling on the slab."""
    f, g = DELTA_FRACTION, SCALED_ASYMMETRY
    x = 0.75 * (1.0 - g) * (1.0 - f) * np.asarray(tau, dtype=np.float64)
    reflected = x / (1.0 + x)
    return reflected, np.maximum(1.0 - reflected - np.exp(-2.0 * np.asarray(tau)), 0.0)


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


def table_pixels() -> np.ndarray:
    """The higher orders' table as an RGBA float image (rows bottom to top) for the node group:
    row side * n_cos + sun node, column tau node * n_cos + view node, RGB the three azimuthal
    terms. Within one tau node's block the image's bilinear filtering at texel coordinates
    clamped to the block's outer centres is _bilinear's."""
    ratio = higher_order_ratios()
    n_cos, n_tau = len(TABLE_COS), len(TABLE_TAUS)
    pixels = np.ones((2 * n_cos, n_tau * n_cos, 4), dtype=np.float32)
    for side in range(2):
        for node in range(n_tau):
            pixels[side * n_cos:(side + 1) * n_cos, node * n_cos:(node + 1) * n_cos, :3] = ratio[side, node]
    return pixels
