"""Aerial perspective and light shafts between a camera and surface points, from the baked
tables: the numpy twin of the aerial-perspective and light-shaft compositor groups
(addon/nodes/aerial.py, addon/nodes/light_shafts.py), and the brute-force per-pixel reference
the epipolar technique is measured against.

World convention (docs/design.md): metres, Z up, ground at z = 0, Earth centre at (0, 0, -R).

* ``segment_transmittance``: extinction between two points from the optical-depth table
  (net density to the top from the nearer end minus from the farther end, along the ray, or
  along the reversed ray where the forward one hits the ground).
* ``segment_inscattering``: eq. (8) of Yusov 2013, L(C) - T(C->P) L(P), both look-ups on the
  same side of the horizon seam (Yusov 2013 Listing 2).
* ``light_shafts``: ray marching through a shadow test with the sample's single-scattering
  modes (none / integration / LUT) and multiple-scattering modes (none / occluded /
  unoccluded).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..tables import parameterization as par
from ..model.profiles import densities
from ..model.atmosphere import mie_phase, rayleigh_phase
from ..tables.lookup import Luts
from . import shaft_boundary

SINGLE_MODES = ("NONE", "INTEGRATION", "LUT")
MULTIPLE_MODES = ("NONE", "OCCLUDED", "UNOCCLUDED")


def _frame(luts: Luts, points):
    """Height, local up and distance to the centre of world points (..., 3)."""
    from_centre = np.asarray(points, dtype=np.float64) + np.array([0.0, 0.0, luts.params.earth_radius])
    radius = np.linalg.norm(from_centre, axis=-1)
    return radius - luts.params.earth_radius, from_centre / radius[..., None]


def _net_density(luts, points, direction):
    height, up = _frame(luts, points)
    cos_zenith = np.sum(up * direction, axis=-1)
    hits = cos_zenith < par.cos_horizon(height, luts.params.earth_radius)
    return luts.net_density_to_top(height, cos_zenith).astype(np.float64), hits


GAUSS_NODES, GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(8)
# Distance of the table ray to its horizon (in zenith cosine) below which the difference of
# table net densities gives way to quadrature along the segment (blended in between).
QUADRATURE_BAND = (0.004, 0.012)


def _horizon_distance(luts, points, direction):
    height, up = _frame(luts, points)
    return np.sum(up * direction, axis=-1) - par.cos_horizon(height, luts.params.earth_radius)


def quadrature_net_density(params, start, end) -> np.ndarray:
    """(..., 3) Rayleigh / Mie / ozone net densities along the segment start -> end
    (8-point Gauss-Legendre)."""
    t = 0.5 * (GAUSS_NODES + 1.0)
    points = start[..., None, :] + (end - start)[..., None, :] * t[:, None]
    radius = np.linalg.norm(points + np.array([0.0, 0.0, params.earth_radius]), axis=-1)
    density = densities(params, radius - params.earth_radius)
    length = np.linalg.norm(end - start, axis=-1)
    return np.sum(density * GAUSS_WEIGHTS[:, None], axis=-2) * (0.5 * length)[..., None]


def segment_transmittance(luts: Luts, start, end, direction=None) -> np.ndarray:
    """(..., 3) transmittance of the atmosphere between ``start`` and ``end``. ``direction``:
    the unit direction from start to end where the caller has it (as the node group takes it),
    broadcastable; the start's look-ups are then made once per start and direction (the
    epipolar in-scattering tables' rays share one per ray, not one per distance)."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = np.linalg.norm(end - start, axis=-1, keepdims=True)
    if direction is None:
        start, end = np.broadcast_arrays(start, end)
        direction = (end - start) / np.maximum(length, 1e-9)
        forward_start, hits_from_start = _net_density(luts, start, direction)
        backward_start, _ = _net_density(luts, start, -direction)
        start_horizon = _horizon_distance(luts, start, direction)
    else:
        direction = np.asarray(direction, float)
        shape = np.broadcast_shapes(start.shape, end.shape, direction.shape)
        forward_start, hits_from_start = _net_density(luts, start, direction)
        backward_start, _ = _net_density(luts, start, -direction)
        forward_start, backward_start = (np.broadcast_to(v, shape[:-1] + v.shape[-1:])
                                         for v in (forward_start, backward_start))
        hits_from_start, start_horizon = (np.broadcast_to(v, shape[:-1]) for v in
                                          (hits_from_start, _horizon_distance(luts, start, direction)))
        start, end, direction = (np.broadcast_to(v, shape) for v in (start, end, direction))
        length = np.broadcast_to(length, shape[:-1] + (1,))
    forward_end, hits_from_end = _net_density(luts, end, direction)
    backward_end, _ = _net_density(luts, end, -direction)
    # Where the forward ray from either end runs into the ground its table entry is the 1e20
    # marker; the reversed ray then gives the difference (near-horizontal segments).
    hits = hits_from_start | hits_from_end
    net = np.where(hits[..., None], backward_end - backward_start, forward_start - forward_end)
    # The difference of two large net densities is ill-conditioned for rays that graze the
    # horizon (the table changes fastest there): integrate along the segment instead.
    horizon = np.where(hits, _horizon_distance(luts, end, -direction), start_horizon)
    weight = _smoothstep(*QUADRATURE_BAND, horizon)
    near_horizon = weight < 1.0                 # quadrature only where it counts (few segments)
    if near_horizon.any():
        quadrature = quadrature_net_density(luts.params, start[near_horizon], end[near_horizon])
        net[near_horizon] = quadrature + (net[near_horizon] - quadrature) * weight[near_horizon][:, None]
    optical_depth = np.maximum(net, 0.0) @ luts.params.extinction_matrix()
    return np.where(length > 1e-6, np.exp(-np.minimum(optical_depth, 80.0)), 1.0)


def _smoothstep(low, high, x):
    t = np.clip((x - low) / (high - low), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _look_up(luts, points, direction, sun, table, above_horizon=None, phase_free=False):
    height, up = _frame(luts, points)
    cos_view = np.sum(up * direction, axis=-1)
    cos_sun = np.sum(up * sun, axis=-1)
    cos_sun_view = np.sum(direction * sun, axis=-1)
    if above_horizon is None:
        above_horizon = cos_view > par.cos_horizon(height, luts.params.earth_radius)
    radiance = luts.sky_radiance(height, cos_view, cos_sun, cos_sun_view, table=table, above_horizon=above_horizon,
                                 phase_free=phase_free)
    if isinstance(table, tuple):
        return tuple(r.astype(np.float64) for r in radiance), above_horizon
    return radiance.astype(np.float64), above_horizon


def segment_inscattering(luts: Luts, start, end, sun_direction, table: str = "multiple") -> np.ndarray:
    """(..., 3) light scattered toward ``start`` from the segment start -> end, per unit sun."""
    start, end = np.broadcast_arrays(np.asarray(start, float), np.asarray(end, float))
    sun = np.asarray(sun_direction, float) / np.linalg.norm(sun_direction)
    direction = end - start
    direction = direction / np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-9)
    return section_inscattering(luts, start, end, direction, sun, table, 1.0, segment_transmittance(luts, start, end))


def aerial_perspective(luts: Luts, camera, points, surface_radiance, sun_direction, sun_strength=1.0,
                       scattering_scale=1.0):
    """Surface radiance seen through the air: L_surface T(C->P) + in-scattering
    (Yusov 2013 eq. 8)."""
    transmittance = segment_transmittance(luts, camera, points)
    inscatter = segment_inscattering(luts, camera, points, sun_direction)
    return np.asarray(surface_radiance) * transmittance + inscatter * sun_strength * scattering_scale


def light_shafts(luts: Luts, camera, end, sun_direction, is_lit, steps: int = 32,
                 single_mode: str = "LUT", multiple_mode: str = "UNOCCLUDED", offsets=None) -> np.ndarray:
    """(..., 3) in-scattering along camera -> end with sun shadows, per unit sun.

    ``is_lit(points) -> array`` tells how much of the sun reaches world points (the shadow
    map: 0 or 1, or fractions with PCF). The march (``march``) takes ``steps`` samples, at the
    step centres or at ``offsets`` (..., in [0, 1): lut_gen.passes.jitter) within each step, and
    finds the lit length and the distance to the first lit sample (the sample's D_lit,
    D_start), its first shadow edge refined between samples (lut_gen.passes.shaft_boundary),
    then applies the modes.
    """
    check_modes(single_mode, multiple_mode)
    camera, end = np.broadcast_arrays(np.asarray(camera, float), np.asarray(end, float))
    sun = np.asarray(sun_direction, float) / np.linalg.norm(sun_direction)
    marched = march(camera, end, is_lit, steps, offsets)
    integrated = None
    if single_mode == "INTEGRATION":
        integrated = np.sum(integration_terms(luts, camera, marched.direction, marched.samples,
                                              marched.step[..., None], sun) * marched.lit[..., None], axis=-2)
    return apply_modes(luts, camera, end, sun, marched.lit_length, marched.first_lit, integrated, single_mode,
                       multiple_mode)


@dataclass
class March:
    """What a brute-force march of pixel rays found (``march``): per ray its unit direction,
    step length, sample points (..., steps, 3) and their lit fractions (..., steps), the lit
    length and the first lit distance (first shadow edge refined)."""
    direction: np.ndarray
    step: np.ndarray
    samples: np.ndarray
    lit: np.ndarray
    lit_length: np.ndarray
    first_lit: np.ndarray


def march(camera, end, is_lit, steps: int, offsets=None) -> March:
    """The shadow tests of light_shafts, whatever the atmosphere: the analytic model's shafts
    (lut_gen.passes.analytic_shafts) march the same samples and refine the same edge."""
    camera, end = np.broadcast_arrays(np.asarray(camera, float), np.asarray(end, float))
    ray = end - camera
    length = np.linalg.norm(ray, axis=-1)
    direction = ray / np.maximum(length, 1e-9)[..., None]
    step = length / steps
    offsets = np.broadcast_to(0.5 if offsets is None else np.asarray(offsets, dtype=np.float64), length.shape)
    t = np.arange(steps) + offsets[..., None]                                  # (..., steps)
    samples = camera[..., None, :] + direction[..., None, :] * (t * step[..., None])[..., None]
    lit = np.asarray(is_lit(samples), dtype=np.float64)                        # (..., steps)
    lit_length = lit.sum(axis=-1) * step
    any_light = lit >= shaft_boundary.LIT_FLOOR
    first_lit = np.where(any_light.any(axis=-1), np.argmax(any_light, axis=-1) * step, length)
    # The first shadow edge, placed between its two samples (lut_gen.passes.shaft_boundary).
    k, before, after = shaft_boundary.first_transition(lit)
    crossed = k < steps
    edge = shaft_boundary.refine(is_lit, camera, direction, (k - 1 + offsets) * step, (k + offsets) * step, before,
                                 after)
    lit_length = lit_length + np.where(crossed, (before - after) * (edge - k * step), 0.0)
    first_lit = np.where(crossed & (lit[..., 0] < shaft_boundary.HALF), edge, first_lit)
    return March(direction, step, samples, lit, lit_length, first_lit)


def check_modes(single_mode, multiple_mode):
    if single_mode not in SINGLE_MODES or multiple_mode not in MULTIPLE_MODES:
        raise ValueError(f"single_mode in {SINGLE_MODES}, multiple_mode in {MULTIPLE_MODES}")


def integration_terms(luts: Luts, camera, direction, samples, steps, sun) -> np.ndarray:
    """(..., n, 3) single scattering of each march step toward the camera, unshadowed:
    sigma_s P(theta) T(C->X) T_sun(X) x step (the sample's "Singl sctr: integration"), with the
    extinction from the camera accumulated step by step (midpoint rule). ``samples`` (..., n, 3)
    are the step centres in order from the camera, ``steps`` (..., n) their lengths."""
    height, up = _frame(luts, samples)
    cos_sun = np.sum(up * sun[(None,) * (samples.ndim - 1)], axis=-1)
    sun_trans = luts.transmittance_to_top(height, cos_sun)
    step_density = densities(luts.params, height) * np.asarray(steps)[..., None]
    before = np.cumsum(step_density, axis=-2) - step_density
    view_trans = np.exp(-np.minimum((before + 0.5 * step_density) @ luts.params.extinction_matrix(), 80.0))
    rho = np.stack([np.exp(-np.maximum(height, 0) / luts.params.rayleigh_scale_height),
                    np.exp(-np.maximum(height, 0) / luts.params.mie_scale_height)], axis=-1)
    cos_theta = np.sum(direction * sun, axis=-1)[..., None, None]
    scatter = (luts.params.rayleigh * rho[..., :1] * rayleigh_phase(cos_theta)
               + luts.params.mie * rho[..., 1:] * mie_phase(cos_theta, luts.params.mie_g))
    if luts.params.has_fog:     # grey and non-absorbing: its scattering is its extinction
        rho_fog = np.exp(-np.maximum(height, 0) / luts.params.fog_height)[..., None]
        scatter = scatter + luts.params.fog * rho_fog * mie_phase(cos_theta, luts.params.fog_g)
    return scatter * view_trans * sun_trans * np.asarray(steps)[..., None]


def apply_modes(luts: Luts, camera, end, sun, lit_length, first_lit, integrated, single_mode: str,
                multiple_mode: str) -> np.ndarray:
    """(..., 3) in-scattering along camera -> end from what a march found: the lit length, the
    distance to the first lit point and (INTEGRATION) the integrated single scattering, with the
    sample's single- and multiple-scattering modes."""
    ray = end - camera
    direction = ray / np.maximum(np.linalg.norm(ray, axis=-1), 1e-9)[..., None]
    result = np.zeros(np.shape(lit_length) + (3,))
    if single_mode == "INTEGRATION":
        result += integrated
    lit_start = camera + direction * first_lit[..., None]
    lit_end = lit_start + direction * lit_length[..., None]
    has_lit = (lit_length > 0)[..., None]
    if single_mode == "LUT":
        table = "multiple" if multiple_mode == "OCCLUDED" else "single"
        result += has_lit * _section(luts, camera, lit_start, lit_end, direction, sun, table)
    if multiple_mode == "OCCLUDED" and single_mode != "LUT":
        result += has_lit * _section(luts, camera, lit_start, lit_end, direction, sun, "higher")
    if multiple_mode == "UNOCCLUDED":
        result += segment_inscattering(luts, camera, end, sun, table="higher")
    return result


def _section(luts, camera, start, end, direction, sun, table):
    """Yusov 2013 eq. (8) for the lit section start -> end seen from the camera."""
    return section_inscattering(luts, start, end, direction, sun, table, segment_transmittance(luts, camera, start),
                                segment_transmittance(luts, camera, end))


HORIZON_BLEND = 0.004      # zenith-cosine half width of Bruneton's blend across the horizon seam ...
HORIZON_BLEND_HEIGHT = 20.0  # ... narrowed so the tilted rays end at most this many metres off


def uses_horizon_blend(params) -> bool:
    """Whether Yusov 2013 eq. (8) blends across the horizon seam: not in fog. There the tilted rays
    differ physically (from 2 m up the lower one meets the ground 400 m out), and the tables' two
    halves agree without it: single scattering to the ground 0.1-5 km from a camera 2 m up in a 1 km
    / 50 m and a 300 m / 20 m fog, sun 20 deg, was 0.90-1.02x of brute force blended, 1.00-1.02x
    without (tilted rays ending 5 m or 1 m off: 0.93-1.07x, 1.00-1.12x)."""
    return not params.has_fog


def section_inscattering(luts, start, end, direction, sun, table, start_transmittance, end_transmittance, phase_free=False):
    """T_start L(start) - T_end L(end), both look-ups on the side of the horizon seam the first one
    chose (Yusov 2013 Listing 2). Within HORIZON_BLEND of the start's horizon the two sides of the
    seam disagree by the tables' interpolation error (about 15% near the ground), which draws a step
    along the horizon: there, as in Bruneton's reference implementation, Yusov 2013 eq. (8) is taken
    along the rays HORIZON_BLEND below and above the horizon (same length) and blended. The band
    narrows for long sections so the tilted rays end within HORIZON_BLEND_HEIGHT of the true end
    (measured: the step drops from 5-22% to 0.1-5%, the error against brute force stays 2.5% p90);
    not in fog (uses_horizon_blend).
    ``start`` and ``direction`` may have a size-1 axis that ``end`` spans (many distances
    along one ray: the start's look-up is made once); ``phase_free`` as Luts.sky_radiance, and
    then ``table`` may be a tuple of names: a tuple of results, from shared look-ups."""
    results = _section_inscattering_each(luts, start, end, direction, sun, table, start_transmittance,
                                         end_transmittance, phase_free)
    return results if isinstance(table, tuple) else results[0]


def _section_inscattering_each(luts, start, end, direction, sun, table, start_transmittance, end_transmittance, phase_free):
    """section_inscattering of each table of ``table`` (a name or a tuple of names), as a tuple."""
    several = isinstance(table, tuple)

    def look_up(*args, **kwargs):
        radiance, above = _look_up(luts, *args, table=table, phase_free=phase_free, **kwargs)
        return (radiance if several else (radiance,)), above

    nears, above = look_up(start, direction, sun)
    fars, _ = look_up(end, direction, sun, above_horizon=above)
    plains = [np.maximum(start_transmittance * near - end_transmittance * far, 0.0) for near, far in zip(nears, fars)]
    plain = plains[0]
    height, up = _frame(luts, start)
    offset = np.sum(up * direction, axis=-1) - par.cos_horizon(height, luts.params.earth_radius)
    length = np.linalg.norm(end - start, axis=-1)
    half_width = np.minimum(HORIZON_BLEND, HORIZON_BLEND_HEIGHT / np.maximum(length, 1e-9))
    band = np.broadcast_to(np.abs(offset) < half_width, plain.shape[:-1])
    if not uses_horizon_blend(luts.params) or not band.any():
        return tuple(plains)

    def in_band(x, channels=()):
        """The band's elements of ``x`` broadcast to the result's shape (the look-ups run on
        those alone)."""
        return np.broadcast_to(np.asarray(x, dtype=np.float64), plain.shape[:-1] + channels)[band]

    up_b, start_b = in_band(up, (3,)), in_band(start, (3,))
    direction_b, length_b = in_band(direction, (3,)), in_band(length)
    offset_b, half_b = in_band(offset), in_band(half_width)
    horizon_b = in_band(par.cos_horizon(height, luts.params.earth_radius))
    start_t, end_t = in_band(start_transmittance, (3,)), in_band(end_transmittance, (3,))
    sides = []                          # per side of the seam, per table
    for side in (-1.0, 1.0):
        tilted = _tilted(up_b, direction_b, horizon_b + side * half_b)
        tilted_end = start_b + tilted * length_b[..., None]
        flag = np.full(offset_b.shape, side > 0)
        nears, _ = look_up(start_b, tilted, sun, above_horizon=flag)
        fars, _ = look_up(tilted_end, tilted, sun, above_horizon=flag)
        sides.append([np.maximum(start_t * near - end_t * far, 0.0) for near, far in zip(nears, fars)])
    weight = np.clip((offset_b + half_b) / (2.0 * half_b), 0.0, 1.0)[..., None]
    results = []
    for plain, below, above_side in zip(plains, *sides):
        result = plain.copy()
        result[band] = below + (above_side - below) * weight
        results.append(result)
    return tuple(results)


def _tilted(up, direction, cos_zenith):
    """``direction`` turned in its vertical plane to the zenith cosine ``cos_zenith``."""
    cos_zenith = np.asarray(cos_zenith)[..., None]
    level = direction - up * np.sum(up * direction, axis=-1, keepdims=True)
    level = level / np.maximum(np.linalg.norm(level, axis=-1, keepdims=True), 1e-12)
    return up * cos_zenith + level * np.sqrt(np.maximum(1.0 - cos_zenith * cos_zenith, 0.0))
