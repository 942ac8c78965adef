"""The air under the cloud layer in the world's sky: the clouds' shade on it and their light in
it, as a mean field.

sky.composite takes the air between a camera under the layer and the cloud it sees as the clear
sky's (S - T S_P, from the tables). Under a cloud deck that air lies in the clouds' shadow: the
haze's forward glow toward a low sun, lit by a sun the deck hides, came out 20x too bright
against the Monte Carlo tracer (tests/numpy_only/test_cloud_monte_carlo.py). Here that air's
light is remade from three parts, per view direction:
- its single scattering (the tables' "single") times the sun's mean transmittance through the
  layer, ``sun_through``: exp(-tau / mu_s) averaged over the map's columns;
- its higher orders (the tables' "higher") times the same factor: they are the clear sky's
  light scattered on, and the sun that feeds them is shaded alike;
- the light of the clouds themselves scattered by that air toward the camera, ``cloud_glow``:
  the cloud base's mean diffuse light from above (the two-stream fluxes a column lets through),
  the ground's reflection of it from below, and what goes back and forth between the two,
  integrated along the ray with the air's scattering, its phase functions split between the
  upper and the lower hemisphere.
The mean is over the map's columns, so a coverage-0 layer changes nothing and a full deck
shades the air everywhere; where one gap or one cloud falls is the light shafts' business
(shafts.py), which march the cloud's shadow step by step.

Seen from above the layer the air is sunlit as the tables have it, but over the bright deck, not
over the ground of the atmosphere's albedo: it scatters the deck's light beyond the ground's
(top_light.deck_light), a negative ``Shade.rest``.

The result is what the world must take off: ``Shade.single`` (the single-scattering part within
the light shafts' reach, SHAFT_RANGE) and ``Shade.rest`` (all the rest, less the clouds' glow).
With light shafts on, camera rays take off ``rest`` only: the shafts pass replaces the air's
single scattering within its reach with its march, which has the cloud's shadow in every step.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..model.atmosphere import mie_phase, rayleigh_phase
from ..model.profiles import densities
from ..passes import aerial
from ..tables.lookup import Luts
from . import field, slab, top_light
from .layer import CloudLayer

GLOW_STEPS = 48             # quadrature points along a ray, camera -> cloud
PHASE_NODES = 512           # Gauss-Legendre nodes in the scattering angle's cosine


@dataclass
class Shade:
    single: np.ndarray      # (..., 3) per unit sun
    rest: np.ndarray        # (..., 3) per unit sun


def sun_through(layer: CloudLayer, cos_sun: float) -> float:
    """The sun's mean transmittance through the layer, exp(-tau / mu_s) over the columns (as
    shadow.ground_transmittance per column); 1 with the sun below the horizon (its light then
    reaches the air under the layer beneath it)."""
    if cos_sun <= 0:
        return 1.0
    full = layer.density * layer.thickness
    return float(field.column_mean(layer.coverage, lambda f: np.exp(-full * f / max(cos_sun, slab.MIN_COS))))


@dataclass
class Glow:
    above: np.ndarray       # (3,) mean radiance of the cloud base, per unit sun
    below: np.ndarray       # (3,) the ground's radiance from the clouds' light, per unit sun
    ground: np.ndarray      # (3,) the ground's whole radiance under the layer, per unit sun


def glow_sources(luts: Luts, layer: CloudLayer, cos_sun: float) -> Glow:
    """The cloud base's mean diffuse light and the ground's share of it, with the light that
    goes back and forth between the two (ground albedo rho, the base's diffuse reflectance r):
    E_ground = (E_clear + E_base) / (1 - rho r), E_clear the sun through the layer and the
    shaded clear sky, which the tables already count."""
    params = luts.params
    full = layer.density * layer.thickness
    mu_s = max(cos_sun, 0.0)
    top_sun = luts.transmittance_to_top(layer.base + layer.thickness, np.array(cos_sun)) * mu_s
    sky = top_light.skylight(luts, layer, np.array(cos_sun))

    def fluxes(fraction):
        tau = full * fraction
        _, through_sun = slab.two_stream(tau, max(mu_s, slab.MIN_COS))
        back, through_sky = slab.diffuse_two_stream(tau)
        return np.array([through_sun, through_sky, back])

    through_sun, through_sky, back = field.column_mean(layer.coverage, fluxes)
    base = top_sun * through_sun + sky * through_sky
    shaded = sun_through(layer, cos_sun)
    clear = (luts.transmittance_to_top(0.0, np.array(cos_sun)) * mu_s + luts.ambient_skylight(np.array(cos_sun))) * shaded
    rho = params.ground_albedo
    ground = (clear + base) / (1.0 - rho * back)
    return Glow(above=(base + back * rho * ground) / np.pi, below=rho * (ground - clear) / np.pi,
                ground=rho * ground / np.pi)


@functools.lru_cache(maxsize=8)
def _upper_share_table(mie_g: float, size: int = 257):
    """(cos_view grid, Rayleigh share, Mie share): the fraction of each phase function's weight
    on light arriving from the upper hemisphere, for a ray looking along zenith cosine
    cos_view (p(view . toward source), as the tables' cos_sun_view)."""
    cos_view = np.linspace(-1.0, 1.0, size)
    x, w = np.polynomial.legendre.leggauss(PHASE_NODES)
    # At angle theta from the view, the circle of source directions has this share above.
    across = np.sqrt(np.maximum(1.0 - cos_view[:, None] ** 2, 0.0)) * np.sqrt(1.0 - x[None, :] ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(across > 1e-12, -cos_view[:, None] * x[None, :] / across,
                         np.where(cos_view[:, None] * x[None, :] > 0, -np.inf, np.inf))
    upper = np.arccos(np.clip(ratio, -1.0, 1.0)) / np.pi
    shares = [2.0 * np.pi * (upper * p * w).sum(-1) for p in (rayleigh_phase(x), mie_phase(x, mie_g))]
    return cos_view, shares[0], shares[1]


def cloud_glow(luts: Luts, camera_height: float, directions, distance, glow: Glow, cloud_light,
               over_layer: bool = False) -> np.ndarray:
    """(n, 3) the clouds' light scattered toward the camera by the air along ``directions`` (n, 3)
    out to ``distance`` (n,), all from under the layer or all from ``over_layer``: ``glow``'s light from
    above and from below for the Rayleigh part, and for the aerosol's forward peak the mean
    column's light along the ray itself, ``cloud_light`` (n, 3), on the layer's side (it sees
    little else: a thin layer is far brighter toward the sun than away)."""
    # Everything but cloud_light depends on the ray's elevation alone (the distance too): the
    # integral is made once per elevation (a panorama's row).
    cos_view, row = np.unique(directions[:, 2], return_inverse=True)
    first = np.zeros(len(cos_view), dtype=int)
    first[row[::-1]] = np.arange(len(row))[::-1]
    rayleigh, mie = _scattering_along(luts.params, camera_height, directions[first], distance[first])
    grid, rayleigh_up, mie_up = _upper_share_table(float(luts.params.mie_g))
    up_r = np.interp(cos_view, grid, rayleigh_up)[:, None]
    up_m = np.interp(cos_view, grid, mie_up)[row, None]
    light_r = (rayleigh * (up_r * glow.above + (1.0 - up_r) * glow.below))[row]
    if over_layer:                   # the column's light is below
        return light_r + mie[row] * (up_m * glow.above + (1.0 - up_m) * cloud_light)
    return light_r + mie[row] * (up_m * cloud_light + (1.0 - up_m) * glow.below)


def _scattering_along(params, camera_height, directions, distance):
    """((n, 3), (n, 3)): the Rayleigh and the aerosol scattering along the rays out to
    ``distance``, each step seen through the air before it: int sigma_s T ds."""
    step = distance / GLOW_STEPS
    along = (np.arange(GLOW_STEPS) + 0.5)[None, :] * step[:, None]                     # (n, k)
    points = np.array([0.0, 0.0, camera_height])[None, None, :] + directions[:, None, :] * along[..., None]
    heights = np.linalg.norm(points + np.array([0.0, 0.0, params.earth_radius]), axis=-1) - params.earth_radius
    rho = densities(params, np.maximum(heights, 0.0)) * step[:, None, None]             # (n, k, 3)
    depth = rho @ params.extinction_matrix()                                            # (n, k, C)
    seen = np.exp(-(np.cumsum(depth, axis=1) - 0.5 * depth))
    return np.sum(seen * rho[..., :1], axis=1) * params.rayleigh, np.sum(seen * rho[..., 1:2], axis=1) * params.mie


def shade(luts: Luts, layer: CloudLayer, camera_height: float, directions, distance, transmittance,
          sun, reach: float, glow: Glow, cloud_light) -> Shade:
    """What the world takes off the clear sky's light for rays from the camera along
    ``directions`` (n, 3) meeting it ``distance`` (n,) away with the air's transmittance
    ``transmittance`` (n, 3) to there; ``reach``: how far the light shafts march (sky pixels end
    at min(distance, reach)); ``glow``: glow_sources; ``cloud_light`` (n, 3): the mean column's
    light along each ray where it meets the layer, per unit sun."""
    directions = np.asarray(directions, dtype=np.float64)
    sun = np.asarray(sun, dtype=np.float64)
    n = len(directions)
    if n == 0:
        return Shade(np.zeros((n, 3)), np.zeros((n, 3)))
    if camera_height >= layer.middle:
        # Over the deck the air is sunlit as the tables have it, but over a bright top, not
        # the ground: it scatters the deck's light beyond the ground's the tables count.
        deck = top_light.deck_light(luts, layer, float(sun[2]))
        extra = np.maximum(cloud_light - deck.counted, 0.0)
        over = Glow(above=np.zeros(3), below=deck.extra, ground=np.zeros(3))
        return Shade(np.zeros((n, 3)), -cloud_glow(luts, camera_height, directions, distance, over, extra, True))
    camera = np.array([0.0, 0.0, camera_height])
    cloud = camera + directions * distance[:, None]
    near = camera + directions * np.minimum(distance, reach)[:, None]
    single_all = _front(luts, camera, cloud, directions, sun, transmittance, "single")
    higher = _front(luts, camera, cloud, directions, sun, transmittance, "higher")
    # Within the shafts' reach (all but the rays near the horizon) the near part is all of it.
    single_near = single_all.copy()
    far = distance > reach
    if far.any():
        single_near[far] = aerial.segment_inscattering(luts, camera, near[far], sun, table="single")
    shaded = 1.0 - sun_through(layer, float(sun[2]))
    glow_light = cloud_glow(luts, camera_height, directions, distance, glow, cloud_light)
    return Shade(single=shaded * single_near,
                 rest=shaded * (single_all - single_near + higher) - glow_light)


def _front(luts, camera, cloud, directions, sun, transmittance, table):
    """S - T S_P of one table: the air's light in front of the cloud, as sky.composite has it."""
    cos_sun_view = directions @ sun
    at_camera = luts.sky_radiance(camera[2], directions[:, 2], sun[2], cos_sun_view, table=table)
    from_centre = cloud + np.array([0.0, 0.0, luts.params.earth_radius])
    radius = np.linalg.norm(from_centre, axis=-1)
    up = from_centre / radius[:, None]
    at_cloud = luts.sky_radiance(radius - luts.params.earth_radius, np.clip((directions * up).sum(-1), -1, 1),
                                 np.clip(up @ sun, -1, 1), cos_sun_view, table=table)
    return np.maximum(at_camera - transmittance * at_cloud, 0.0)
