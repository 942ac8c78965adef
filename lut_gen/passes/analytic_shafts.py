"""Light shafts under the analytic model (Hoffman & Preetham, lut_gen.model.analytic): the numpy
twin of the analytic "OLS Light Shafts" group (addon/nodes/analytic_shafts.py), by both
techniques, brute-force ray marching and epipolar sampling.

The shadows are found exactly as for the tables: the same march of shadow tests
(lut_gen.passes.aerial.march, its first shadow edge refined) and the same epipolar lit-length
tables (lut_gen.passes.epipolar). Only the air's light differs, and there the model needs no
table: along a pixel's ray the aerial perspective holds air and haze at constant densities (those
of the ray's middle height, analytic.segment_densities), so the in-scattering gathered from the
camera out to distance t is Hoffman & Preetham Eq. 4's closed form

    I(t) = E_sun beta_sc(theta) (1 - exp(-beta t)) / beta,

and the light of a lit section [a, b] of the ray is I(b) - I(a) = E_sun beta_sc exp(-beta a)
(1 - exp(-beta (b - a))) / beta, exact for the model. Summing lit sections is exact too: there
is nothing to tabulate or interpolate.

The sample's single-scattering modes, given their analytic meaning:

- LUT: the closed form over one lit section, from the first lit distance F for the lit length
  L (as the tables' mode takes its look-ups there): I(F + L) - I(F).
- INTEGRATION: the sum of the closed forms of every march step (epipolar: every distance
  interval of the tables) times that step's lit fraction, E_sun beta_sc J with
  J = sum_j lit_j exp(-beta t_j) (1 - exp(-beta dt_j)) / beta: several shafts along one ray
  count each; exact for a sample-and-hold visibility.
- NONE: no single scattering, as for the tables: only the (here absent) higher orders remain.

The model has single scattering only (docs/analytic.md), so the higher orders are 0 and the
three multiple-scattering modes (NONE, OCCLUDED, UNOCCLUDED) give the same light: OCCLUDED's
higher orders over the lit section and UNOCCLUDED's over the whole ray are both 0.

With no occluder every mode but NONE gives I(end), the analytic aerial perspective's own
in-scattering, so the pass equals the unshadowed aerial perspective.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import analytic
from . import aerial, epipolar, jitter, scattering_pass as tables_pass
from .shadow_map import Camera, ShadowCascades, visibility

# exp's argument ceiling, as the node groups keep it (nodes/analytic.py MAX_DEPTH): past it the
# light is 0 either way.
MAX_DEPTH = 80.0
# Rays per slab of the epipolar INTEGRATION table (rays x K x K float64 at once: 16 MB at K = 32).
INTEGRAL_CHUNK = 2048


def reach(beta, length):
    """(1 - exp(-beta s)) / beta per channel (``beta`` (..., 3), ``length`` (...)): the
    distance a segment of length s weighs in Hoffman & Preetham Eq. 4, s itself where beta is 0
    (-expm1 keeps a small beta s accurate)."""
    beta = np.asarray(beta, dtype=np.float64)
    length = np.asarray(length, dtype=np.float64)[..., None]
    safe = np.maximum(beta, analytic.MIN_EXTINCTION)
    return np.where(beta > analytic.MIN_EXTINCTION, -np.expm1(-safe * length) / safe, length)


@dataclass
class RayMedia:
    """A pixel ray's constant-density media: its unit direction and length, extinction beta
    (..., 3, 1/m) and source E_sun beta_sc(theta) (..., 3, per unit E0 and metre), the aerial
    perspective's (analytic.aerial_perspective: densities of the middle height, E_sun at the
    camera)."""
    direction: np.ndarray
    length: np.ndarray
    extinction: np.ndarray
    source: np.ndarray

    @classmethod
    def of(cls, m: analytic.AnalyticMedia, camera, end, sun) -> "RayMedia":
        camera = np.asarray(camera, dtype=np.float64)
        end = np.asarray(end, dtype=np.float64)
        sun = np.asarray(sun, dtype=np.float64)
        ray = end - camera
        length = np.linalg.norm(ray, axis=-1)
        direction = ray / np.maximum(length, 1e-9)[..., None]
        air, haze = analytic.segment_densities(m, camera, end)
        extinction = m.rayleigh * air[..., None] + m.haze_extinction * haze[..., None]
        e_sun = analytic.sun_transmittance(m, sun[2], camera[..., 2])
        source = e_sun * analytic.angular_scattering(m, direction @ sun, air, haze)
        return cls(direction, length, extinction, source)

    def section(self, start, length):
        """(..., 3) the light of the lit section [start, start + length] seen from the camera:
        E_sun beta_sc exp(-beta start) reach(length)."""
        start = np.asarray(start, dtype=np.float64)[..., None]
        return self.source * np.exp(-np.minimum(self.extinction * start, MAX_DEPTH)) * reach(
            self.extinction, length)

    def unshadowed(self):
        """I(end): the analytic aerial perspective's in-scattering per unit E0."""
        return self.source * reach(self.extinction, self.length)


def shadowed(ray: RayMedia, lit_length, first_lit, integral, single_mode: str, multiple_mode: str):
    """(..., 3) the shadowed in-scattering per unit E0 for the modes (module docstring), from
    what the shadow tests found: the lit length, the first lit distance and (INTEGRATION) J
    (..., 3, metres)."""
    aerial.check_modes(single_mode, multiple_mode)
    lit_length = np.asarray(lit_length, dtype=np.float64)
    if single_mode == "LUT":
        return ray.section(first_lit, lit_length) * (lit_length > 0)[..., None]
    if single_mode == "INTEGRATION":
        return ray.source * integral
    return np.zeros(np.shape(lit_length) + (3,))


def step_integral(extinction, starts, widths, lit):
    """J = sum_j lit_j exp(-beta t_j) reach(widths_j) (..., 3): the exact light of sections
    [t_j, t_j + widths_j] held at the lit fractions ``lit`` (..., n), per unit source."""
    beta = np.asarray(extinction, dtype=np.float64)[..., None, :]                  # (..., 1, 3)
    starts = np.asarray(starts, dtype=np.float64)[..., None]
    weights = np.exp(-np.minimum(beta * starts, MAX_DEPTH)) * reach(beta, widths)
    return np.sum(np.asarray(lit, dtype=np.float64)[..., None] * weights, axis=-2)


def light_shafts(m: analytic.AnalyticMedia, camera, end, sun, is_lit, steps: int = 32, single_mode: str = "LUT",
                 multiple_mode: str = "UNOCCLUDED", offsets=None) -> np.ndarray:
    """(..., 3) in-scattering along camera -> end with sun shadows per unit E0, brute force: the
    tables' march (aerial.march, the same samples, offsets and refined edge), the modes in
    closed form."""
    aerial.check_modes(single_mode, multiple_mode)
    camera, end = np.broadcast_arrays(np.asarray(camera, float), np.asarray(end, float))
    sun = np.asarray(sun, dtype=np.float64) / np.linalg.norm(sun)
    marched = aerial.march(camera, end, is_lit, steps, offsets)
    ray = RayMedia.of(m, camera, end, sun)
    integral = None
    if single_mode == "INTEGRATION":
        # The steps' own sections [j, j + 1) x step, whatever the offsets of their samples.
        starts = np.arange(steps) * marched.step[..., None]
        integral = step_integral(ray.extinction, starts, marched.step[..., None], marched.lit)
    return shadowed(ray, marched.lit_length, marched.first_lit, integral, single_mode, multiple_mode)


def epipolar_integral(m: analytic.AnalyticMedia, camera_position, sun):
    """The ``integral`` of lut_gen.passes.epipolar.build_tables under the analytic model: per node
    ray and distance t_k, J(t_k) summed over the intervals before t_k with the extinction of
    the segment camera -> t_k (its middle height), the one a pixel ending there has. The
    source (E_sun, phase, densities) is the pixel's, applied when the table is read.

    Each distance has its own extinction, so this is K x K exponentials a ray: written as
    differences exp(-beta t_j) - exp(-beta t_j+1) over beta (one exponential per node pair,
    channel by channel) it takes 1.2 s for 25 000 rays of 32 distances on the 2-core machine,
    where step_integral's expm1 form took 3.5 s (the float64 differences lose nothing here)."""
    camera = np.asarray(camera_position, dtype=np.float64)

    def integral(directions, t, lit):
        directions = np.asarray(directions, dtype=np.float64)
        n, k = len(directions), len(t)
        widths = np.diff(t)
        before = np.arange(k - 1)[None, :] < np.arange(k)[:, None]                    # (K, K - 1): j < k
        out = np.zeros((n, k, 3))
        for first in range(0, n, INTEGRAL_CHUNK):
            rays = slice(first, first + INTEGRAL_CHUNK)
            ends = camera + directions[rays, None, :] * t[None, :, None]              # (c, K, 3)
            air, haze = analytic.segment_densities(m, camera, ends)
            beta = m.rayleigh * air[..., None] + m.haze_extinction * haze[..., None]     # (c, K, 3)
            held = lit[rays, None, :] * before                                          # (c, K, K - 1)
            plain = (held * widths).sum(axis=-1)                                        # beta = 0: the lit length
            for channel in range(3):
                b = beta[:, :, channel]
                e = np.exp(-np.minimum(b[..., None] * t, MAX_DEPTH))                   # (c, K, K)
                weights = e[..., :-1] - e[..., 1:]
                weights *= held
                thick = b > analytic.MIN_EXTINCTION
                out[rays, :, channel] = np.where(thick, weights.sum(axis=-1) / np.where(thick, b, 1.0), plain)
        return out
    return integral


def build_epipolar_tables(m: analytic.AnalyticMedia, camera: Camera, sun, cascades: ShadowCascades, settings,
                          width: int, height: int):
    """(frame, lit-length tables) of a frame under the analytic model: the tables' epipolar
    march (no clouds: the analytic model has none), its INTEGRATION table from
    epipolar_integral. ``settings``: scene.ols sanitized or a PassSettings. What the add-on
    writes before each frame (addon/scene/frame/epipolar_tables.py) and the twin reads."""
    wanted = epipolar.for_render(epipolar.settings_from(settings), width, height)
    frame = epipolar.frame_for(camera, sun, width, height, float(cascades.far_depths[-1]), wanted)
    integrate = settings.single_scattering_mode == "INTEGRATION"
    tables = epipolar.build_tables(frame, cascades, camera, wanted, settings.smooth_shadows,
                                   settings.best_cascade_search, settings.first_cascade_to_ray_march, None, integrate,
                                   None, epipolar_integral(m, camera.position, frame.sun) if integrate else None)
    return frame, tables


def epipolar_difference(m: analytic.AnalyticMedia, camera: Camera, end, sun, frame, tables, single_mode: str,
                        multiple_mode: str):
    """((..., 3) unshadowed in-scattering, (..., 3) shadowed minus unshadowed) per unit E0 of
    every pixel from the epipolar lit-length tables read at its own depth; the air's light in
    closed form per pixel (no in-scattering tables). Beyond the tables' reach the air is lit,
    as outside every cascade."""
    ray = RayMedia.of(m, camera.position, end, sun)
    lit_length, first_lit, integral = epipolar.look_up(frame, tables, ray.direction, ray.length)
    if integral is not None:
        beyond = np.maximum(ray.length - frame.t_max, 0.0)
        integral = integral + step_integral(ray.extinction, np.minimum(ray.length, frame.t_max)[..., None],
                                            beyond[..., None], np.ones(np.shape(beyond) + (1,)))
    unshadowed = ray.unshadowed()
    return unshadowed, shadowed(ray, lit_length, first_lit, integral, single_mode, multiple_mode) - unshadowed


def scattering_pass(m: analytic.AnalyticMedia, image, position, depth, camera: Camera, sun_direction,
                    cascades: ShadowCascades | None, settings: tables_pass.PassSettings) -> np.ndarray:
    """(H, W, 3) radiance: the analytic "OLS Aerial Perspective" and "OLS Light Shafts" groups as
    Set Up Scene wires them, per pixel (lut_gen.passes.scattering_pass with the analytic model's
    air; arrays (H, W, ...), rows bottom to top). The analytic model ignores the cloud layer."""
    image = np.asarray(image, dtype=np.float64)[..., :3]
    if not settings.enable_light_scattering:
        return image.copy()
    sun, width, height, directions = tables_pass.pixel_rays(image, sun_direction, camera)
    far = cascades.far_depths[-1] if cascades is not None else 1.0
    shafts = settings.enable_light_shafts and cascades is not None
    end, geometry = tables_pass.march_ends(camera, directions, position, depth, far)
    ray = RayMedia.of(m, camera.position, end, sun)
    scale = settings.sun_strength * settings.scattering_scale
    surface = image * np.exp(-np.minimum(ray.extinction * ray.length[..., None], MAX_DEPTH))
    surface = surface * (0.0 if settings.lighting_only else 1.0)
    overlay = None
    unshadowed = ray.unshadowed()
    difference = 0.0
    if shafts and settings.scattering_technique == "EPIPOLAR_SAMPLING":
        frame, tables = build_epipolar_tables(m, camera, sun, cascades, settings, width, height)
        unshadowed, difference = epipolar_difference(m, camera, end, sun, frame, tables,
                                                     settings.single_scattering_mode, settings.multiple_scattering_mode)
        if settings.show_sampling:
            overlay = epipolar.sampling_overlay(frame, tables.marched, camera, width, height)
    elif shafts:
        def is_lit(points):
            return visibility(cascades, points, camera, settings.smooth_shadows, settings.best_cascade_search,
                              settings.first_cascade_to_ray_march)
        offsets = jitter.step_offsets(height, width, settings.jitter_steps)
        difference = light_shafts(m, camera.position, end, sun, is_lit, settings.num_integration_steps,
                                  settings.single_scattering_mode, settings.multiple_scattering_mode,
                                  offsets) - unshadowed
        if settings.jitter_steps:       # the darkening's 3 x 3 mean, as the tables' pass takes it
            difference = jitter.neighbourhood_mean(difference, ray.length)
    share = tables_pass.sky_shadow_share(image, unshadowed * scale, geometry)
    out = np.maximum(np.where(geometry[..., None], surface + unshadowed * scale, image) + difference * scale * share,
                     0.0)
    if settings.show_cascades and cascades is not None:
        out = np.where(geometry[..., None], out * tables_pass.cascade_tint(cascades, end, camera, settings), out)
    if overlay is not None:
        out = np.where(overlay[..., None] > 0.5, tables_pass.sampling_red(out), out)
    return out
