"""Monte Carlo path tracer for a homogeneous cloud slab: the reference the cloud layer's shading
(lut_gen/clouds/slab.py) is checked against.

A plane-parallel slab of optical thickness ``tau`` (no absorption unless ``albedo`` < 1) with
the cloud phase function of lut_gen.model.cloud_medium, lit from above by a collimated beam of
unit irradiance (perpendicular to the beam) whose direction makes ``cos_sun`` with the upward
normal. Photons are walked to every order; each collision adds its next-event estimate of the
radiance leaving the slab toward a viewer below (looking up) or above (looking down):
    L(v) = (E mu_0 / N) sum_collisions albedo p(d . v) exp(-t_exit / |mu_v|) / |mu_v|
with t_exit the optical depth from the collision to the slab's face along v. Horizontal
homogeneity makes the per-area average exact, so the estimator has no bias; its noise is
reported as a standard error.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import cloud_medium


@dataclass(frozen=True)
class SlabRadiance:
    below: np.ndarray          # (V,) radiance per unit sun irradiance seen from below, per view
    above: np.ndarray          # (V,) seen from above
    below_se: np.ndarray       # standard errors
    above_se: np.ndarray
    below_higher: np.ndarray   # the second and higher orders only (no first collision)
    above_higher: np.ndarray
    transmitted_flux: float    # total flux through the bottom per unit incident flux (direct + diffuse)


def _sample_phase(cos_in: np.ndarray, rng) -> np.ndarray:
    """Scattering-angle cosines drawn from cloud_medium.phase (a mix of Henyey-Greenstein lobes)."""
    u = rng.random(cos_in.shape)
    pick = rng.random(cos_in.shape)
    g = np.full(cos_in.shape, cloud_medium.PHASE_LOBES[-1][1])
    cumulative = 0.0
    # Lobes in order: the first whose cumulative weight passes ``pick``.
    chosen = np.zeros(cos_in.shape, dtype=bool)
    for weight, lobe_g in cloud_medium.PHASE_LOBES:
        cumulative += weight
        take = ~chosen & (pick < cumulative)
        g = np.where(take, lobe_g, g)
        chosen |= take
    s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = np.where(np.abs(g) > 1e-6, (1.0 + g * g - s * s) / (2.0 * g), 2.0 * u - 1.0)
    return np.clip(cos, -1.0, 1.0)


def _rotate(d: np.ndarray, cos_theta: np.ndarray, rng) -> np.ndarray:
    phi = rng.random(cos_theta.shape) * 2.0 * np.pi
    sin_theta = np.sqrt(np.maximum(1.0 - cos_theta ** 2, 0.0))
    helper = np.where(np.abs(d[:, 2:3]) < 0.9, np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    a = np.cross(d, helper)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(d, a)
    return (d * cos_theta[:, None] + a * (sin_theta * np.cos(phi))[:, None]
            + b * (sin_theta * np.sin(phi))[:, None])


def trace(tau: float, cos_sun: float, views: np.ndarray, photons: int = 20000, seed: int = 1,
          albedo: float = 1.0, max_orders: int = 4000) -> SlabRadiance:
    """Radiance of the slab per unit sun irradiance toward ``views`` (V, 3), unit vectors that
    point from the slab to the viewer, z up: views with z < 0 are seen from below, z > 0 from
    above (the estimate for the other side is 0). The sun is toward (sin, 0, cos) of its zenith angle."""
    rng = np.random.default_rng(seed)
    views = np.asarray(views, dtype=np.float64)
    sun_travel = -np.array([np.sqrt(max(1.0 - cos_sun ** 2, 0.0)), 0.0, cos_sun])
    depth = np.zeros(photons)                        # optical depth below the top face
    d = np.tile(sun_travel, (photons, 1))
    alive = np.ones(photons, dtype=bool)
    weight = np.ones(photons)
    per_photon_below = np.zeros((photons, len(views)))
    per_photon_above = np.zeros((photons, len(views)))
    transmitted = np.zeros(photons)
    higher_below = np.zeros((photons, len(views)))
    higher_above = np.zeros((photons, len(views)))
    order = 0
    mu_v = views[:, 2]
    for _ in range(max_orders):
        idx = np.flatnonzero(alive)
        if idx.size == 0:
            break
        step = rng.exponential(size=idx.size)
        depth[idx] -= step * d[idx, 2]               # d_z < 0 goes deeper
        out_bottom = depth[idx] > tau
        out_top = depth[idx] < 0.0
        transmitted[idx[out_bottom]] = weight[idx[out_bottom]]
        alive[idx[out_bottom | out_top]] = False
        hit = idx[~(out_bottom | out_top)]
        if hit.size == 0:
            continue
        cos_dv = d[hit] @ views.T                    # (n, V)
        p = cloud_medium.phase(cos_dv) * albedo * weight[hit, None]
        t = depth[hit, None]
        with np.errstate(divide="ignore", over="ignore"):
            below = np.where(mu_v < 0, np.exp(-(tau - t) / np.abs(mu_v)) / np.abs(mu_v), 0.0)
            above = np.where(mu_v > 0, np.exp(-t / np.abs(mu_v)) / np.abs(mu_v), 0.0)
        per_photon_below[hit] += p * below
        per_photon_above[hit] += p * above
        if order > 0:
            higher_below[hit] += p * below
            higher_above[hit] += p * above
        order += 1
        weight[hit] *= albedo
        d[hit] = _rotate(d[hit], _sample_phase(np.zeros(hit.size), rng), rng)
    scale = cos_sun                                  # photons per unit horizontal area: E mu_0
    b, a = per_photon_below * scale, per_photon_above * scale
    return SlabRadiance(b.mean(0), a.mean(0), b.std(0) / np.sqrt(photons), a.std(0) / np.sqrt(photons),
                        higher_below.mean(0) * scale, higher_above.mean(0) * scale, float(transmitted.mean()))


AZIMUTHS = np.radians(np.linspace(0.0, 180.0, 7))


def higher_order_samples(taus, cos_suns, cos_views, photons: int = 20000, seed: int = 7):
    """(2, n_tau, n_sun, n_view, n_az): the second and higher orders' radiance per unit sun
    irradiance, [0] seen from below, [1] from above, at the AZIMUTHS phi between the line of
    sight (eye to cloud) and the sun."""
    cos_views = np.asarray(cos_views, dtype=np.float64)
    sin_views = np.sqrt(np.maximum(1.0 - cos_views ** 2, 0.0))
    az = np.repeat(AZIMUTHS[None, :], len(cos_views), axis=0)
    # Lines of sight (eye to cloud) at azimuth phi from the sun (toward +x): looking up from
    # below, and looking down from above; the tracer takes the reverse, slab to eye.
    look_up = np.stack([sin_views[:, None] * np.cos(az), sin_views[:, None] * np.sin(az),
                        np.repeat(cos_views[:, None], len(AZIMUTHS), axis=1)], axis=-1).reshape(-1, 3)
    look_down = look_up * np.array([1.0, 1.0, -1.0])
    samples = np.zeros((2, len(taus), len(cos_suns), len(cos_views), len(AZIMUTHS)))
    n = len(look_up)
    for i, tau in enumerate(taus):
        for j, cos_sun in enumerate(cos_suns):
            r = trace(float(tau), float(cos_sun), np.concatenate([-look_up, -look_down]), photons=photons,
                      seed=seed + 1000 * i + j)
            for side, values in enumerate((r.below_higher[:n], r.above_higher[n:])):
                samples[side, i, j] = values.reshape(len(cos_views), -1)
    return samples


def log_cosine_series(values, terms: int, floor: float = 1e-12):
    """(..., terms) least-squares coefficients c of log(values) (..., n_az) at AZIMUTHS in
    cos(k phi), k < terms: values ~ exp(sum c_k cos(k phi)). A series of the values themselves
    rang around the forward glow of thin clouds (the second order's peak toward the sun): with
    three terms 0.87x the tracer toward the sun and 1.18x away from it at optical depth 2; the
    series of the logs stays positive and within 4% there with four."""
    basis = np.stack([np.cos(k * AZIMUTHS) for k in range(terms)], axis=-1)          # (n_az, terms)
    logs = np.log(np.maximum(values, floor))
    return logs @ np.linalg.pinv(basis).T
