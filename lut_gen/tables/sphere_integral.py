"""J~ of each scattering order: the sphere integral of Yusov 2013 eq. (1), the previous order's
radiance (and the lit ground) against the phase functions, per unit density and scattering
coefficient, on the order grid.

For a fixed height and sun zenith the integral is a convolution in azimuth with the phase
function, done with real cosine transforms over a fixed direction grid (zenith cosines from
sphere_zenith_grid, SPHERE_AZIMUTHS azimuths); the discrete kernel is normalised so that a
constant radiance integrates exactly."""
from __future__ import annotations

import math

import numpy as np

from . import parameterization as par
from ..model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase
from .bake_parallel import parallel_rows, workers
from .interpolation import axis_weights, gather, packed_rows

SPHERE_BELOW_NODES = 17         # sphere-integral zeniths below the horizon band (angle-spaced)
SPHERE_BAND_NODES = 49          # ... inside the band of horizons (cos-spaced)
SPHERE_ABOVE_NODES = 25         # ... above it (angle-spaced, up to the zenith)
SPHERE_AZIMUTHS = 64            # azimuth samples of the sphere integral (full circle)


def sphere_zenith_grid(atmosphere_height: float, earth_radius: float):
    """Nodes (ascending, poles included) and trapezoid weights in cos zenith over [-1, 1]:
    evenly spaced in angle toward the poles (the Mie kernel is ~10 deg wide everywhere) and
    dense in cos zenith in the band where the horizon of every height inside the atmosphere
    lies, so the radiance jump there costs little."""
    c_low = float(par.cos_horizon(atmosphere_height, earth_radius)) - 0.05
    c_high = 0.05
    below = np.cos(np.linspace(math.pi, math.acos(c_low), SPHERE_BELOW_NODES))
    band = np.linspace(c_low, c_high, SPHERE_BAND_NODES)
    above = np.cos(np.linspace(math.acos(c_high), 0.0, SPHERE_ABOVE_NODES))
    mu = np.concatenate([below[:-1], band[:-1], above])
    mu[0], mu[-1] = -1.0, 1.0
    gaps = np.diff(mu)
    weights = np.zeros_like(mu)
    weights[:-1] += 0.5 * gaps
    weights[1:] += 0.5 * gaps
    return mu, weights


def _cosine_transforms(n_az: int):
    """Forward (m, j) and inverse (j, m) real DFTs of sequences on a circle of n_az samples
    that are symmetric about az = 0, using only the samples j = 0 .. n_az/2 (az in [0, pi])."""
    half = n_az // 2 + 1
    angle = 2 * math.pi * np.outer(np.arange(half), np.arange(half)) / n_az
    doubled = np.full(half, 2.0)
    doubled[[0, -1]] = 1.0           # az = 0 and az = pi appear once on the full circle
    forward = np.cos(angle) * doubled[None, :]
    inverse = np.cos(angle).T * doubled[None, :] / n_az
    return forward.astype(np.float32), inverse.astype(np.float32)


def phase_kernels(params: AtmosphereParams, mu, mu_weights, n_az: int):
    """Spectra over the azimuth difference of the discretised phase functions,
    (n_az//2+1, n_mu_out, n_mu_in) for Rayleigh, Mie and (with fog) the fog, rows normalised to
    integrate to 1."""
    sin = np.sqrt(np.clip(1 - mu * mu, 0, 1))
    d_az = 2 * math.pi / n_az
    cos_az = np.cos(np.arange(n_az // 2 + 1) * d_az)
    cosang = mu[:, None, None] * mu[None, :, None] + sin[:, None, None] * sin[None, :, None] * cos_az
    forward, _ = _cosine_transforms(n_az)
    kernels = []
    phases = [rayleigh_phase(cosang), mie_phase(cosang, params.mie_g)]
    if params.has_fog:
        phases.append(mie_phase(cosang, params.fog_g))
    for phase in phases:
        k = phase * mu_weights[None, :, None] * d_az
        spectrum = np.einsum("vwj,mj->mvw", k, forward.astype(np.float64))
        spectrum /= spectrum[0].sum(axis=1)[None, :, None]      # m = 0 holds the full integral
        kernels.append(spectrum.astype(np.float32))
    return kernels


# Azimuthal frequencies of the sphere integral: a kernel's frequencies from the first one
# under KERNEL_FREQUENCY_FLOOR of its m = 0 term on are left out of the convolution. The
# Rayleigh kernel holds m <= 2 only (its phase is quadratic in the cosine of the scattering
# angle), so its convolution takes 3 of the 33 frequencies; the Mie and fog kernels keep all.
# (The radiance of the orders after the second is not smooth enough in azimuth to truncate it
# as well: its spectrum levels off at a few 1e-3 of the m = 0 term from m ~ 12 on, the kinks of
# the tables' linear interpolation along the sun-view cosine.)
KERNEL_FREQUENCY_FLOOR = 1e-6


def frequencies_needed(kernel: np.ndarray) -> int:
    """M: how many leading frequencies (axis 0) of a kernel's cosine spectrum (m, mu, mu) are
    not negligible (KERNEL_FREQUENCY_FLOOR of the m = 0 term)."""
    size = np.abs(kernel).max(axis=(1, 2))
    above = np.nonzero(size > KERNEL_FREQUENCY_FLOOR * size[0])[0]
    return int(above[-1]) + 1


def scattered_radiance(params, dims_j, prev_n, mu, kernels, n_az, prev_mie=None, ground=None, prev_fog=None):
    """J~ for Rayleigh, Mie and the fog (phase-convolved radiance, per unit density and
    scattering coefficient; one per kernel) on the order grid: (n_h, n_a, n_s, n_t, media x C).
    ``prev_n`` is the previous order divided by the Rayleigh phase, like the stored tables;
    ``prev_mie`` and ``prev_fog`` (order 2) the single Mie and fog scattering without their
    phases, which are applied here per sphere direction. ``ground``: (GroundSource, irradiance
    of the ground by the order before) adds the lit ground.

    Each height's J~ needs the previous order at that height alone: the heights are shared
    between the cores (on one, this took 0.8 s of each order of the default bake)."""
    n_h, n_a, n_s, n_t = dims_j
    channels = prev_n.shape[-1]
    source = np.concatenate([t for t in (prev_n, prev_mie, prev_fog) if t is not None], axis=-1)
    packed, width = packed_rows(source.reshape(-1, source.shape[-1]))
    directions = _SphereDirections(params, dims_j, mu, n_az)
    if ground is not None:
        ground[0].radiance(ground[1], directions.cos_sun_view, slice(0, 0))     # its sun weights, once
    out = np.empty((n_h, n_a, n_s, n_t, len(kernels) * channels), dtype=np.float32)
    parts = np.array_split(np.arange(n_h), min(n_h, 2 * workers()))

    def fill(part):
        rows = slice(int(parts[part][0]), int(parts[part][-1]) + 1)
        out[rows] = _scattered_radiance_rows(params, dims_j, directions, packed, width, channels, kernels, rows,
                                             prev_mie is not None, prev_fog is not None, ground)
    parallel_rows(fill, len(parts), lambda stage, fraction: None, "scattered radiance")
    return out


class _SphereDirections:
    """The sphere directions J~ integrates over (zenith cosines ``mu``, ``n_az`` azimuths, of
    which the half circle is kept: the sky is symmetric about the sun's plane) against the
    order grid's sun nodes, and where each falls on the grid's view-zenith and sun-view axes."""

    def __init__(self, params, dims_j, mu, n_az):
        n_h, n_a, n_s, n_t = dims_j
        self.heights, self.cos_view, _, self.cos_sun, self.cos_sun_view_nodes = par.grid_axes(params, dims_j)
        self.mu, self.n_az = mu, n_az
        self.half = n_az // 2 + 1
        self.d_az = 2 * math.pi / n_az
        az = np.arange(self.half) * self.d_az
        sin_mu = np.sqrt(np.clip(1 - mu * mu, 0, 1))
        sin_sun = np.sqrt(np.clip(1 - self.cos_sun * self.cos_sun, 0, 1))
        xa, _ = par.view_zenith_to_x(mu[None, :], self.heights[:, None], n_a, params.earth_radius)  # (h, mu)
        self.cos_sun_view = (mu[None, :, None] * self.cos_sun[:, None, None]
                             + sin_mu[None, :, None] * sin_sun[:, None, None] * np.cos(az))        # (s, mu, az)
        xt = par.sun_view_to_x(self.cos_sun_view, n_t)
        self.ia, self.wa = axis_weights(xa, n_a)
        self.it, self.wt = axis_weights(xt, n_t)
        self.rayleigh = rayleigh_phase(self.cos_sun_view).astype(np.float32)[None, ..., None]
        self.mie = mie_phase(self.cos_sun_view, params.mie_g).astype(np.float32)[None, ..., None]
        self.fog = mie_phase(self.cos_sun_view, params.fog_g).astype(np.float32)[None, ..., None]
        self.transforms = _cosine_transforms(n_az)


def _scattered_radiance_rows(params, dims_j, directions: _SphereDirections, packed, width, channels, kernels,
                             rows: slice, mie: bool, fog: bool, ground):
    """scattered_radiance at the heights ``rows`` of the order grid, from the previous order
    packed (packed_rows) with its channels Rayleigh, then Mie and the fog when ``mie`` and
    ``fog``."""
    n_h, n_a, n_s, n_t = dims_j
    n_media = len(kernels)
    mu, half, d_az = directions.mu, directions.half, directions.d_az
    n_mu = len(mu)
    heights = np.arange(n_h)[rows]
    n_rows = len(heights)
    ia, wa = directions.ia[rows], directions.wa[rows]
    it, wt = directions.it, directions.wt
    # Previous-order radiance on the direction grid (exact height and sun nodes): (h, s, mu, az, 3).
    base_h = heights[:, None, None, None] * (n_a * n_s * n_t)
    base_s = np.arange(n_s)[None, :, None, None] * n_t
    radiance = np.zeros((n_rows, n_s, n_mu, half, width), dtype=np.float32)
    for da, w_a in ((0, 1 - wa), (1, wa)):
        for dt, w_t in ((0, 1 - wt), (1, wt)):
            idx = base_h + (ia + da)[:, None, :, None] * (n_s * n_t) + base_s + (it + dt)[None]
            radiance += (w_a[:, None, :, None] * w_t[None])[..., None] * gather(packed, width, idx)
    scattered = radiance[..., :channels] * directions.rayleigh
    if mie:
        scattered += radiance[..., channels:2 * channels] * directions.mie
    if fog:
        scattered += radiance[..., 2 * channels:3 * channels] * directions.fog
    if ground is not None:
        ground_source, irradiance = ground
        scattered += ground_source.radiance(irradiance, directions.cos_sun_view, rows)
    radiance = scattered
    # Convolution in azimuth = product of cosine spectra; a matmul over mu per frequency.
    forward, inverse = directions.transforms
    by_az = np.ascontiguousarray(radiance.transpose(3, 2, 0, 1, 4)).reshape(half, -1)           # (j, mu*h*s*C)
    spectrum = (forward @ by_az).reshape(half, n_mu, -1)                                       # (m, mu, h*s*C)
    table = np.zeros((n_rows, n_s, n_mu, half, n_media * channels), dtype=np.float32)
    for medium, kernel in enumerate(kernels):
        m = frequencies_needed(kernel)
        conv = np.matmul(kernel[:m], spectrum[:m]).reshape(m, -1)                              # (m, mu_v*h*s*C)
        back = (inverse[:, :m] @ conv).reshape(half, n_mu, n_rows, n_s, channels)             # (j, mu_v, h, s, C)
        table[..., channels * medium:channels * (medium + 1)] = back.transpose(2, 3, 1, 0, 4)
    # Resample from (mu, az) to the table's (cos view zenith, cos sun-view) nodes.
    cos_view = directions.cos_view[rows]
    ca = cos_view[:, :, None, None]                                                         # (h, a, 1, 1)
    cs = directions.cos_sun[None, None, :, None]
    ctn = par.clamp_sun_view(ca, cs, directions.cos_sun_view_nodes[None, None, None, :])    # (h, a, s, t)
    denom = np.sqrt(np.clip(1 - ca * ca, 0, 1) * np.clip(1 - cs * cs, 0, 1))
    cos_daz = np.where(denom > 1e-9, (ctn - ca * cs) / np.maximum(denom, 1e-9), 1.0)
    i_az, w_az = axis_weights(np.arccos(np.clip(cos_daz, -1, 1)) / d_az, half)               # (h, a, s, t)
    i_mu, w_mu = axis_weights(np.interp(cos_view, mu, np.arange(n_mu)), n_mu)                 # (h, a)
    packed, width = packed_rows(table.reshape(-1, n_media * channels))
    base = (np.arange(n_rows)[:, None, None, None] * n_s + np.arange(n_s)[None, None, :, None]) * n_mu
    out = np.zeros((n_rows, n_a, n_s, n_t, width), dtype=np.float32)
    for dm, w_m in ((0, 1 - w_mu), (1, w_mu)):
        for dz, w_z in ((0, 1 - w_az), (1, w_az)):
            idx = (base + (i_mu + dm)[:, :, None, None]) * half + i_az + dz
            out += (w_m[:, :, None, None] * w_z)[..., None] * gather(packed, width, idx)
    # The cosine-series convolution rings slightly (a few 1e-3 of the peak) next to the sun's
    # Mie peak; scattered radiance is never negative.
    return np.maximum(out[..., :n_media * channels], 0.0)

