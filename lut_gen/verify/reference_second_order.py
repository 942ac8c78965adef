"""The brute-force second-order reference: twice-scattered radiance per unit extraterrestrial
sun, built on the single-scattering reference (lut_gen.verify.reference_single_scattering).

J2(P, v, l) = int_sphere [beta_R rho_R(h_P) p_R(v.w) + beta_M rho_M(h_P) p_M(v.w)] L1(P, w, l) dw
L2(C, v, l) = int_0^D T_view(C -> P(s)) J2(P(s), v, l) ds,   P(s) = C + s v

(no ground reflection). L1(P, w, l) is the single-scattered radiance seen from P looking
along w, from ``single_scattering``. Everything is built from real 3D vectors: the viewer C
on the z axis, v in the xz plane, l from the sun-view angle; every point P along the view
ray has its own local zenith P/|P| and sphere frame.

Sphere quadrature at P: the frame (e1, e2, z) has z = P/|P| and e1 along the horizontal part
of l. Zenith cosines: Gauss-Legendre on [-1, mu_h] and [mu_h, 1], split at the local horizon
mu_h = -sqrt(1 - (R/|P|)^2) where L1 jumps (a ray just below it ends on the ground, one just
above it grazes on through the atmosphere). Azimuths: uniform midpoint nodes on the full
circle (the trapezoid rule of a periodic function). L1(P, w, l) is a function of
(|P|, w.z, l.z, w.l), so it is mirror-symmetric about the plane of z and l: it is evaluated
on the half circle az in (0, pi) only and weighted with the phase functions of both w and
its mirror image. The quadrature is not renormalised: its phase-function integrals are a
diagnostic (``sphere_phase_integrals``).

View ray: the panel nodes of single scattering (split at the ray's lowest point and at the
Earth's shadow crossings, smootherstep map per panel, trapezoid in u with the exact
Jacobian); nodes where the Jacobian vanishes (panel ends) carry no weight and skip the
expensive J2. T_view(C -> P) at every node is integrated on its own clustered sub-ray
(``transmittance_steps`` intervals), ozone as the difference of two Gauss-Legendre line
integrals as in single scattering.
"""
from __future__ import annotations

import numpy as np

from ..model.profiles import fog_density, mie_density, rayleigh_density
from ..model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase
from .reference_rays import (_clamp_height, _distance_to_ground, _distance_to_top, _hits_earth, _horizon_cos,
                             _panel_nodes, _radius_along, _shadow_crossings, _trapezoid_weights)
from .reference_single_scattering import single_scattering
from .reference_spectral import _three_channel
from .reference_transmittance import MEDIA_COUNT, _fog_segment, _fog_view_breaks, _ozone_line, _ozone_panel_nodes

__all__ = ["second_order", "second_order_source", "sphere_phase_integrals", "SECOND_ORDER_DEFAULTS"]


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
