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
- the ambient skylight at P, diffusely transmitted or reflected (slab.diffuse_two_stream);
- the column hides alpha = 1 - exp(-tau / |mu_v|) of what lies behind it.
The air between the camera and P hazes it. With S the sky's radiance from the camera and S_P
the sky's from P along the same ray (both from the 4D table), eq. (8) gives the air's light in
front of the cloud as S - T S_P, so
    sky with clouds = S + T (C - alpha S_P),
T the air's transmittance camera -> P and C the cloud's light. Far clouds, with T small, fade
into the sky.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..tables import ground
from ..tables.lookup import Luts
from . import field, slab
from .layer import CloudLayer, middle_hit


@dataclass
class CloudView:
    hit: np.ndarray            # (...) the ray meets a cloud column (before the ground)
    alpha: np.ndarray          # (...) the fraction of the light behind the cloud it hides
    light: np.ndarray          # (..., 3) C: the cloud's own light per unit sun (sun + ambient)
    air: np.ndarray            # (..., 3) T: transmittance camera -> P (1 where no cloud is met)
    sky_behind: np.ndarray     # (..., 3) S_P: the sky's radiance from P on (the table's, per unit sun)


def column_fraction(layer: CloudLayer, cloud, x, y):
    u, v = field.map_uv(x, y, layer.scale, layer.offset)
    return field.thickness_fraction(field.sample(cloud, u, v), layer.coverage)


def view(luts: Luts, layer: CloudLayer, cloud, camera_height: float, directions, sun, camera_xy=(0.0, 0.0)) -> CloudView:
    """``camera_xy``: the camera's world x, y, where the map is read (the sky itself does not
    depend on it; the clouds and their shadows on the ground must agree)."""
    params = luts.params
    directions = np.asarray(directions, dtype=np.float64)
    sun = np.asarray(sun, dtype=np.float64)
    height = max(float(camera_height), 0.0)
    distance, hit = middle_hit(layer, height, directions, params.earth_radius)
    hit = hit & ~(ground.hits_ground(params, min(height, params.atmosphere_height), directions[..., 2])
                  & (height < layer.middle))
    # Only the rays that meet the layer are shaded (the lighting panorama's lower half never does).
    rays, distance = directions[hit], distance[hit]
    point = np.array([0.0, 0.0, height]) + rays * distance[:, None]
    radius = params.earth_radius + layer.middle
    centre_to_point = point + np.array([0.0, 0.0, params.earth_radius])
    cos_view = (rays * centre_to_point).sum(-1) / radius
    cos_sun = centre_to_point @ sun / radius
    cos_sun_view = rays @ sun
    fraction = column_fraction(layer, cloud, point[:, 0] + camera_xy[0], point[:, 1] + camera_xy[1])
    tau = layer.density * layer.thickness * fraction
    abs_view = np.maximum(np.abs(cos_view), slab.MIN_COS)
    abs_sun = np.abs(cos_sun)
    # The sun on the viewer's side of the slab: seen from below (looking up) with the sun under
    # the cloud's horizontal, or from above with it over.
    reflected = (cos_view * cos_sun) < 0
    cos_az = slab.cos_azimuth(cos_view, cos_sun, cos_sun_view)
    sun_light = luts.transmittance_to_top(layer.middle, cos_sun) * slab.radiance(
        tau, abs_sun, abs_view, cos_sun_view, cos_az, reflected)[:, None]
    back, through = slab.diffuse_two_stream(tau)
    ambient = luts.ambient_skylight(np.clip(cos_sun, -1.0, 1.0)) / np.pi * np.where(
        cos_view > 0, through, back)[:, None]
    shape = directions.shape[:-1]
    alpha, light = np.zeros(shape), np.zeros(shape + (3,))
    air, sky_behind = np.ones(shape + (3,)), np.zeros(shape + (3,))
    alpha[hit] = -np.expm1(-tau / abs_view)
    light[hit] = sun_light + ambient
    air[hit] = air_to_cloud(luts, height, rays[:, 2], layer.middle, cos_view)
    sky_behind[hit] = luts.sky_radiance(layer.middle, np.clip(cos_view, -1.0, 1.0), np.clip(cos_sun, -1.0, 1.0),
                                        cos_sun_view)
    return CloudView(hit, alpha, light, air, sky_behind)


def air_to_cloud(luts: Luts, camera_height, cos_view, cloud_height, cos_view_at_cloud):
    """Transmittance camera -> cloud as the difference of the net densities to the top from the
    ray's lower end and from its upper end, both looking up along it (from above the layer, the
    cloud is the lower end). Rays that meet a cloud never run into the ground, so the difference
    needs none of aerial.segment_transmittance's care (reversed rays, a quadrature at the
    horizon), which was a third of the cloud group's nodes."""
    params = luts.params
    camera_height = min(camera_height, params.atmosphere_height)
    cos_view = np.asarray(cos_view, dtype=np.float64)
    down = cos_view < 0
    near_h, far_h = np.where(down, cloud_height, camera_height), np.where(down, camera_height, cloud_height)
    near_c = np.where(down, -cos_view_at_cloud, cos_view)
    far_c = np.where(down, -cos_view, cos_view_at_cloud)
    net = (luts.net_density_to_top(near_h, np.clip(near_c, -1.0, 1.0)).astype(np.float64)
           - luts.net_density_to_top(far_h, np.clip(far_c, -1.0, 1.0)))
    return np.exp(-np.minimum(np.maximum(net, 0.0) @ params.extinction_matrix(), 80.0))


def composite(clear_sky, scattering_scale, sun_strength, cloud: CloudView, ground=0.0):
    """The sky with clouds from the clear sky (``clear_sky``: S times the sun strength and the
    scattering scale, as the world shows it) and the ground the view meets (as the world shows
    it, or 0): the cloud's light scales with the sun strength, as the ground's does, and the sky
    behind it as the sky does; the ground behind a cloud (seen from above the layer) is dimmed
    by it, as the "OLS Sky" group dims it."""
    behind = cloud.alpha[..., None] * cloud.sky_behind * (scattering_scale * sun_strength)
    return (clear_sky + (1.0 - cloud.alpha[..., None]) * ground
            + cloud.air * (cloud.light * sun_strength - behind))
