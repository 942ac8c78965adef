"""Ray geometry and quadrature of the brute-force references (lut_gen.verify.reference): rays
through the spherical shell of ``AtmosphereParams``, the clustered nodes they are integrated on,
and the trapezoid and cumulative rules over those nodes. Shared by the transmittance, the
single-scattering and the second-order references; nothing here reads a table.

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
"""
from __future__ import annotations

import numpy as np

from ..model.atmosphere import AtmosphereParams

# Budget of float64 elements per work array (bounds memory; ~16 MB per array).
_CHUNK_ELEMENTS = 1 << 21


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


# -- clustered nodes and the rules on them ------------------------------------------------------

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


def _chunks(total: int, per_item: int):
    """Slices of ``total`` rays, each bounding the work arrays to _CHUNK_ELEMENTS elements."""
    size = max(1, _CHUNK_ELEMENTS // max(per_item, 1))
    for start in range(0, total, size):
        yield slice(start, min(start + size, total))
