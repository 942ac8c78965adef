"""Aerial perspective and light shafts between a camera and surface points, from the baked
tables: the numpy twin of the (coming) light-scattering compositor pass, and the brute-force
per-pixel reference the epipolar technique will be measured against.

World convention (DESIGN.md): metres, Z up, ground at z = 0, Earth centre at (0, 0, -R).

* ``segment_transmittance``: extinction between two points from the optical-depth table
  (net density to the top from the nearer end minus from the farther end, along the ray, or
  along the reversed ray where the forward one hits the ground).
* ``segment_inscattering``: eq. (8) of seed 000, L(C) - T(C->P) L(P), both look-ups on the
  same side of the horizon seam (Listing 2).
* ``light_shafts``: ray marching through a shadow test with the sample's single-scattering
  modes (none / integration / LUT) and multiple-scattering modes (none / occluded /
  unoccluded).
"""
from __future__ import annotations

import numpy as np

from . import parameterization as par
from .atmosphere import mie_phase, rayleigh_phase
from .sampling import Luts

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


def segment_transmittance(luts: Luts, start, end) -> np.ndarray:
    """(..., 3) transmittance of the atmosphere between ``start`` and ``end``."""
    start, end = np.broadcast_arrays(np.asarray(start, float), np.asarray(end, float))
    direction = end - start
    length = np.linalg.norm(direction, axis=-1, keepdims=True)
    direction = direction / np.maximum(length, 1e-9)
    forward_start, hits_from_start = _net_density(luts, start, direction)
    forward_end, hits_from_end = _net_density(luts, end, direction)
    backward_end, _ = _net_density(luts, end, -direction)
    backward_start, _ = _net_density(luts, start, -direction)
    # Where the forward ray from either end runs into the ground its table entry is the 1e20
    # marker; the reversed ray then gives the difference (near-horizontal segments).
    hits = hits_from_start | hits_from_end
    net = np.where(hits[..., None], backward_end - backward_start, forward_start - forward_end)
    optical_depth = np.maximum(net, 0.0) @ luts.params.extinction_matrix()
    return np.where(length > 1e-6, np.exp(-np.minimum(optical_depth, 80.0)), 1.0)


def _look_up(luts, points, direction, sun, table, above_horizon=None):
    height, up = _frame(luts, points)
    cos_view = np.sum(up * direction, axis=-1)
    cos_sun = np.sum(up * sun, axis=-1)
    cos_sun_view = np.sum(direction * sun, axis=-1)
    if above_horizon is None:
        above_horizon = cos_view > par.cos_horizon(height, luts.params.earth_radius)
    return luts.sky_radiance(height, cos_view, cos_sun, cos_sun_view, table=table,
                             above_horizon=above_horizon).astype(np.float64), above_horizon


def segment_inscattering(luts: Luts, start, end, sun_direction, table: str = "multiple") -> np.ndarray:
    """(..., 3) light scattered toward ``start`` from the segment start -> end, per unit sun."""
    start, end = np.broadcast_arrays(np.asarray(start, float), np.asarray(end, float))
    sun = np.asarray(sun_direction, float) / np.linalg.norm(sun_direction)
    direction = end - start
    direction = direction / np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-9)
    return _eq8(luts, start, end, direction, sun, table, 1.0, segment_transmittance(luts, start, end))


def aerial_perspective(luts: Luts, camera, points, surface_radiance, sun_direction, sun_strength=1.0,
                       scattering_scale=1.0):
    """Surface radiance seen through the air: L_surface T(C->P) + in-scattering (eq. 8)."""
    transmittance = segment_transmittance(luts, camera, points)
    inscatter = segment_inscattering(luts, camera, points, sun_direction)
    return np.asarray(surface_radiance) * transmittance + inscatter * sun_strength * scattering_scale


def light_shafts(luts: Luts, camera, end, sun_direction, is_lit, steps: int = 32,
                 single_mode: str = "LUT", multiple_mode: str = "UNOCCLUDED") -> np.ndarray:
    """(..., 3) in-scattering along camera -> end with sun shadows, per unit sun.

    ``is_lit(points) -> array`` tells how much of the sun reaches world points (the shadow
    map: 0 or 1, or fractions with PCF). The march takes ``steps`` samples at step centres and finds the lit length and the
    distance to the first lit sample (the sample's D_lit, D_start), then applies the modes.
    """
    if single_mode not in SINGLE_MODES or multiple_mode not in MULTIPLE_MODES:
        raise ValueError(f"single_mode in {SINGLE_MODES}, multiple_mode in {MULTIPLE_MODES}")
    camera = np.asarray(camera, float)
    end = np.asarray(end, float)
    camera, end = np.broadcast_arrays(camera, end)
    sun = np.asarray(sun_direction, float) / np.linalg.norm(sun_direction)
    ray = end - camera
    length = np.linalg.norm(ray, axis=-1)
    direction = ray / np.maximum(length, 1e-9)[..., None]
    step = length / steps
    t = (np.arange(steps) + 0.5)[(None,) * length.ndim]                        # (..., steps)
    samples = camera[..., None, :] + direction[..., None, :] * (t * step[..., None])[..., None]
    lit = np.asarray(is_lit(samples), dtype=np.float64)                        # (..., steps)
    lit_length = lit.sum(axis=-1) * step
    any_light = lit > 0.0
    first_lit = np.where(any_light.any(axis=-1), np.argmax(any_light, axis=-1) * step, length)

    result = np.zeros(length.shape + (3,))
    if single_mode == "INTEGRATION":
        height, up = _frame(luts, samples)
        cos_sun = np.sum(up * sun[(None,) * (samples.ndim - 1)], axis=-1)
        sun_trans = luts.transmittance_to_top(height, cos_sun)
        view_trans = segment_transmittance(luts, camera[..., None, :], samples)
        rho = np.stack([np.exp(-np.maximum(height, 0) / luts.params.rayleigh_scale_height),
                        np.exp(-np.maximum(height, 0) / luts.params.mie_scale_height)], axis=-1)
        cos_theta = np.sum(direction * sun, axis=-1)[..., None, None]
        scatter = (luts.params.rayleigh * rho[..., :1] * rayleigh_phase(cos_theta)
                   + luts.params.mie * rho[..., 1:] * mie_phase(cos_theta, luts.params.mie_g))
        result += np.sum(scatter * view_trans * sun_trans * lit[..., None], axis=-2) * step[..., None]
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
    """Eq. (8) for the lit section start -> end seen from the camera."""
    return _eq8(luts, start, end, direction, sun, table, segment_transmittance(luts, camera, start),
                segment_transmittance(luts, camera, end))


def _eq8(luts, start, end, direction, sun, table, start_transmittance, end_transmittance):
    """T_start L(start) - T_end L(end), both look-ups on the side of the horizon seam the first
    one chose (Listing 2)."""
    near, above = _look_up(luts, start, direction, sun, table)
    far, _ = _look_up(luts, end, direction, sun, table, above_horizon=above)
    return np.maximum(start_transmittance * near - end_transmittance * far, 0.0)
