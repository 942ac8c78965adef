"""Events of the atmosphere's Monte Carlo path tracer (lut_gen.verify.monte_carlo): the new
direction at a vertex (drawn from the phase functions in the air, cosine-weighted on the ground)
and next-event estimation towards the sun.

In the air the direction is drawn from a Rayleigh / Mie mixture by the two media's share of the
scattering there, summed over the channels; each channel's weight then corrects for its own
share. Fog (``params.has_fog``): a collision scatters off Rayleigh, Mie or fog in proportion to
their channel-summed scattering coefficients there (the fog's direction drawn with the Mie
sampler at fog_g; the weight is the three media's kernel over the mixture pdf), and next-event
estimation sums the three phase terms. Without fog the tracer makes no fog arrays and draws no
random numbers for it: its paths are those of the three media alone.
"""
from __future__ import annotations

import math

import numpy as np

from ..model.atmosphere import mie_phase, rayleigh_phase
from .monte_carlo_media import _Media, _around, _norm
from .monte_carlo_segments import _sun_transmittance


def _sample_rayleigh_cos(rng, n: int) -> np.ndarray:
    """cos theta with density proportional to 1 + cos^2: the root of c^3 + 3c + 4 - 8 xi = 0."""
    q = 4.0 - 8.0 * rng.random(n)
    a = np.cbrt(-0.5 * q + np.sqrt(0.25 * q * q + 1.0))
    return a - 1.0 / a


def _sample_mie_cos(rng, n: int, g: float) -> np.ndarray:
    """cos theta from the Cornette-Shanks phase function: Henyey-Greenstein proposals
    accepted with probability (1 + cos^2) / 2 (CS = HG x 3 (1 + cos^2) / (2 (2 + g^2)))."""
    out = np.empty(n)
    todo = np.arange(n)
    while todo.size:
        xi = rng.random(todo.size)
        if abs(g) < 1e-6:
            c = 2.0 * xi - 1.0
        else:
            t = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi)
            c = np.clip((1.0 + g * g - t * t) / (2.0 * g), -1.0, 1.0)
        accept = rng.random(todo.size) < 0.5 * (1.0 + c * c)
        out[todo[accept]] = c[accept]
        todo = todo[~accept]
    return out


def _scatter_with_fog(media: _Media, points, direction, rng):
    """``_scatter_atmosphere`` with the fog: Rayleigh, Mie or fog picked by their channel-summed
    share of the scattering at the point, the fog's Cornette-Shanks phase (fog_g) drawn with the
    Mie sampler; the proposal pdf is the mixture of the three phase functions."""
    n = points.shape[0]
    beta_r, beta_m, beta_f = media.scattering(_norm(points))
    shares = np.stack([beta_r.sum(axis=1), beta_m.sum(axis=1), beta_f.sum(axis=1)], axis=1)
    total = shares.sum(axis=1, keepdims=True)
    shares = np.where(total > 0.0, shares / np.where(total > 0.0, total, 1.0), np.array([1.0, 0.0, 0.0]))
    pick = (rng.random(n)[:, None] > np.cumsum(shares, axis=1)).sum(axis=1).clip(0, 2)
    cos_theta = np.empty(n)
    g_mie, g_fog = media.params.mie_g, media.params.fog_g
    for k, sampler in enumerate((lambda m: _sample_rayleigh_cos(rng, m), lambda m: _sample_mie_cos(rng, m, g_mie),
                                 lambda m: _sample_mie_cos(rng, m, g_fog))):
        mask = pick == k
        if mask.any():
            cos_theta[mask] = sampler(int(mask.sum()))
    phase_r, phase_m, phase_f = rayleigh_phase(cos_theta), mie_phase(cos_theta, g_mie), mie_phase(cos_theta, g_fog)
    pdf = shares[:, 0] * phase_r + shares[:, 1] * phase_m + shares[:, 2] * phase_f
    kernel = beta_r * phase_r[:, None] + beta_m * phase_m[:, None] + beta_f * phase_f[:, None]
    return _around(direction, cos_theta, rng), kernel / pdf[:, None]


def _scatter_atmosphere(media: _Media, points, direction, rng):
    """New directions at atmospheric vertices and the weight factors (N, 3): the scattering
    coefficient x phase function of every channel over the channel-free proposal pdf."""
    if media.has_fog:
        return _scatter_with_fog(media, points, direction, rng)
    n = points.shape[0]
    beta_r, beta_m, _ = media.scattering(_norm(points))
    total_r, total_m = beta_r.sum(axis=1), beta_m.sum(axis=1)
    p_rayleigh = np.divide(total_r, total_r + total_m, out=np.ones(n), where=total_r + total_m > 0.0)
    use_rayleigh = rng.random(n) < p_rayleigh
    cos_theta = np.empty(n)
    cos_theta[use_rayleigh] = _sample_rayleigh_cos(rng, int(use_rayleigh.sum()))
    cos_theta[~use_rayleigh] = _sample_mie_cos(rng, int((~use_rayleigh).sum()), media.params.mie_g)
    phase_r = rayleigh_phase(cos_theta)
    phase_m = mie_phase(cos_theta, media.params.mie_g)
    pdf = p_rayleigh * phase_r + (1.0 - p_rayleigh) * phase_m
    kernel = beta_r * phase_r[:, None] + beta_m * phase_m[:, None]
    return _around(direction, cos_theta, rng), kernel / pdf[:, None]


def _scatter_ground(media: _Media, points, rng):
    """Cosine-weighted directions about the ground normal; the Lambertian weight is the albedo."""
    normal = points / _norm(points)[:, None]
    cos_theta = np.sqrt(rng.random(points.shape[0]))
    return _around(normal, cos_theta, rng), np.full((points.shape[0], 3), media.params.ground_albedo)


def _sun_events(media: _Media, points, direction, on_ground, sun) -> np.ndarray:
    """(N, 3) radiance towards the previous vertex per unit path weight, from the sun alone."""
    t_sun = _sun_transmittance(media, points, sun)
    beta_r, beta_m, beta_f = media.scattering(_norm(points))
    nu = np.clip(direction @ sun, -1.0, 1.0)
    in_air = beta_r * rayleigh_phase(nu)[:, None] + beta_m * mie_phase(nu, media.params.mie_g)[:, None]
    if beta_f is not None:
        in_air = in_air + beta_f * mie_phase(nu, media.params.fog_g)[:, None]
    cos_sun = np.maximum(points @ sun / _norm(points), 0.0)
    on_earth = (media.params.ground_albedo / math.pi * cos_sun)[:, None]
    return np.where(on_ground[:, None], on_earth, in_air) * t_sun
