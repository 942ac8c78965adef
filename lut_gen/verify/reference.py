"""Brute-force reference integrators: the "truth" the precomputed tables are checked against.

Nothing here reads a table or interpolates precomputed data. Every quantity is integrated
numerically along straight rays through the spherical atmosphere of ``AtmosphereParams``:

* ``net_density_to_top``: integrated Rayleigh / Mie / ozone / fog densities to the top
  (``profiles.MEDIA``'s order, the rows of ``AtmosphereParams.extinction_matrix``).
* ``transmittance_to_top``: ``exp(-net @ extinction_matrix)``.
* ``single_scattering``: single-scattered radiance per unit extraterrestrial sun,
  phase functions included, with the sun's optical depth at every view sample integrated
  numerically as well (a ray per sample, not an analytic approximation). The fog
  (``params.has_fog``) is a fourth medium that only scatters, grey, with its own
  Cornette-Shanks phase function ``mie_phase(cos, params.fog_g)``.

This module is deliberately self-contained (it does not share geometry code with the baker)
so that it stays an independent check. Everything is float64 numpy, broadcast over the
inputs and processed in chunks to bound memory.

Sampling scheme
---------------
Rayleigh and Mie densities (and the single-scattering integrand) along a ray [0, D]: the ray
is cut into panels at its lowest point (the start for upward rays, the end for rays that
reach the ground, the tangent point for rays that pass it), where the density peaks, and,
for view rays, where the ray crosses the boundary of the Earth's shadow (the sun
transmittance jumps there). Nodes are uniform in u in [0, 1]; panels get a share of them
proportional to the cube root of their length (equal node spacing next to a shared
breakpoint, which is snapped onto a node), and each panel is mapped with smootherstep,
``s = b0 + (b1 - b0) g(w)``, ``g' = 30 w^2 (1 - w)^2``. Integrals are the trapezoid rule in u
of the integrand times the exact Jacobian ``ds/du``. The map clusters nodes at the lowest
point (g ~ 10 w^3: scale heights of ~1 km are resolved on rays over 1000 km long) and makes
the Jacobian vanish with its first derivative at every panel end, so the Euler-Maclaurin
endpoint terms vanish and the error is O(du^4) for smooth integrands.

The view ray's optical depth from its start to each node uses a 4th-order cumulative rule
(cubic through the 4 nearest nodes per interval), since inside the ray the Jacobian does not
vanish and a cumulative trapezoid would be only O(du^2).

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
``h_low + fog_height * FOG_VIEW_CUTS``: with the clustering at the lowest point this resolves a
fog of tens of metres on a ray of hundreds of kilometres. Measured (fog heights 10 and 50 m,
toward / away from a low sun, inside, above and looking down on the fog): single scattering at
the default (256, 64) steps within 1e-5 of (4096, 256) for visibilities of 300 m and more,
within 4e-4 at 30 m (the extinction length then, ~8 m, is shorter than the fog's scale);
vertical rays match the closed forms within 3e-6 (tests/numpy_only/test_fog_references.py).
Without fog none of this runs and the results are those of the three media alone, bit for bit.

Measured (float64, default steps, Yusov parameters): net densities change by < 1e-5
relative between 64 and 8192 steps; single scattering at (256, 64) steps is within ~1e-5
of (2048, 256) on random and twilight / grazing rays.
"""
from __future__ import annotations

import numpy as np

from ..model.profiles import OZONE_HALF_WIDTH_M, OZONE_PEAK_HEIGHT_M, fog_density, mie_density, rayleigh_density
from ..model import spectrum
from ..model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase

__all__ = ["net_density_to_top", "transmittance_to_top", "single_scattering", "HIT_EARTH_NET_DENSITY",
           "fog_net_density"]

# Returned for every medium when a ray towards the top runs into the Earth.
HIT_EARTH_NET_DENSITY = 1e20
# Budget of float64 elements per work array (bounds memory; ~16 MB per array).
_CHUNK_ELEMENTS = 1 << 21
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


# -- geometry ----------------------------------------------------------------------------------

def _clamp_height(params: AtmosphereParams, height_m) -> np.ndarray:
    return np.clip(np.asarray(height_m, dtype=np.float64), 0.0, params.atmosphere_height)


def _horizon_cos(params: AtmosphereParams, r) -> np.ndarray:
    """Cosine of the zenith angle of the geometric horizon seen from radius r >= R."""
    q = params.earth_radius / r
    return -np.sqrt(np.maximum(1.0 - q * q, 0.0))


def _hits_earth(params: AtmosphereParams, r, mu) -> np.ndarray:
    """True where the ray from radius r with zenith cosine mu meets the Earth sphere in front
    (tangent rays do not count as hits)."""
    return mu < _horizon_cos(params, r)


def _distance_to_top(params: AtmosphereParams, r, mu) -> np.ndarray:
    rt = params.top_radius
    disc = r * r * (mu * mu - 1.0) + rt * rt
    return np.maximum(-r * mu + np.sqrt(np.maximum(disc, 0.0)), 0.0)


def _distance_to_ground(params: AtmosphereParams, r, mu) -> np.ndarray:
    """Distance to the first hit of the Earth sphere (only meaningful where it is hit)."""
    re = params.earth_radius
    disc = r * r * (mu * mu - 1.0) + re * re
    return np.maximum(-r * mu - np.sqrt(np.maximum(disc, 0.0)), 0.0)


def _side_map(w):
    """Map of a panel: w in [0, 1] -> fraction of the panel's length, and its derivative.
    Smootherstep, g' = 30 w^2 (1 - w)^2: nodes cluster at both ends (g ~ 10 w^3) and the
    integrand times the Jacobian vanishes with its first derivative there, so the trapezoid
    rule's Euler-Maclaurin endpoint terms vanish up to O(du^4)."""
    w2 = w * w
    return w2 * w * (10.0 + w * (-15.0 + 6.0 * w)), 30.0 * w2 * (1.0 - w) ** 2


def _split_rows(k0, n: int):
    """Per split node index k0 (m,) the node coefficients (m, n+1) of the map:

    s = s_split + A * len_before + B * len_after, ds/du = JA * len_before + JB * len_after.
    """
    k = np.arange(n + 1, dtype=np.float64)[None, :]
    k0 = k0.astype(np.float64)[:, None]
    before = k <= k0
    with np.errstate(divide="ignore", invalid="ignore"):
        wa = np.where(before & (k0 > 0), (k0 - k) / k0, 0.0)
        wb = np.where(~before & (k0 < n), (k - k0) / (n - k0), 0.0)
        ga, dga = _side_map(wa)
        gb, dgb = _side_map(wb)
        ja = np.where(before & (k0 > 0), dga * n / k0, 0.0)
        jb = np.where(~before & (k0 < n), dgb * n / (n - k0), 0.0)
    return np.where(before, -ga, 0.0), np.where(before, 0.0, gb), ja, jb


def _ray_nodes(r, mu, length, n: int):
    """Clustered nodes on rays [0, length] (arrays of shape (N,)): the fast path of
    ``_panel_nodes`` for breakpoints (0, lowest point, length), used for the sun rays.

    Returns ``s`` (N, n+1) distances, ``jac`` (N, n+1) = ds/du and ``du`` = 1/n, so that
    ``integral f ds ~= trapezoid(f * jac) * du``. The ray is split at its lowest point
    (clamped into the ray) and the split is snapped onto node ``k0``, chosen so that the node
    spacing next to the split is the same on both sides.
    """
    n = int(n)
    if n < 2:
        raise ValueError(f"steps must be >= 2, got {n}")
    length = np.maximum(length, 0.0)
    s_low = np.minimum(np.maximum(-r * mu, 0.0), length)
    a = np.cbrt(s_low)
    b = np.cbrt(length - s_low)
    tot = a + b
    frac = np.divide(a, tot, out=np.zeros_like(tot), where=tot > 0.0)
    k0 = np.rint(frac * n).astype(np.int64)
    # A side that rounds to no interval is negligibly short (< (0.5/n)^3 of the other side's
    # length): the split moves to the ray's end and the other side covers the whole ray.
    s_split = np.where(k0 <= 0, 0.0, np.where(k0 >= n, length, s_low))
    len_a = s_split[:, None]
    len_b = (length - s_split)[:, None]
    uniq, inv = np.unique(k0, return_inverse=True)
    ca, cb, ja, jb = _split_rows(uniq, n)
    s = s_split[:, None] + ca[inv] * len_a + cb[inv] * len_b
    jac = ja[inv] * len_a + jb[inv] * len_b
    return s, jac, 1.0 / n


def _panel_nodes(breaks, n: int):
    """Nodes on rays cut into panels at sorted breakpoints ``breaks`` (N, m+1), from 0 to the
    ray's length. Same map as ``_ray_nodes`` (smootherstep on every panel) with the nodes
    shared out in proportion to the cube root of the panel lengths; every breakpoint that
    keeps a panel of its own lands on a node. Returns ``s``, ``jac``, ``du`` like ``_ray_nodes``.
    """
    n = int(n)
    if n < 2:
        raise ValueError(f"steps must be >= 2, got {n}")
    m = breaks.shape[-1] - 1
    weights = np.cbrt(np.maximum(np.diff(breaks, axis=-1), 0.0))
    cum = np.concatenate([np.zeros_like(breaks[:, :1]), np.cumsum(weights, axis=-1)], axis=-1)
    total = cum[:, -1:]
    frac = np.divide(cum, total, out=np.zeros_like(cum), where=total > 0.0)
    frac[:, -1] = 1.0
    knode = np.rint(frac * n)  # (N, m+1), knode[:, 0] = 0, knode[:, -1] = n
    j = np.arange(n + 1, dtype=np.float64)
    panel = (knode[:, None, 1:m] <= j[None, :, None]).sum(axis=-1)  # (N, n+1)
    k_lo = np.take_along_axis(knode, panel, axis=-1)
    k_hi = np.take_along_axis(knode, panel + 1, axis=-1)
    b_lo = np.take_along_axis(breaks, panel, axis=-1)
    b_hi = np.take_along_axis(breaks, panel + 1, axis=-1)
    width = k_hi - k_lo
    has = width > 0
    w = np.where(has, (j[None, :] - k_lo) / np.where(has, width, 1.0), 0.0)
    g, dg = _side_map(w)
    s = b_lo + (b_hi - b_lo) * g
    jac = np.where(has, (b_hi - b_lo) * dg * n / np.where(has, width, 1.0), 0.0)
    return s, jac, 1.0 / n


def _shadow_crossings(params: AtmosphereParams, r, mu_v, mu_s, nu, length):
    """(N, 2) distances along the view rays where they cross the boundary of the Earth's shadow
    (the cylinder of radius R behind the Earth along the sun direction), clamped into
    [0, length]; rays without a crossing get 0. The sun transmittance jumps there."""
    a = 1.0 - nu * nu
    b = r * (mu_v - mu_s * nu)
    c = r * r * (1.0 - mu_s * mu_s) - params.earth_radius ** 2
    disc = b * b - a * c
    ok = (a > 1e-12) & (disc > 0.0)
    root = np.sqrt(np.maximum(disc, 0.0))
    out = []
    for sign in (-1.0, 1.0):
        x = np.divide(-b + sign * root, a, out=np.zeros_like(a), where=ok)
        behind = r * mu_s + x * nu < 0.0  # on the anti-sun side of the Earth's centre
        valid = ok & behind & (x > 0.0) & (x < length)
        out.append(np.where(valid, x, 0.0))
    return np.stack(out, axis=-1)


def _radius_along(r, mu, s):
    """Radius at distance s (N, k...) along rays from radius r with zenith cosine mu (N,)."""
    extra = (1,) * (s.ndim - 1)
    r_ = r.reshape(r.shape + extra)
    b = (r * mu).reshape(r.shape + extra)
    return np.sqrt(np.maximum(r_ * r_ + s * (s + 2.0 * b), 0.0))


def _trapezoid_weights(n: int, du: float) -> np.ndarray:
    w = np.full(int(n) + 1, du)
    w[0] = w[-1] = 0.5 * du
    return w


def _trapezoid(f, du):
    """Trapezoid rule over the node axis (axis=-2 for (..., nodes, 3), i.e. f has a media axis)."""
    return du * (f.sum(axis=-2) - 0.5 * (f[..., 0, :] + f[..., -1, :]))


def _cumulative_integral(f, du):
    """Cumulative integral along axis -2 (nodes), 0 on the first node, 4th order: every
    interval integrates the cubic through its 4 nearest nodes,
    du/24 * (-f[i-1] + 13 f[i] + 13 f[i+1] - f[i+2]), one-sided on the first and last interval.
    (A cumulative trapezoid would leave an O(du^2) error inside the ray, where the Jacobian
    does not vanish.) Needs at least 4 nodes."""
    if f.shape[-2] < 4:
        raise ValueError("need at least 3 steps")
    c = du / 24.0
    inc = np.empty(f.shape[:-2] + (f.shape[-2] - 1,) + f.shape[-1:])
    inc[..., 1:-1, :] = c * (13.0 * (f[..., 1:-2, :] + f[..., 2:-1, :]) - f[..., :-3, :] - f[..., 3:, :])
    inc[..., 0, :] = c * (9.0 * f[..., 0, :] + 19.0 * f[..., 1, :] - 5.0 * f[..., 2, :] + f[..., 3, :])
    inc[..., -1, :] = c * (9.0 * f[..., -1, :] + 19.0 * f[..., -2, :] - 5.0 * f[..., -3, :] + f[..., -4, :])
    out = np.zeros_like(f)
    np.cumsum(inc, axis=-2, out=out[..., 1:, :])
    return out


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


def _chunks(total: int, per_item: int):
    size = max(1, _CHUNK_ELEMENTS // max(per_item, 1))
    for start in range(0, total, size):
        yield slice(start, min(start + size, total))


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


def _three_channel(params: AtmosphereParams) -> AtmosphereParams:
    """The integrators below take the media's three channels literally: spectral params must go
    through ``spectral`` / ``per_wavelength`` (their RGB coefficients are only an approximation)."""
    if params.spectral:
        raise ValueError("spectral params: call reference.spectral(integrator, params, ...) or "
                         "reference.per_wavelength(...) instead of the three-channel integrator")
    return params


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
    if not params.has_fog:  # the three media alone, as before the fog (bit for bit)
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


# -- single scattering ---------------------------------------------------------------------------

def _single_scattering_flat(params, r, mu_v, mu_s, nu, steps, sun_steps):
    """(N, 3) single scattering for flat arrays (already clamped and made consistent)."""
    ext = params.extinction_matrix()
    with_ozone = bool(np.any(ext[2] != 0.0))
    with_fog = bool(params.has_fog)
    media = MEDIA_COUNT if with_fog else 3
    ext = ext[:media]
    hits = _hits_earth(params, r, mu_v)
    to_top = _distance_to_top(params, r, mu_v)
    length = np.where(hits, np.minimum(_distance_to_ground(params, r, mu_v), to_top), to_top)
    # Panels: split at the lowest point of the ray and where it crosses the Earth's shadow.
    s_low = np.minimum(np.maximum(-r * mu_v, 0.0), length)
    breaks = np.sort(
        np.concatenate(
            [np.stack([np.zeros_like(r), s_low, length], axis=-1),
             _shadow_crossings(params, r, mu_v, mu_s, nu, length)]
            + ([_fog_view_breaks(params, r, mu_v, length)] if with_fog else []),
            axis=-1,
        ),
        axis=-1,
    )
    s, jac, du = _panel_nodes(breaks, steps)
    rs = np.clip(_radius_along(r, mu_v, s), params.earth_radius, params.top_radius)
    h_s = rs - params.earth_radius
    rho = np.stack([rayleigh_density(params, h_s), mie_density(params, h_s)], axis=-1)  # (N, n+1, 2)

    # Optical depth from the start of the view ray to every sample: 4th-order cumulative
    # quadrature for Rayleigh and Mie; ozone as the difference of two Gauss-Legendre line
    # integrals (from the start minus from the sample, same direction), exact at the kinks.
    net_view = np.zeros(rho.shape[:-1] + (media,))
    net_view[..., :2] = _cumulative_integral(rho * jac[..., None], du)
    if with_fog:  # the fog's own panels over [0, s] of every node
        net_view[..., 3] = _fog_segment(params, r[:, None], mu_v[:, None], np.zeros_like(s), s)
    if with_ozone:
        k = _ozone_panel_nodes(steps)
        mu_v_at = np.clip((r[:, None] * mu_v[:, None] + s) / rs, -1.0, 1.0)
        from_sample = _ozone_line(params, rs.ravel(), mu_v_at.ravel(), k).reshape(rs.shape)
        net_view[..., 2] = np.maximum(_ozone_line(params, r, mu_v, k)[:, None] - from_sample, 0.0)
        net_view[:, 0, 2] = 0.0
    t_view = np.exp(-(net_view @ ext))

    # Sun transmittance at every sample: a numerically integrated ray per sample.
    mu_s_at = np.clip((r[:, None] * mu_s[:, None] + s * nu[:, None]) / rs, -1.0, 1.0)
    r_flat = rs.ravel()
    mu_flat = mu_s_at.ravel()
    net_sun = _net_density_flat(params, r_flat, mu_flat, sun_steps, with_ozone, with_fog, media)
    t_sun = np.exp(-(net_sun @ ext))
    t_sun[_hits_earth(params, r_flat, mu_flat)] = 0.0
    t_sun = t_sun.reshape(rs.shape + (3,))

    weight = t_view * t_sun * jac[..., None]  # (N, n+1, 3)
    ray_r = _trapezoid(rho[..., 0:1] * weight, du)  # (N, 3)
    ray_m = _trapezoid(rho[..., 1:2] * weight, du)
    pr = rayleigh_phase(nu)[:, None]
    pm = mie_phase(nu, params.mie_g)[:, None]
    out = params.rayleigh * pr * ray_r + params.mie * pm * ray_m
    if with_fog:
        ray_f = _trapezoid(fog_density(params, h_s)[..., None] * weight, du)
        out = out + params.fog * mie_phase(nu, params.fog_g)[:, None] * ray_f
    return out


def single_scattering(
    params: AtmosphereParams,
    height_m,
    cos_view_zenith,
    cos_sun_zenith,
    cos_sun_view,
    steps: int = 256,
    sun_steps: int = 64,
) -> np.ndarray:
    """(..., 3) single-scattered radiance per unit extraterrestrial sun (phase included).

    L = int_0^D [beta_R rho_R(h_s) p_R(nu) + beta_M rho_M(h_s) p_M(nu, g)
                 + beta_F rho_F(h_s) p_M(nu, fog_g)] T_view(0->s) T_sun(P_s) ds

    (the fog term only with ``params.has_fog``; beta_F = params.fog, grey)

    with D the distance to the ground when the view ray hits the Earth, else to the top of
    the atmosphere. ``steps`` intervals on the view ray (clustered at its lowest point and at
    the Earth's shadow boundary), the view optical depth integrated cumulatively on the same
    nodes, and ``sun_steps`` intervals on the sun ray from every view sample (``T_sun`` = 0 where the
    sun ray runs into the Earth). ``cos_sun_view`` is clamped into the range that is
    geometrically consistent with the two zenith cosines; heights are clamped to
    [0, atmosphere_height]. 0 where the view ray has zero length.
    """
    _three_channel(params)
    if int(steps) < 3 or int(sun_steps) < 2:
        raise ValueError(f"need steps >= 3 and sun_steps >= 2, got {steps}, {sun_steps}")
    h, mu_v, mu_s, nu = np.broadcast_arrays(
        _clamp_height(params, height_m),
        np.clip(np.asarray(cos_view_zenith, np.float64), -1.0, 1.0),
        np.clip(np.asarray(cos_sun_zenith, np.float64), -1.0, 1.0),
        np.asarray(cos_sun_view, np.float64),
    )
    shape = h.shape
    r = (h + params.earth_radius).ravel()
    mu_v = mu_v.ravel()
    mu_s = mu_s.ravel()
    sin_v = np.sqrt(np.maximum(1.0 - mu_v * mu_v, 0.0))
    sin_s = np.sqrt(np.maximum(1.0 - mu_s * mu_s, 0.0))
    nu = np.clip(nu.ravel(), mu_v * mu_s - sin_v * sin_s, mu_v * mu_s + sin_v * sin_s)
    nu = np.clip(nu, -1.0, 1.0)
    out = np.empty((r.size, 3))
    per_ray = (int(steps) + 1) * (int(sun_steps) + 1) * 4
    if params.has_fog:
        per_ray += (int(steps) + 1) * (2 * len(FOG_CUTS) + 2) * FOG_GAUSS_NODES * 4
    for sl in _chunks(r.size, per_ray):
        out[sl] = _single_scattering_flat(params, r[sl], mu_v[sl], mu_s[sl], nu[sl], steps, sun_steps)
    return out.reshape(shape + (3,))


# -- second scattering order ---------------------------------------------------------------------
#
# J2(P, v, l) = int_sphere [beta_R rho_R(h_P) p_R(v.w) + beta_M rho_M(h_P) p_M(v.w)] L1(P, w, l) dw
# L2(C, v, l) = int_0^D T_view(C -> P(s)) J2(P(s), v, l) ds,   P(s) = C + s v
#
# (no ground reflection). L1(P, w, l) is the single-scattered radiance seen from P looking
# along w, from ``single_scattering``. Everything is built from real 3D vectors: the viewer C
# on the z axis, v in the xz plane, l from the sun-view angle; every point P along the view
# ray has its own local zenith P/|P| and sphere frame.
#
# Sphere quadrature at P: the frame (e1, e2, z) has z = P/|P| and e1 along the horizontal part
# of l. Zenith cosines: Gauss-Legendre on [-1, mu_h] and [mu_h, 1], split at the local horizon
# mu_h = -sqrt(1 - (R/|P|)^2) where L1 jumps (a ray just below it ends on the ground, one just
# above it grazes on through the atmosphere). Azimuths: uniform midpoint nodes on the full
# circle (the trapezoid rule of a periodic function). L1(P, w, l) is a function of
# (|P|, w.z, l.z, w.l), so it is mirror-symmetric about the plane of z and l: it is evaluated
# on the half circle az in (0, pi) only and weighted with the phase functions of both w and
# its mirror image. The quadrature is not renormalised: its phase-function integrals are a
# diagnostic (``sphere_phase_integrals``).
#
# View ray: the panel nodes of single scattering (split at the ray's lowest point and at the
# Earth's shadow crossings, smootherstep map per panel, trapezoid in u with the exact
# Jacobian); nodes where the Jacobian vanishes (panel ends) carry no weight and skip the
# expensive J2. T_view(C -> P) at every node is integrated on its own clustered sub-ray
# (``transmittance_steps`` intervals), ozone as the difference of two Gauss-Legendre line
# integrals as in single scattering.

SECOND_ORDER_DEFAULTS = dict(ray_steps=32, sphere_zeniths=16, sphere_azimuths=32,
                             l1_steps=32, l1_sun_steps=16, transmittance_steps=128)


def _sphere_rule(params: AtmosphereParams, r: float, n_mu: int, n_az: int):
    """Nodes of the sphere quadrature at radius r: zenith cosines (2 n_mu,), their weights, and
    half-circle azimuths (n_az // 2,) with the full-circle weight 2 pi / n_az each."""
    if int(n_mu) < 1 or int(n_az) < 2 or int(n_az) % 2:
        raise ValueError(f"need sphere_zeniths >= 1 and an even sphere_azimuths >= 2, got {n_mu}, {n_az}")
    mu_h = float(_horizon_cos(params, np.float64(r)))
    x, w = np.polynomial.legendre.leggauss(int(n_mu))
    mus, wts = [], []
    for a, b in ((-1.0, mu_h), (mu_h, 1.0)):
        mus.append(0.5 * (a + b) + 0.5 * (b - a) * x)
        wts.append(0.5 * (b - a) * w)
    az = (np.arange(int(n_az) // 2) + 0.5) * (2.0 * np.pi / int(n_az))
    return np.concatenate(mus), np.concatenate(wts), az, 2.0 * np.pi / int(n_az)


def _local_frame(z, l, v):
    """Orthonormal (e1, e2) perpendicular to the unit local zenith z, e1 along the horizontal
    part of l (of v when l is vertical, of the x axis when both are)."""
    for d in (l, v, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
        perp = d - np.dot(d, z) * z
        norm = np.linalg.norm(perp)
        if norm > 1e-9:
            e1 = perp / norm
            return e1, np.cross(z, e1)
    raise AssertionError("unreachable")


def _source_at_points(params, points, v, l, n_mu, n_az, l1_steps, l1_sun_steps):
    """(K, X, 3): int_sphere p_X(v.w) L1(P, w, l) dw for X = Rayleigh, Mie (and fog, with
    ``params.has_fog``) at K points (K, 3) (per unit density and scattering coefficient:
    J2 = beta_R rho_R J[0] + beta_M rho_M J[1] + beta_F rho_F J[2])."""
    k_pts = points.shape[0]
    out = np.zeros((k_pts, 3 if params.has_fog else 2, 3))
    if k_pts == 0:
        return out
    heights, mus_all, mul_all, nuwl_all, ph_all, wts_all = [], [], [], [], [], []
    for p in points:
        r = float(np.linalg.norm(p))
        z = p / r
        e1, e2 = _local_frame(z, l, v)
        mu, mu_w, az, az_w = _sphere_rule(params, r, n_mu, n_az)
        sin = np.sqrt(np.maximum(1.0 - mu * mu, 0.0))
        # w = sin (cos az e1 + sin az e2) + mu z, and its mirror image (az -> -az): (2, n_mu, half, 3)
        ca, sa = np.cos(az), np.sin(az)
        w = np.stack([sin[:, None, None] * (ca[:, None] * e1 + sgn * sa[:, None] * e2)[None]
                      + mu[:, None, None] * z for sgn in (1.0, -1.0)])
        cos_wv = np.clip(w @ v, -1.0, 1.0)                      # (2, n_mu, half)
        cos_wl = np.clip(w[0] @ l, -1.0, 1.0)                    # (n_mu, half), same for the mirror
        mu_wz = np.clip(w[0] @ z, -1.0, 1.0)
        ph = [rayleigh_phase(cos_wv).sum(axis=0), mie_phase(cos_wv, params.mie_g).sum(axis=0)]
        if params.has_fog:
            ph.append(mie_phase(cos_wv, params.fog_g).sum(axis=0))
        ph = np.stack(ph)
        heights.append(np.full(mu_wz.shape, r - params.earth_radius))
        mus_all.append(mu_wz)
        mul_all.append(np.full(mu_wz.shape, float(np.clip(np.dot(l, z), -1.0, 1.0))))
        nuwl_all.append(cos_wl)
        ph_all.append(ph)
        wts_all.append(mu_w[:, None] * az_w * np.ones_like(az)[None, :])
    l1 = single_scattering(params, np.stack(heights), np.stack(mus_all), np.stack(mul_all),
                           np.stack(nuwl_all), steps=l1_steps, sun_steps=l1_sun_steps)  # (K, n_mu, half, 3)
    ph = np.stack(ph_all)                                         # (K, 2, n_mu, half)
    wts = np.stack(wts_all)                                       # (K, n_mu, half)
    return np.einsum("kxma,kma,kmac->kxc", ph, wts, l1)


def _ray_geometry(params, r, mu_v, mu_s, nu):
    """3D vectors of one ray: viewer C on the z axis, v in the xz plane, l (unit vectors)."""
    sin_v = float(np.sqrt(max(1.0 - mu_v * mu_v, 0.0)))
    sin_s = float(np.sqrt(max(1.0 - mu_s * mu_s, 0.0)))
    c = np.array([0.0, 0.0, r])
    v = np.array([sin_v, 0.0, mu_v])
    if sin_v * sin_s > 1e-12:
        cos_phi = float(np.clip((nu - mu_v * mu_s) / (sin_v * sin_s), -1.0, 1.0))
    else:
        cos_phi = 1.0
    sin_phi = float(np.sqrt(max(1.0 - cos_phi * cos_phi, 0.0)))
    l = np.array([sin_s * cos_phi, sin_s * sin_phi, mu_s])
    return c, v, l


def _view_transmittance(params, r, mu_v, s_nodes, steps):
    """(K, 3) transmittance from the viewer (radius r, zenith cosine mu_v) to the points at
    distances s_nodes along the ray, each segment integrated on its own clustered nodes."""
    k = s_nodes.size
    rr = np.full(k, r)
    mm = np.full(k, mu_v)
    s_low = np.minimum(np.maximum(-r * mu_v, 0.0), s_nodes)
    breaks = np.stack([np.zeros(k), s_low, s_nodes], axis=-1)
    s, jac, du = _panel_nodes(breaks, steps)
    h = np.clip(_radius_along(rr, mm, s), params.earth_radius, params.top_radius) - params.earth_radius
    wts = jac * _trapezoid_weights(steps, du)
    media = MEDIA_COUNT if params.has_fog else 3
    net = np.zeros((k, media))
    net[:, 0] = np.einsum("nk,nk->n", rayleigh_density(params, h), wts)
    net[:, 1] = np.einsum("nk,nk->n", mie_density(params, h), wts)
    ext = params.extinction_matrix()[:media]
    if params.has_fog:
        net[:, 3] = _fog_segment(params, rr, mm, np.zeros(k), s_nodes)
    if np.any(ext[2] != 0.0):
        n_oz = _ozone_panel_nodes(steps)
        r_end = _radius_along(rr, mm, s_nodes[:, None])[:, 0]
        mu_end = np.clip((r * mu_v + s_nodes) / np.maximum(r_end, 1.0), -1.0, 1.0)
        net[:, 2] = np.maximum(_ozone_line(params, rr, mm, n_oz) - _ozone_line(params, r_end, mu_end, n_oz), 0.0)
        net[s_nodes <= 0.0, 2] = 0.0
    return np.exp(-(net @ ext))


def _second_order_ray(params, r, mu_v, mu_s, nu, ray_steps, sphere_zeniths, sphere_azimuths,
                      l1_steps, l1_sun_steps, transmittance_steps):
    """(3,) L2 of one ray (arguments already clamped and consistent)."""
    ra, mva, msa, nua = (np.array([x]) for x in (r, mu_v, mu_s, nu))
    hits = _hits_earth(params, ra, mva)
    to_top = _distance_to_top(params, ra, mva)
    length = np.where(hits, np.minimum(_distance_to_ground(params, ra, mva), to_top), to_top)
    if not length[0] > 0.0:
        return np.zeros(3)
    s_low = np.minimum(np.maximum(-ra * mva, 0.0), length)
    breaks = np.sort(np.concatenate([np.stack([np.zeros(1), s_low, length], axis=-1),
                                     _shadow_crossings(params, ra, mva, msa, nua, length)]
                                    + ([_fog_view_breaks(params, ra, mva, length)] if params.has_fog else []),
                                    axis=-1), axis=-1)
    s, jac, du = _panel_nodes(breaks, ray_steps)
    s, jac = s[0], jac[0]
    weight = jac * _trapezoid_weights(ray_steps, du)
    used = weight > 0.0
    s_used = s[used]
    c, v, l = _ray_geometry(params, r, mu_v, mu_s, nu)
    points = c[None, :] + s_used[:, None] * v[None, :]
    # Keep points inside the shell [R, R + H] (rounding at the ground / top ends).
    radii = np.linalg.norm(points, axis=-1)
    points *= (np.clip(radii, params.earth_radius, params.top_radius) / radii)[:, None]
    j = _source_at_points(params, points, v, l, sphere_zeniths, sphere_azimuths, l1_steps, l1_sun_steps)
    h = np.linalg.norm(points, axis=-1) - params.earth_radius
    t_view = _view_transmittance(params, r, mu_v, s_used, transmittance_steps)
    j2 = (params.rayleigh * rayleigh_density(params, h)[:, None] * j[:, 0]
          + params.mie * mie_density(params, h)[:, None] * j[:, 1])
    if params.has_fog:
        j2 = j2 + params.fog * fog_density(params, h)[:, None] * j[:, 2]
    return np.einsum("k,kc->c", weight[used], t_view * j2)


def _consistent_angles(params, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view):
    h, mu_v, mu_s, nu = np.broadcast_arrays(
        _clamp_height(params, height_m),
        np.clip(np.asarray(cos_view_zenith, np.float64), -1.0, 1.0),
        np.clip(np.asarray(cos_sun_zenith, np.float64), -1.0, 1.0),
        np.asarray(cos_sun_view, np.float64),
    )
    shape = h.shape
    mu_v, mu_s = mu_v.ravel(), mu_s.ravel()
    sin_v = np.sqrt(np.maximum(1.0 - mu_v * mu_v, 0.0))
    sin_s = np.sqrt(np.maximum(1.0 - mu_s * mu_s, 0.0))
    nu = np.clip(np.clip(nu.ravel(), mu_v * mu_s - sin_v * sin_s, mu_v * mu_s + sin_v * sin_s), -1.0, 1.0)
    return shape, (h.ravel() + params.earth_radius), mu_v, mu_s, nu


def second_order(
    params: AtmosphereParams,
    height_m,
    cos_view_zenith,
    cos_sun_zenith,
    cos_sun_view,
    ray_steps: int = SECOND_ORDER_DEFAULTS["ray_steps"],
    sphere_zeniths: int = SECOND_ORDER_DEFAULTS["sphere_zeniths"],
    sphere_azimuths: int = SECOND_ORDER_DEFAULTS["sphere_azimuths"],
    l1_steps: int = SECOND_ORDER_DEFAULTS["l1_steps"],
    l1_sun_steps: int = SECOND_ORDER_DEFAULTS["l1_sun_steps"],
    transmittance_steps: int = SECOND_ORDER_DEFAULTS["transmittance_steps"],
) -> np.ndarray:
    """(..., 3) twice-scattered radiance per unit extraterrestrial sun (no ground reflection).

    L2(C, v, l) = int_0^D T_view(C -> P(s)) J2(P(s), v, l) ds with
    J2(P, v, l) = int_sphere [beta_R rho_R p_R(v.w) + beta_M rho_M p_M(v.w)] L1(P, w, l) dw
    (plus beta_F rho_F p_M(v.w, fog_g) with fog; the sphere rule does not resolve the fog's
    forward peak at the default sphere nodes: see ``sphere_phase_integrals``),
    L1 from ``single_scattering(l1_steps, l1_sun_steps)``. ``ray_steps`` intervals on the view
    ray, ``sphere_zeniths`` Gauss-Legendre nodes on each side of the local horizon,
    ``sphere_azimuths`` (even) on the full circle, ``transmittance_steps`` intervals for
    T_view to each node. Cost ~ ray_steps * 2 sphere_zeniths * sphere_azimuths / 2 calls of
    L1 per ray (~0.5-1 s per ray at the defaults). Inputs broadcast and are clamped like
    ``single_scattering``.
    """
    _three_channel(params)
    if int(ray_steps) < 2 or int(transmittance_steps) < 2:
        raise ValueError(f"need ray_steps >= 2 and transmittance_steps >= 2, got {ray_steps}, {transmittance_steps}")
    shape, r, mu_v, mu_s, nu = _consistent_angles(params, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view)
    out = np.empty((r.size, 3))
    for i in range(r.size):
        out[i] = _second_order_ray(params, float(r[i]), float(mu_v[i]), float(mu_s[i]), float(nu[i]),
                                   int(ray_steps), int(sphere_zeniths), int(sphere_azimuths),
                                   int(l1_steps), int(l1_sun_steps), int(transmittance_steps))
    return out.reshape(shape + (3,))


def second_order_source(
    params: AtmosphereParams,
    height_m,
    cos_view_zenith,
    cos_sun_zenith,
    cos_sun_view,
    sphere_zeniths: int = SECOND_ORDER_DEFAULTS["sphere_zeniths"],
    sphere_azimuths: int = SECOND_ORDER_DEFAULTS["sphere_azimuths"],
    l1_steps: int = SECOND_ORDER_DEFAULTS["l1_steps"],
    l1_sun_steps: int = SECOND_ORDER_DEFAULTS["l1_sun_steps"],
) -> np.ndarray:
    """(..., 3) J2(P, v, l) in 1/m per unit sun at a point of the given height, for a view
    direction v and sun l with the given local zenith cosines and mutual cosine."""
    shape, r, mu_v, mu_s, nu = _consistent_angles(params, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view)
    out = np.empty((r.size, 3))
    for i in range(r.size):
        c, v, l = _ray_geometry(params, float(r[i]), float(mu_v[i]), float(mu_s[i]), float(nu[i]))
        j = _source_at_points(params, c[None, :], v, l, int(sphere_zeniths), int(sphere_azimuths),
                              int(l1_steps), int(l1_sun_steps))[0]
        h = r[i] - params.earth_radius
        out[i] = params.rayleigh * rayleigh_density(params, h) * j[0] + params.mie * mie_density(params, h) * j[1]
        if params.has_fog:
            out[i] += params.fog * fog_density(params, h) * j[2]
    return out.reshape(shape + (3,))


def sphere_phase_integrals(params: AtmosphereParams, height_m: float, view_dir,
                           sphere_zeniths: int = SECOND_ORDER_DEFAULTS["sphere_zeniths"],
                           sphere_azimuths: int = SECOND_ORDER_DEFAULTS["sphere_azimuths"],
                           sun_dir=(1.0, 0.0, 0.0)):
    """(Rayleigh, Mie) phase-function integrals of the sphere quadrature used by J2 at the given
    height, for a view direction ``view_dir`` (3D, local zenith = +z): exactly 1 for an exact
    rule, so 1 - value is the energy error of the discretised scattering."""
    z = np.array([0.0, 0.0, 1.0])
    v = np.asarray(view_dir, np.float64)
    v = v / np.linalg.norm(v)
    l = np.asarray(sun_dir, np.float64)
    l = l / np.linalg.norm(l)
    e1, e2 = _local_frame(z, l, v)
    mu, mu_w, az, az_w = _sphere_rule(params, params.earth_radius + float(height_m), sphere_zeniths, sphere_azimuths)
    sin = np.sqrt(np.maximum(1.0 - mu * mu, 0.0))
    ca, sa = np.cos(az), np.sin(az)
    w = np.stack([sin[:, None, None] * (ca[:, None] * e1 + sgn * sa[:, None] * e2)[None]
                  + mu[:, None, None] * z for sgn in (1.0, -1.0)])
    cos_wv = np.clip(w @ v, -1.0, 1.0)
    wts = mu_w[:, None] * az_w
    return (float(np.sum(rayleigh_phase(cos_wv) * wts)), float(np.sum(mie_phase(cos_wv, params.mie_g) * wts)))


__all__ += ["second_order", "second_order_source", "sphere_phase_integrals", "SECOND_ORDER_DEFAULTS"]


# -- per wavelength ------------------------------------------------------------------------------
#
# The bake of spectral params integrates at a few wavelengths and converts them to RGB. The
# reference integrates every 10 nm from 360 to 830 nm (48 wavelengths, as Bruneton 2017's
# reference) with the three-channel integrators above, three wavelengths at a time, and converts
# with the same solar spectrum and colour-matching functions (lut_gen.model.spectrum.rgb_weights).

REFERENCE_WAVELENGTHS_NM = tuple(float(v) for v in range(360, 831, 10))


def per_wavelength(integrator, params: AtmosphereParams, *args, wavelengths_nm=REFERENCE_WAVELENGTHS_NM,
                   **kwargs) -> np.ndarray:
    """(..., len(wavelengths)) ``integrator(params, *args, **kwargs)`` (a three-channel reference
    function) evaluated per wavelength on the spectral media of ``params``."""
    lam = np.asarray(wavelengths_nm, dtype=np.float64)
    padded = np.concatenate([lam, np.full(-len(lam) % 3, lam[-1])])
    parts = [integrator(spectrum.triple_params(params, padded[i:i + 3]), *args, **kwargs)
             for i in range(0, len(padded), 3)]
    return np.concatenate(parts, axis=-1)[..., :len(lam)]


def spectral(integrator, params: AtmosphereParams, *args, wavelengths_nm=REFERENCE_WAVELENGTHS_NM,
             **kwargs) -> np.ndarray:
    """(..., 3) linear Rec.709 per unit extraterrestrial sun of a three-channel reference
    integrator run per wavelength; the integrator itself for Sample 2013 (non-spectral) params."""
    if not params.spectral:
        return integrator(params, *args, **kwargs)
    radiance = per_wavelength(integrator, params, *args, wavelengths_nm=wavelengths_nm, **kwargs)
    return radiance @ spectrum.rgb_weights(wavelengths_nm).T
