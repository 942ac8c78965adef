"""The Lambertian ground under the atmosphere (AtmosphereParams.ground_albedo).

A ray that hits the ground at G sees, besides the light scattered in front of it,

    L_ground = T(x -> G) * albedo / pi * (T_sun(G) * max(mu_s(G), 0) + E_sky(mu_s(G)))

where mu_s(G) is the sun's zenith cosine at G (the Earth is curved: it differs from the
viewer's) and E_sky the irradiance from the sky. The tables hold only the light scattered in the
atmosphere, so the look-ups add this term for ground rays (the world below the horizon, the
same formula as the terrain material). In the bake the ground is a source of the higher orders:
the radiance field that order n scatters includes the ground lit by order n - 2 (the direct sun
for n = 2), so ground-reflected light reaches the sky and the ambient skylight.
"""
from __future__ import annotations

import math

import numpy as np

from . import parameterization as par
from ..model.atmosphere import mie_phase, rayleigh_phase
from ..model.geometry import distance_to_ground
from .interpolation import axis_weights, interpolate
from .optical_depth import table_net_density

# Quadrature of the sky irradiance at the ground in the bake (upper hemisphere).
IRRADIANCE_ZENITHS = 16
IRRADIANCE_AZIMUTHS = 16        # over half a circle; the sky is symmetric about the sun plane


def ground_point(params, height_m, cos_view, cos_sun, cos_sun_view):
    """(distance to the ground, sun zenith cosine at the ground point, zenith cosine at the
    ground point of the direction back toward the viewer) for rays that hit the ground."""
    h = np.clip(np.asarray(height_m, dtype=np.float64), 0.0, params.atmosphere_height)
    r = params.earth_radius + h
    c = np.asarray(cos_view, dtype=np.float64)
    d = distance_to_ground(r, c, params.earth_radius)
    d = np.minimum(d, 2.0 * math.sqrt(params.top_radius ** 2 - params.earth_radius ** 2))
    cos_sun_at = (r * np.asarray(cos_sun) + d * np.asarray(cos_sun_view)) / params.earth_radius
    cos_back = -(r * c + d) / params.earth_radius
    return d, np.clip(cos_sun_at, -1.0, 1.0), np.clip(cos_back, 0.0, 1.0)


def net_density_to_ground(params, optical_depth, height_m, cos_view, cos_back, packed=None):
    """(..., 4) net densities from the viewer to the ground point: both upward rays read from
    the optical-depth table, the one from the ground minus the one from the viewer. ``packed``:
    interpolation.packed_rows(optical_depth), when the caller keeps it."""
    from_ground = table_net_density(params, optical_depth, 0.0, cos_back, packed)
    from_viewer = table_net_density(params, optical_depth, height_m, -np.asarray(cos_view, dtype=np.float64), packed)
    return np.maximum(from_ground - from_viewer, 0.0)


def direct_irradiance(params, optical_depth, extinction, cos_sun, packed=None) -> np.ndarray:
    """(..., C) sun irradiance on the ground per unit extraterrestrial sun, for the channels of
    ``extinction`` (4 media x C); ``packed`` as for net_density_to_ground."""
    c = np.asarray(cos_sun, dtype=np.float64)
    net = table_net_density(params, optical_depth, 0.0, np.maximum(c, 0.0), packed)
    return np.exp(-np.minimum(net @ extinction, 80.0)) * np.maximum(c, 0.0)[..., None]


def hits_ground(params, height_m, cos_view):
    return np.asarray(cos_view) < par.cos_horizon(height_m, params.earth_radius)


class GroundSource:
    """The ground's radiance toward the sphere directions of the higher-order bake.

    ``heights`` (n_h,) and ``mu`` (n_mu,): the order grid's heights and the sphere zeniths;
    ``cos_sun`` (n_s,): its sun nodes, where the irradiance functions are sampled."""

    def __init__(self, params, media, optical_depth, heights, mu, cos_sun, dims):
        self.params, self.dims = params, dims
        self.albedo = params.ground_albedo
        self.cos_sun = cos_sun
        extinction = media.extinction_matrix()
        h, m = heights[:, None], mu[None, :]
        self.hits = hits_ground(params, h, m)                                            # (h, mu)
        d, _, back = ground_point(params, h, m, 0.0, 0.0)
        self.distance = np.where(self.hits, d, 0.0)
        net = net_density_to_ground(params, optical_depth, h, m, back)
        self.transmittance = np.where(self.hits[..., None], np.exp(-np.minimum(net @ extinction, 80.0)), 0.0)
        self.radius = params.earth_radius + heights
        self.direct = direct_irradiance(params, optical_depth, extinction, cos_sun)     # (s, C)
        self._reflected = ((self.albedo / math.pi) * self.transmittance[:, None, :, None, :]).astype(np.float32)
        self._weights_for = None        # (cos_sun_view, i_s, w_s) of _sun_weights

    def radiance(self, irradiance, cos_sun_view, rows=slice(None)) -> np.ndarray:
        """(h, s, mu, az, C) radiance of the ground lit with ``irradiance`` (s, C) on the sun
        nodes, seen along the sphere directions; ``cos_sun_view`` (s, mu, az). ``rows``: the
        heights (a slice of the grid's)."""
        i_s, w_s = self._sun_weights(cos_sun_view)
        i_s, w_s = i_s[rows], w_s[rows]
        irradiance = np.asarray(irradiance, dtype=np.float32)
        low = irradiance[i_s]
        lit = low + (irradiance[i_s + 1] - low) * w_s[..., None]
        lit *= self._reflected[rows]
        return lit

    def _sun_weights(self, cos_sun_view):
        """Where each ground point's sun falls on the sun nodes: the same directions every
        order, so found once (it was a third of the ground's cost per order)."""
        cached = self._weights_for
        if cached is None or not np.array_equal(cached[0], cos_sun_view):
            n_s = len(self.cos_sun)
            cos_at = ((self.radius[:, None, None, None] * self.cos_sun[None, :, None, None]
                       + self.distance[:, None, :, None] * cos_sun_view[None]) / self.params.earth_radius)
            i_s, w_s = axis_weights(par.sun_zenith_to_x(np.clip(cos_at, -1.0, 1.0), n_s), n_s)
            self._weights_for = cached = (np.array(cos_sun_view), i_s, w_s.astype(np.float32))
        return cached[1], cached[2]

    def sky_irradiance(self, table_n, table_mie=None, table_fog=None) -> np.ndarray:
        """(s, C) irradiance at the ground from one order's radiance on the order grid (stored
        divided by the Rayleigh phase; ``table_mie`` and ``table_fog``: single Mie and fog
        without phase, order 1)."""
        n_h, n_a, n_s, n_t = self.dims
        mu, mu_w = np.polynomial.legendre.leggauss(IRRADIANCE_ZENITHS)
        mu, mu_w = 0.5 * (mu + 1.0), 0.5 * mu_w
        az = (np.arange(IRRADIANCE_AZIMUTHS) + 0.5) * math.pi / IRRADIANCE_AZIMUTHS
        weight = mu * mu_w * 2.0 * math.pi / IRRADIANCE_AZIMUTHS                        # (mu,)
        cs = self.cos_sun[:, None, None]
        ct = mu[None, :, None] * cs + np.sqrt(1 - mu[None, :, None] ** 2) * np.sqrt(1 - cs ** 2) * np.cos(az)
        xa, _ = par.view_zenith_to_x(mu, 0.0, n_a, self.params.earth_radius)
        coords = (np.broadcast_to(xa[None, :, None], ct.shape), np.arange(n_s)[:, None, None],
                  par.sun_view_to_x(ct, n_t))
        radiance = interpolate(table_n[0], coords) * rayleigh_phase(ct)[..., None]
        if table_mie is not None:
            radiance += interpolate(table_mie[0], coords) * mie_phase(ct, self.params.mie_g)[..., None]
        if table_fog is not None:
            radiance += interpolate(table_fog[0], coords) * mie_phase(ct, self.params.fog_g)[..., None]
        return np.einsum("smac,m->sc", radiance, weight)
