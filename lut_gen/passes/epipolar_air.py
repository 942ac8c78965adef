"""The air's in-scattering along the epipolar table rays: what lets the epipolar technique
apply the sample's scattering modes with texture fetches instead of per-pixel Yusov 2013 eq. (8).

Yusov 2013 eq. (8) for a lit section a -> b of a view ray seen from the camera C is
    T(C->a) S(a) - T(C->b) S(b) = I(b) - I(a),   I(t) = S(C) - T(C->X_t) S(X_t),
the in-scattering gathered from the camera out to distance t. So each mode needs I at three
distances of the pixel's ray (the first lit distance F, F + lit length, the ray's end), and
the shadowed minus the unshadowed in-scattering the pass adds is

    single LUT:        [I_s(F + L) - I_s(F)] - I_s(end)
    multiple OCCLUDED: [I_h(F + L) - I_h(F)] - I_h(end)     (NONE: - I_h(end); UNOCCLUDED: 0)
    single INTEGRATION: the marched integral - I_s(end);    NONE: - I_s(end)

(UNOCCLUDED's higher orders cancel against the unshadowed pass's.) With no occluders
(F = 0, L = end) the difference is exactly 0, and in full shadow only the multiple
scattering's share stays, as for brute force. The aerial perspective's own in-scattering
I_s(end) + I_h(end) comes from the same tables, so the pass evaluates no Yusov 2013 eq. (8) per
pixel at all (the epipolar technique of Intel 2012 interpolates all of its in-scattering too).

Before each frame numpy evaluates I at the nodes of a coarser grid of the same (phi, theta)
parametrisation as the lit-length tables (lut_gen.passes.epipolar) and a geometric distance grid out
to the camera's reach. The phase functions are divided out at each node (they are constant
along a ray) and applied per pixel, so the Mie peak around the sun is exact and what is
interpolated across directions varies slowly: Rayleigh single scattering / P_R, single Mie
scattering / P_M, the fog's / P_F and the higher orders / P_R, as the 4D tables store them
(lut_gen.tables.lookup).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from . import aerial
from ..model.atmosphere import mie_phase, rayleigh_phase
from .epipolar import MIN_NEAR, EpipolarFrame, corner_cosine, look_up, trilinear
from ..tables.lookup import Luts
from .shadow_map import Camera

AIR_SLICES = 64             # directions of the in-scattering grid at most (it varies slowly with direction)
AIR_SAMPLES = 32
AIR_DISTANCES = 32          # geometric from MIN_NEAR to the reach
MAX_REACH = 400e3           # m: a camera with no clip end sees no farther than this through the air


@dataclass
class AirTables:
    """Per grid node (slices + 1, samples) and distance: I / phase for the Rayleigh and the
    Mie single scattering and the higher orders, and the fog's single scattering (None
    without fog)."""
    rayleigh: np.ndarray
    mie: np.ndarray
    higher: np.ndarray
    fog: np.ndarray = None


def air_dims(slices: int, samples: int):
    """(slices, samples, distances) of the in-scattering grid for lit-length tables of
    ``slices`` x ``samples``."""
    return min(slices, AIR_SLICES), min(samples, AIR_SAMPLES), AIR_DISTANCES


def air_frame(frame: EpipolarFrame, camera: Camera) -> EpipolarFrame:
    """The in-scattering grid of ``frame``: the same angles, at most AIR_SLICES x AIR_SAMPLES
    directions, and distances out to what the camera can see (its clip end at the screen's
    corner), at least the lit-length tables' reach."""
    reach = max(frame.t_max, min(float(camera.clip_end), MAX_REACH) / corner_cosine(camera))
    slices, samples, distances = air_dims(frame.slices, frame.samples)
    return dataclasses.replace(frame, slices=slices, samples=samples, steps=distances, t_max=reach,
                               growth=reach / MIN_NEAR)


def _above_ground(luts: Luts, camera, directions, t):
    """((..., K, 3), (..., K) bool): ``directions`` raised in their vertical plane where needed
    (the mask says where), so that each reaches distance ``t`` (K,) in the air: a ray that
    would hit the ground sooner is replaced by the one that meets the ground at t. A pixel's
    ray never runs on under the ground, and
    the pixel on the ground at distance t near the ground's horizon is that very ray: so the
    nodes around it hold the air a pixel there sees (clamping I at each node's own ground hit
    instead left a haze band 12-16% too dark along a plain's horizon)."""
    radius = luts.params.earth_radius
    centre = camera + np.array([0.0, 0.0, radius])
    r = np.linalg.norm(centre, axis=-1)                                        # (..., 1)
    up = centre / r[..., None]
    cos_zenith = np.sum(up * directions, axis=-1)                              # (..., 1)
    t = np.asarray(t, dtype=np.float64)
    # Zenith cosine of the ray from radius r that meets the ground (radius R) at distance t.
    meets_at_t = (radius * radius - r * r - t * t) / (2.0 * r * np.maximum(t, 1e-9))
    raised = np.maximum(cos_zenith, np.minimum(meets_at_t, 1.0))              # (..., K)
    lifted = raised > cos_zenith
    return np.where(lifted[..., None], aerial._tilted(up, directions, raised), directions), lifted


def build(luts: Luts, frame: EpipolarFrame, camera_position, needed=None) -> AirTables:
    """I / phase at the nodes of ``frame`` (an air_frame) seen from ``camera_position``;
    ``needed`` ((S+1, N) bool, lut_gen.passes.epipolar.screen_nodes): only those nodes, the
    others 0."""
    nodes = frame.node_directions()[:, :, None, :]                         # (S+1, N, 1, 3)
    camera = np.broadcast_to(np.asarray(camera_position, dtype=np.float64), nodes.shape)
    t = frame.distances()
    directions, lifted = _above_ground(luts, camera, nodes, t)             # (S+1, N, K, 3), (S+1, N, K)
    # Rays no distance raises keep one direction: their start look-ups are made once, not per
    # distance (a third of the tables' time; the sky's half of a frame has no raised ray).
    straight = ~lifted.any(axis=-1)                                        # (S+1, N)
    built = np.ones(straight.shape, dtype=bool) if needed is None else needed
    names = ("single", "single_mie", "higher") + (() if luts.single_fog is None else ("single_fog",))
    radiances = [np.zeros(directions.shape, dtype=np.float32) for _ in names]
    for rays, ray_directions in ((straight & built, nodes), (~straight & built, directions)):
        if not rays.any():
            continue
        start, direction = camera[rays], ray_directions[rays]              # (m, 1, 3), (m, 1 or K, 3)
        points = start + direction * t[:, None]
        transmittance = aerial.segment_transmittance(luts, start, points, direction)
        # The three tables at the same points: one set of look-up coordinates and corners.
        found = aerial.section_inscattering(luts, start, points, direction, frame.sun, names, 1.0, transmittance,
                                            phase_free=True)
        for radiance, part in zip(radiances, found):
            radiance[rays] = part
    for radiance in radiances:
        # I(0) = 0: Yusov 2013 eq. 8's clamp and float error leave a trace there.
        radiance[:, :, 0] = 0.0
    return AirTables(*radiances)


def inscattering(luts: Luts, frame: EpipolarFrame, tables: AirTables, part: str, direction, distance) -> np.ndarray:
    """(..., 3) I(distance) per unit sun along pixel rays ``direction`` for ``part`` "single"
    or "higher", the phase functions applied at the pixel's own angle from the sun."""
    cos_theta = np.sum(direction * frame.sun, axis=-1)
    p_r = rayleigh_phase(cos_theta)[..., None]
    if part == "higher":
        return p_r * trilinear(frame, tables.higher, direction, distance)
    p_m = mie_phase(cos_theta, luts.params.mie_g)[..., None]
    single = p_r * trilinear(frame, tables.rayleigh, direction, distance) + p_m * trilinear(frame, tables.mie,
                                                                                        direction, distance)
    if tables.fog is not None:
        single = single + mie_phase(cos_theta, luts.params.fog_g)[..., None] * trilinear(frame, tables.fog, direction,
                                                                                         distance)
    return single


def table_uses(single_mode: str, multiple_mode: str) -> dict:
    """{"single": [(distance, sign)], "higher": [...]}: the I(distance) terms whose sum is the
    shadowed minus unshadowed in-scattering for the modes (module docstring); distances are
    "end" (the ray's), "first" (first lit) and "lit_end" (first lit + lit length). Without a
    lit part the lit end is the first lit distance and the section is 0."""
    aerial.check_modes(single_mode, multiple_mode)
    section = [("lit_end", 1.0), ("first", -1.0)]
    single = [("end", -1.0)] + (section if single_mode == "LUT" else [])
    higher = {"OCCLUDED": section + [("end", -1.0)], "NONE": [("end", -1.0)]}.get(multiple_mode, [])
    return {"single": single, "higher": higher}


def shadow_difference(luts: Luts, frame: EpipolarFrame, tables: AirTables, direction, length, lit_length,
                      first_lit, integrated, single_mode: str, multiple_mode: str) -> np.ndarray:
    """(..., 3) shadowed minus unshadowed in-scattering per unit sun of pixel rays
    ``direction`` of ``length``, from what the lit-length tables found (module docstring)."""
    distances = {"end": length, "first": first_lit, "lit_end": first_lit + lit_length}
    difference = 0.0
    for part, uses in table_uses(single_mode, multiple_mode).items():
        for name, sign in uses:
            difference = difference + sign * inscattering(luts, frame, tables, part, direction, distances[name])
    if single_mode == "INTEGRATION":
        difference = difference + integrated
    return difference


def light_shaft_difference(luts: Luts, camera: Camera, end, frame: EpipolarFrame, lit_tables, air: EpipolarFrame,
                           air_tables: AirTables, single_mode: str = "LUT", multiple_mode: str = "UNOCCLUDED"):
    """((..., 3) unshadowed in-scattering along camera -> end per unit sun, (..., 3) shadowed
    minus unshadowed): the aerial perspective's in-scattering and the light shafts, both from
    the tables: the lit-length tables (lut_gen.passes.epipolar.build_tables on ``frame``) read at each
    pixel's own depth, the in-scattering tables (``build`` on ``air``)."""
    ray = np.asarray(end, dtype=np.float64) - camera.position
    length = np.linalg.norm(ray, axis=-1)
    direction = ray / np.maximum(length, 1e-9)[..., None]
    lit_length, first_lit, integrated = look_up(frame, lit_tables, direction, length)
    unshadowed = sum(inscattering(luts, air, air_tables, part, direction, length) for part in ("single", "higher"))
    return unshadowed, shadow_difference(luts, air, air_tables, direction, length, lit_length, first_lit, integrated,
                                         single_mode, multiple_mode)
