"""The sky with the cloud layer: what a view ray sees of the clouds, per unit sun. Twin of the
"OLS Clouds" node group (addon/nodes/clouds.py); the lighting panoramas use it too.

A ray meets the layer at its middle sphere (layer.middle_hit), at point P a distance d away,
where the column's vertical optical thickness is tau = density * thickness * fraction(P). There:
- the sun's irradiance is the atmosphere's transmittance from P toward the sun (the tables):
  white at noon, reddened at sunset;
- the column scatters it (slab.radiance: single scattering with the cloud phase function, the
  higher orders from the Monte Carlo table), seen through the column (from below) or reflected
  (the sun on the viewer's side: from above, or from below when the sun is under the cloud's
  horizontal, which lights the undersides at sunset);
- the ambient skylight on the layer's top (top_light.py), diffusely transmitted or reflected
  (slab.diffuse_shares: the two-stream fluxes with the slab's own angular shape);
- the column hides alpha = 1 - exp(-tau / |mu_v|) of what lies behind it.
The air between the camera and P hazes it. With S the sky's radiance from the camera and S_P the
sky's from P along the same ray (both from the 4D table), Yusov 2013 eq. (8) gives the air's light
in front of the cloud as S - T S_P, so
    sky with clouds = S + T (C - alpha S_P),
T the air's transmittance camera -> P and C the cloud's light.

The terms split in two. What depends on the ray's direction alone (T, the sun's colour at P, the
ambient skylight at P, S_P: AirTerms) is smooth across the sky; what depends on the column met
(tau, hence alpha and how much of the sun and skylight the column sends on) is as sharp as the
cloud map. The node group reads the smooth part from a per-frame panorama (air_map.py) and
computes the sharp part per ray; ``view`` takes either.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..tables import ground
from ..tables.lookup import Luts
from . import air_shade, field, slab, top_light
from .layer import SHAFT_RANGE, CloudLayer, middle_hit


@dataclass
class CloudView:
    hit: np.ndarray            # (...) the ray meets a cloud column (before the ground)
    alpha: np.ndarray          # (...) the fraction of the light behind the cloud it hides
    light: np.ndarray          # (..., 3) T C: the cloud's own light per unit sun as the camera sees it
    sky_behind: np.ndarray     # (..., 3) T S_P: the table's sky from P on (per unit sun) as the camera sees it
    shade: air_shade.Shade     # (..., 3) each: what the clouds take off the air in front of them (air_shade.py)


@dataclass
class AirTerms:
    """Per view direction; the first three already times T (transmittance camera -> P)."""
    sun: np.ndarray            # (..., 3) T x the transmittance from P to the sun
    ambient: np.ndarray        # (..., 3) T x the ambient skylight at P / pi
    behind: np.ndarray         # (..., 3) T x S_P
    bounce: np.ndarray         # (..., 3) T x the ground's light on the cloud base / pi (air_shade.Glow.ground)
    shade_single: np.ndarray   # (..., 3) air_shade.Shade.single
    shade_rest: np.ndarray     # (..., 3) air_shade.Shade.rest


@dataclass
class _Geometry:
    point: np.ndarray          # (n, 3) P, camera at (0, 0, height)
    cos_view: np.ndarray       # (n,) the ray's zenith cosine at P
    cos_sun: np.ndarray        # (n,) the sun's zenith cosine at P
    cos_sun_view: np.ndarray   # (n,)


def column_fraction(layer: CloudLayer, cloud, x, y):
    u, v = field.map_uv(x, y, layer.scale, layer.offset)
    return field.thickness_fraction(field.sample(cloud, u, v), layer.coverage)


def _geometry(params, layer, height, rays, distance, sun) -> _Geometry:
    point = np.array([0.0, 0.0, height]) + rays * distance[:, None]
    radius = params.earth_radius + layer.middle
    centre_to_point = point + np.array([0.0, 0.0, params.earth_radius])
    return _Geometry(point, (rays * centre_to_point).sum(-1) / radius, centre_to_point @ sun / radius, rays @ sun)


def sun_at_lit_face(luts: Luts, layer: CloudLayer, cos_sun):
    """(..., 3) the atmosphere's transmittance toward the sun from the face of the layer the
    sun lights (the slab's sun falls on it): the top, or the base with the sun under the
    cloud's horizontal. Taken at the middle, a sun 5 deg high reached a deck's top through
    300 m of haze too many, and the deck seen from above toward it was 0.87-0.89x the Monte
    Carlo tracer's (0.94x from the top)."""
    cos_sun = np.asarray(cos_sun, dtype=np.float64)
    colour = np.asarray(luts.transmittance_to_top(layer.base + layer.thickness, cos_sun))
    under = cos_sun <= 0.0
    if np.any(under):
        colour = colour.copy()
        colour[under] = luts.transmittance_to_top(layer.base, cos_sun[under])
    return colour


def _air_terms(luts: Luts, layer: CloudLayer, height, rays, at: _Geometry, sun) -> AirTerms:
    air = air_to_cloud(luts, height, rays[:, 2], layer.middle, at.cos_view)
    cos_sun = np.clip(at.cos_sun, -1.0, 1.0)
    sun_colour = sun_at_lit_face(luts, layer, at.cos_sun)
    ambient_colour = top_light.skylight(luts, layer, cos_sun) / np.pi
    glow = air_shade.glow_sources(luts, layer, float(sun[2]))
    # The mean column's light feeds the aerosol's forward glow only: four nodes in the edge band.
    mean_light = field.column_mean(
        layer.coverage, lambda f: _column_light(layer.density * layer.thickness * f, at, sun_colour, ambient_colour,
                                                glow.ground), band_nodes=4)
    distance = np.linalg.norm(at.point - np.array([0.0, 0.0, height]), axis=-1)
    shade = air_shade.shade(luts, layer, height, rays, distance, air, sun, SHAFT_RANGE, glow, mean_light)
    return AirTerms(air * sun_colour, air * ambient_colour,
                    air * luts.sky_radiance(layer.middle, np.clip(at.cos_view, -1.0, 1.0), cos_sun, at.cos_sun_view),
                    air * glow.ground, shade.single, shade.rest)


def _column_light(tau, at: _Geometry, sun_colour, ambient_colour, bounce_colour):
    """(n, 3) the light of columns of optical thickness ``tau`` (n,) where the rays meet them,
    per unit sun, from the sun's, the skylight's and the ground's light there (each (n, 3), or
    all times T for the light as the camera sees it)."""
    abs_view = np.maximum(np.abs(at.cos_view), slab.MIN_COS)
    abs_sun = np.abs(at.cos_sun)
    # The sun on the viewer's side of the slab: seen from below (looking up) with the sun under
    # the cloud's horizontal, or from above with it over.
    reflected = (at.cos_view * at.cos_sun) < 0
    cos_az = slab.cos_azimuth(at.cos_view, at.cos_sun, at.cos_sun_view)
    sun_share = slab.radiance(tau, abs_sun, abs_view, at.cos_sun_view, cos_az, reflected)
    back, through = slab.diffuse_shares(tau, abs_view)
    # The skylight falls on the top, the ground's light on the base.
    looking_up = at.cos_view > 0
    ambient_share = np.where(looking_up, through, back)
    bounce_share = np.where(looking_up, back, through)
    return sun_colour * sun_share[:, None] + ambient_colour * ambient_share[:, None] + bounce_colour * bounce_share[:, None]


def air_terms(luts: Luts, layer: CloudLayer, camera_height: float, directions, sun) -> AirTerms:
    """AirTerms of every ray that meets the middle sphere, the ground not minded (the air map
    must be smooth across the horizon); 0 elsewhere."""
    directions = np.asarray(directions, dtype=np.float64)
    height = max(float(camera_height), 0.0)
    distance, hit = middle_hit(layer, height, directions, luts.params.earth_radius)
    sun = np.asarray(sun, float)
    terms = _air_terms(luts, layer, height, directions[hit],
                       _geometry(luts.params, layer, height, directions[hit], distance[hit], sun), sun)
    shape = directions.shape[:-1] + (3,)
    out = AirTerms(*(np.zeros(shape) for _ in dataclasses.fields(AirTerms)))
    for term in dataclasses.fields(AirTerms):
        getattr(out, term.name)[hit] = getattr(terms, term.name)
    return out


def view(luts: Luts, layer: CloudLayer, cloud, camera_height: float, directions, sun, camera_xy=(0.0, 0.0),
         air=None) -> CloudView:
    """``camera_xy``: the camera's world x, y, where the map is read (the sky itself does not
    depend on it; the clouds and their shadows on the ground must agree). ``air``: a function
    of the rays (n, 3) giving their AirTerms (the node group's: air_map.lookup); computed
    exactly when None."""
    params = luts.params
    directions = np.asarray(directions, dtype=np.float64)
    sun = np.asarray(sun, dtype=np.float64)
    height = max(float(camera_height), 0.0)
    distance, hit = middle_hit(layer, height, directions, params.earth_radius)
    hit = hit & ~(ground.hits_ground(params, min(height, params.atmosphere_height), directions[..., 2])
                  & (height < layer.middle))
    # Only the rays that meet the layer are shaded (the lighting panorama's lower half never does).
    rays = directions[hit]
    at = _geometry(params, layer, height, rays, distance[hit], sun)
    terms = _air_terms(luts, layer, height, rays, at, sun) if air is None else air(rays)
    fraction = column_fraction(layer, cloud, at.point[:, 0] + camera_xy[0], at.point[:, 1] + camera_xy[1])
    tau = layer.density * layer.thickness * fraction
    shape = directions.shape[:-1]
    alpha, light, sky_behind = np.zeros(shape), np.zeros(shape + (3,)), np.zeros(shape + (3,))
    shade = air_shade.Shade(np.zeros(shape + (3,)), np.zeros(shape + (3,)))
    alpha[hit] = -np.expm1(-tau / np.maximum(np.abs(at.cos_view), slab.MIN_COS))
    light[hit] = _column_light(tau, at, terms.sun, terms.ambient, terms.bounce)
    sky_behind[hit] = terms.behind
    shade.single[hit], shade.rest[hit] = terms.shade_single, terms.shade_rest
    return CloudView(hit, alpha, light, sky_behind, shade)


def air_to_cloud(luts: Luts, camera_height, cos_view, cloud_height, cos_view_at_cloud):
    """Transmittance camera -> cloud as the difference of the net densities to the top from the
    ray's lower end and from its upper end, both looking up along it: from below the layer the
    camera is the lower end (a ray a little below the horizon dips and climbs back to the
    layer, and the camera's net density covers the dip), from above the cloud is. Rays that
    meet a cloud never run into the ground, so the difference needs none of
    aerial.segment_transmittance's care (reversed rays, a quadrature at the horizon), which was
    a third of the cloud group's nodes."""
    params = luts.params
    camera_height = min(camera_height, params.atmosphere_height)
    cos_view = np.asarray(cos_view, dtype=np.float64)
    if camera_height >= cloud_height:
        near_h, near_c, far_h, far_c = cloud_height, -np.asarray(cos_view_at_cloud), camera_height, -cos_view
    else:
        near_h, near_c, far_h, far_c = camera_height, cos_view, cloud_height, cos_view_at_cloud
    net = (luts.net_density_to_top(near_h, np.clip(near_c, -1.0, 1.0)).astype(np.float64)
           - luts.net_density_to_top(far_h, np.clip(far_c, -1.0, 1.0)))
    return np.exp(-np.minimum(np.maximum(net, 0.0) @ params.extinction_matrix(), 80.0))


def air_taken(cloud: CloudView, light_shafts: bool = False):
    """(..., 3) per unit sun, what the clouds take off the air in front of them (air_shade.py):
    all of it, or with ``light_shafts`` on (camera rays) what the shafts pass does not redo."""
    return cloud.shade.rest if light_shafts else cloud.shade.rest + cloud.shade.single


def composite(clear_sky, scattering_scale, sun_strength, cloud: CloudView, ground=0.0, light_shafts=False):
    """The sky with clouds from the clear sky (``clear_sky``: S times the sun strength and the
    scattering scale, as the world shows it) and the ground the view meets (as the world shows
    it, or 0): the cloud's light scales with the sun strength, as the ground's does, and the sky
    behind it and the air in front of it (air_taken) as the sky does; the ground behind a cloud
    (seen from above the layer) is dimmed by it, as the "OLS Sky" group dims it."""
    behind = (cloud.alpha[..., None] * cloud.sky_behind + air_taken(cloud, light_shafts)) * (scattering_scale
                                                                                          * sun_strength)
    return clear_sky + (1.0 - cloud.alpha[..., None]) * ground + cloud.light * sun_strength - behind
