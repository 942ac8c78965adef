"""Optical depth and transmittance of the brute-force references: the media's densities
integrated along straight rays to the top of the atmosphere (``net_density_to_top``,
``transmittance_to_top``) and over a ray's first metres through the fog (``fog_net_density``),
and the ozone and fog line integrals the single-scattering and second-order references reuse.

Rayleigh and Mie are integrated on the clustered nodes of lut_gen.verify.reference_rays.

Ozone (a tent in height, with kinks at 10, 25 and 40 km) is integrated separately with
Gauss-Legendre quadrature on panels cut at every crossing of a kink height, so it is smooth
on each panel; the view ray's ozone depth to a node is the line integral from the start minus
the line integral from the node (same direction, both to the top sphere, through the Earth if
need be, where the tent is 0).

The fog (exp(-h / fog_height), scale heights of 1 m to 5 km at the ground) is integrated like
ozone, with Gauss-Legendre quadrature (``FOG_GAUSS_NODES``) on panels cut where the ray crosses
the heights ``h_low + fog_height * FOG_CUTS`` above its lowest point h_low on the segment (and at
that point), so every panel spans a bounded change of the density; the view ray's fog depth to a
node is the integral over [0, s] itself (not the difference of two lines through the Earth,
where the clamped profile is 1). With fog the view ray's panels are also cut where it crosses
``h_low + fog_height * FOG_VIEW_CUTS`` (``_fog_view_breaks``).

Measured (float64, default steps, Yusov parameters): net densities change by < 1e-5
relative between 64 and 8192 steps.
"""
from __future__ import annotations

import numpy as np

from ..model.profiles import OZONE_HALF_WIDTH_M, OZONE_PEAK_HEIGHT_M, fog_density, mie_density, rayleigh_density
from ..model.atmosphere import AtmosphereParams
from .reference_rays import (_chunks, _clamp_height, _distance_to_top, _hits_earth, _radius_along, _ray_nodes,
                             _trapezoid_weights)
from .reference_spectral import _three_channel

__all__ = ["net_density_to_top", "transmittance_to_top", "fog_net_density", "HIT_EARTH_NET_DENSITY"]


# Returned for every medium when a ray towards the top runs into the Earth.
HIT_EARTH_NET_DENSITY = 1e20
# Minimum Gauss-Legendre nodes per ozone panel.
OZONE_MIN_NODES = 4
# Fog: panel cuts, in fog scale heights above the lowest point of the segment, and the
# Gauss-Legendre nodes per panel; the density changes by at most e^0.5 on the panels that matter
# (those below ~10 scale heights) and e^-48 of it is left above the last cut.
FOG_CUTS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 13.0, 17.0, 22.0, 30.0, 40.0, 48.0)
FOG_GAUSS_NODES = 8
# Extra breakpoints of the view ray's panels with fog, in fog scale heights above its lowest
# point. One cut at 2 H measured best: more panels waste nodes on their clustered ends (cuts at
# 1, 3, 8, 20 H were 5-10x worse at 256 steps, 20-40x at 64).
FOG_VIEW_CUTS = (2.0,)
# The number of media (profiles.MEDIA: Rayleigh, Mie, ozone, fog).
MEDIA_COUNT = 4


# -- ozone ---------------------------------------------------------------------------------------

# Heights where the ozone tent profile has kinks (its only non-smooth points).
_OZONE_KINKS_M = (
    OZONE_PEAK_HEIGHT_M - OZONE_HALF_WIDTH_M,
    OZONE_PEAK_HEIGHT_M,
    OZONE_PEAK_HEIGHT_M + OZONE_HALF_WIDTH_M,
)


def _ozone_panel_nodes(steps: int) -> int:
    return max(OZONE_MIN_NODES, int(steps) // 32)


def _ozone_line(params: AtmosphereParams, r, mu, nodes_per_panel: int) -> np.ndarray:
    """(N,) ozone density integrated from radius r along mu to where the straight line leaves
    the top sphere, ignoring the Earth (the tent profile is 0 below its base anyway).

    The line is cut into panels at every crossing of a kink height of the tent profile, so
    the integrand is smooth on each panel, and each panel gets Gauss-Legendre quadrature.
    """
    length = _distance_to_top(params, r, mu)
    cuts = [np.zeros_like(r), length]
    b = r * mu
    c0 = r * r * (mu * mu - 1.0)
    for hk in _OZONE_KINKS_M:
        rk = params.earth_radius + hk
        disc = c0 + rk * rk
        root = np.sqrt(np.maximum(disc, 0.0))
        for sign in (-1.0, 1.0):
            cuts.append(np.where(disc > 0.0, np.clip(-b + sign * root, 0.0, length), 0.0))
    cuts = np.sort(np.stack(cuts, axis=-1), axis=-1)  # (N, 8)
    lo, hi = cuts[:, :-1, None], cuts[:, 1:, None]  # (N, 7, 1)
    x, w = np.polynomial.legendre.leggauss(int(nodes_per_panel))
    half = 0.5 * (hi - lo)
    s = 0.5 * (hi + lo) + half * x
    rs = _radius_along(r, mu, s)
    # The tent profile of profiles.ozone_density, written out for speed (tested equal).
    tent = np.maximum(1.0 - np.abs(rs - (params.earth_radius + OZONE_PEAK_HEIGHT_M)) / OZONE_HALF_WIDTH_M, 0.0)
    return np.einsum("nkj,j,nk->n", tent, w, half[..., 0])


# -- the fog ------------------------------------------------------------------------------------

def _lowest_height_on(params: AtmosphereParams, r, mu, s0, s1):
    """(N,) distance and height of the lowest point of the segments [s0, s1] of rays from radius
    r with zenith cosine mu (the height clamped at 0)."""
    s_star = np.clip(-r * mu, s0, s1)
    r_star = np.sqrt(np.maximum(r * r + s_star * (s_star + 2.0 * r * mu), 0.0))
    return s_star, np.maximum(r_star - params.earth_radius, 0.0)


def _fog_crossings(params: AtmosphereParams, r, mu, s0, s1, cuts, missing):
    """(N, 2 len(cuts)) distances where the rays cross the heights h_low + fog_height * cuts
    (h_low: the lowest height on [s0, s1]), clamped into [s0, s1]; ``missing`` (N,) where a
    crossing does not exist."""
    s_star, h_low = _lowest_height_on(params, r, mu, s0, s1)
    rmu = r * mu
    out = []
    for c in cuts:
        rc = params.earth_radius + h_low + params.fog_height * c
        disc = (rc - r) * (rc + r) + rmu * rmu  # rc^2 - (perpendicular distance)^2, no cancellation
        root = np.sqrt(np.maximum(disc, 0.0))
        for sign in (-1.0, 1.0):
            out.append(np.where(disc > 0.0, np.clip(-rmu + sign * root, s0, s1), missing))
    return np.stack(out, axis=-1), s_star


def _fog_segment(params: AtmosphereParams, r, mu, s0, s1, nodes_per_panel: int = None) -> np.ndarray:
    """(N,) fog density (profiles.fog_density) integrated over [s0, s1] along rays from radius r
    with zenith cosine mu (all (N,)): Gauss-Legendre on panels cut at the segment's lowest
    point and where it crosses h_low + fog_height * FOG_CUTS, so each panel is smooth and spans
    a bounded change of the density."""
    r, mu, s0, s1 = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in (r, mu, s0, s1)))
    s1 = np.maximum(s1, s0)
    crossings, s_star = _fog_crossings(params, r, mu, s0, s1, FOG_CUTS, s0)
    cuts = np.sort(np.concatenate([np.stack([s0, s_star, s1], axis=-1), crossings], axis=-1), axis=-1)
    lo, hi = cuts[..., :-1, None], cuts[..., 1:, None]
    x, w = np.polynomial.legendre.leggauss(int(nodes_per_panel or FOG_GAUSS_NODES))
    half = 0.5 * (hi - lo)
    s = 0.5 * (hi + lo) + half * x
    rs = np.sqrt(np.maximum(r[..., None, None] ** 2 + s * (s + 2.0 * (r * mu)[..., None, None]), 0.0))
    dens = fog_density(params, rs - params.earth_radius)
    return np.einsum("...kj,j,...k->...", dens, w, half[..., 0])


def _fog_view_breaks(params: AtmosphereParams, r, mu, length):
    """(N, 2 len(FOG_VIEW_CUTS)) extra panel breakpoints of view rays [0, length] with fog: their
    crossings of h_low + fog_height * FOG_VIEW_CUTS (0 where there is none)."""
    crossings, _ = _fog_crossings(params, r, mu, np.zeros_like(r), length, FOG_VIEW_CUTS, np.zeros_like(r))
    return crossings


# -- net densities and transmittance -------------------------------------------------------------

def _net_density_flat(params: AtmosphereParams, r, mu, steps: int, with_ozone: bool = True,
                      with_fog: bool = False, media: int = 3) -> np.ndarray:
    """(N, media) net densities for flat arrays r (radius), mu; no Earth-hit handling.

    Rayleigh and Mie: trapezoid on the clustered nodes; ozone: Gauss-Legendre panels split
    at the tent's kinks (0 when ``with_ozone`` is False); fog (column 3, ``media`` = 4):
    ``_fog_segment`` to the top (0 when ``with_fog`` is False).
    """
    length = _distance_to_top(params, r, mu)
    s, jac, du = _ray_nodes(r, mu, length, steps)
    h = _radius_along(r, mu, s) - params.earth_radius
    wts = jac * _trapezoid_weights(steps, du)
    out = np.zeros((r.size, media))
    out[:, 0] = np.einsum("nk,nk->n", rayleigh_density(params, h), wts)
    out[:, 1] = np.einsum("nk,nk->n", mie_density(params, h), wts)
    if with_ozone:
        out[:, 2] = _ozone_line(params, r, mu, _ozone_panel_nodes(steps))
    if with_fog:
        out[:, 3] = _fog_segment(params, r, mu, np.zeros_like(r), length)
    return out


def net_density_to_top(params: AtmosphereParams, height_m, cos_zenith, steps: int = 512) -> np.ndarray:
    """(..., 4) Rayleigh, Mie, ozone and fog densities integrated from the point to the top of
    the atmosphere (metres x relative density) along the direction with the given zenith
    cosine (profiles.MEDIA's order; the fog column is the fog profile's whether or not
    ``params.has_fog``, its extinction being 0 without fog).

    ``HIT_EARTH_NET_DENSITY`` (1e20) for all four where the ray runs into the Earth.
    Heights are clamped to [0, atmosphere_height], cosines to [-1, 1].
    """
    h, mu = np.broadcast_arrays(
        _clamp_height(params, height_m), np.clip(np.asarray(cos_zenith, np.float64), -1.0, 1.0)
    )
    shape = h.shape
    r = (h + params.earth_radius).ravel()
    mu = mu.ravel()
    out = np.empty((r.size, MEDIA_COUNT))
    per_ray = 4 * (int(steps) + 1) + (2 * len(FOG_CUTS) + 2) * FOG_GAUSS_NODES * 4
    for sl in _chunks(r.size, per_ray):
        out[sl] = _net_density_flat(params, r[sl], mu[sl], steps, with_fog=True, media=MEDIA_COUNT)
    hit = _hits_earth(params, r, mu)
    out[hit] = HIT_EARTH_NET_DENSITY
    return out.reshape(shape + (MEDIA_COUNT,))


def transmittance_to_top(params: AtmosphereParams, height_m, cos_zenith, steps: int = 512) -> np.ndarray:
    """(..., 3) RGB transmittance from the point to the top of the atmosphere; 0 where the
    ray runs into the Earth."""
    _three_channel(params)
    net = net_density_to_top(params, height_m, cos_zenith, steps)
    hit = net[..., 0] >= HIT_EARTH_NET_DENSITY
    ext = params.extinction_matrix()
    if not params.has_fog:  # the three media alone: the result does not depend on the fog column
        net, ext = net[..., :3], ext[:3]
    t = np.exp(-np.where(hit[..., None], 0.0, net) @ ext)
    return np.where(hit[..., None], 0.0, t)


def fog_net_density(params: AtmosphereParams, height_m, cos_zenith, distance_m) -> np.ndarray:
    """(...) fog density (profiles.fog_density, 1 at the ground) integrated along the first
    ``distance_m`` metres of the ray from the point with the given zenith cosine (the fog's
    quadrature of ``single_scattering``; no Earth-hit handling: keep the segment above ground)."""
    h, mu, d = np.broadcast_arrays(_clamp_height(params, height_m),
                                   np.clip(np.asarray(cos_zenith, np.float64), -1.0, 1.0),
                                   np.maximum(np.asarray(distance_m, np.float64), 0.0))
    r = h + params.earth_radius
    return _fog_segment(params, r.ravel(), mu.ravel(), np.zeros(r.size), d.ravel()).reshape(h.shape)
