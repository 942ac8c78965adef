"""The fog layer's references: geometries to check the baked fog against, the Monte Carlo path
tracer on them, and its energy balance.

The fog (AtmosphereParams.fog_visibility / fog_height / fog_g) is a fourth medium that only
scatters, grey, exp(-h / fog_height), with its own Cornette-Shanks phase function.
``reference.single_scattering`` (deterministic) and ``monte_carlo.radiance_by_order`` /
``monte_carlo.irradiance_by_order`` (path tracer, orders apart) both include it; this module
only names the cases to run them on:

* ``fog_geometries``: (height, cos view zenith, cos sun zenith, cos sun-view) inside the fog,
  just above it and looking down on it, toward and away from a low and a high sun;
* ``fog_params``: three-channel params with a fog (what the tracer and the reference take;
  spectral params go through ``spectrum.triple_params`` per wavelength triple);
* ``fog_radiance_by_order``: the tracer on every geometry;
* ``energy_balance``: all the light that enters a white, non-absorbing fog over a white ground
  must leave through the top: the upward irradiance above the fog over cos(sun zenith).
"""
from __future__ import annotations

import math

from ..model.atmosphere import AtmosphereParams
from .monte_carlo import DEFAULT_PATHS, irradiance_by_order, radiance_by_order

__all__ = ["fog_geometries", "fog_params", "fog_radiance_by_order", "energy_balance"]


def _by_elevation(height_m, view_elevation_deg, sun_elevation_deg, azimuth_deg):
    """(height, cos view zenith, cos sun zenith, cos sun-view) from elevations above the
    horizontal and the azimuth between the view and the sun, in degrees."""
    tv, ts, az = (math.radians(90.0 - view_elevation_deg), math.radians(90.0 - sun_elevation_deg),
                  math.radians(azimuth_deg))
    return (float(height_m), math.cos(tv), math.cos(ts),
            math.cos(tv) * math.cos(ts) + math.sin(tv) * math.sin(ts) * math.cos(az))


def fog_geometries(fog_height: float = 50.0) -> dict:
    """Geometries to compare the baked fog with the path tracer on, by name:
    (height m, cos view zenith, cos sun zenith, cos sun-view), ``rays.ray_by_elevation``'s
    convention. Elevations are above the local horizontal (negative: looking down), azimuths
    between the view and the sun (0: toward the sun, 180: away from it). ``fog_height`` (the
    fog's scale height H) places the ones defined relative to the layer (default 50 m).

    Inside the fog (camera at 2 m; at H):
      "in 2 m, up 10, sun 5 toward"        looking 10 deg up toward a low sun (5 deg): the forward
                                          peak of the fog's phase through the densest fog
      "in 2 m, up 10, sun 5 away"          the same, sun behind (back scattering)
      "in 2 m, horizontal, sun 5 az 90"    the horizon inside the fog, sun to the side: the
                                          thickest view (optical depth ~ beta sqrt(pi R H / 2))
      "in 2 m, up 10, sun 40 toward"       a high sun (40 deg), forward-ish (scattering angle 30)
      "in 2 m, zenith, sun 40"             the zenith seen from inside the fog, high sun
      "in 2 m, down 5, sun 40 away"        the ground ~23 m away (view ray ends on the ground)
      "in H, horizontal, sun 5 toward"     the camera at one scale height, toward the low sun
    Just above the fog (camera at 2.5 H):
      "above 2.5H, horizontal, sun 5 toward"  the fog's top grazed toward a low sun
      "above 2.5H, down 10, sun 5 away"       looking down into it, low sun behind
      "above 2.5H, up 10, sun 40 az 90"       the sky above the fog, high sun to the side (the
                                              fog lights it from below)
    Looking down on it from 500 m:
      "500 m, down 10, sun 5 toward"      the fog's top toward a low sun (forward glare)
      "500 m, down 10, sun 5 away"        the same, sun behind
      "500 m, down 10, sun 40 toward"     high sun, in front
      "500 m, down 30, sun 40 away"       high sun behind (the glory side)
      "500 m, nadir, sun 40"              straight down, high sun
    """
    h = float(fog_height)
    g = _by_elevation
    return {
        "in 2 m, up 10, sun 5 toward": g(2.0, 10.0, 5.0, 0.0),
        "in 2 m, up 10, sun 5 away": g(2.0, 10.0, 5.0, 180.0),
        "in 2 m, horizontal, sun 5 az 90": g(2.0, 0.0, 5.0, 90.0),
        "in 2 m, up 10, sun 40 toward": g(2.0, 10.0, 40.0, 0.0),
        "in 2 m, zenith, sun 40": g(2.0, 90.0, 40.0, 0.0),
        "in 2 m, down 5, sun 40 away": g(2.0, -5.0, 40.0, 180.0),
        "in H, horizontal, sun 5 toward": g(h, 0.0, 5.0, 0.0),
        "above 2.5H, horizontal, sun 5 toward": g(2.5 * h, 0.0, 5.0, 0.0),
        "above 2.5H, down 10, sun 5 away": g(2.5 * h, -10.0, 5.0, 180.0),
        "above 2.5H, up 10, sun 40 az 90": g(2.5 * h, 10.0, 40.0, 90.0),
        "500 m, down 10, sun 5 toward": g(500.0, -10.0, 5.0, 0.0),
        "500 m, down 10, sun 5 away": g(500.0, -10.0, 5.0, 180.0),
        "500 m, down 10, sun 40 toward": g(500.0, -10.0, 40.0, 0.0),
        "500 m, down 30, sun 40 away": g(500.0, -30.0, 40.0, 180.0),
        "500 m, nadir, sun 40": g(500.0, -90.0, 40.0, 0.0),
    }


def fog_params(visibility_m: float, fog_height: float = 50.0, **changes) -> AtmosphereParams:
    """Three-channel params (the sample's wavelengths as RGB, ``spectral=False``) with a fog of
    the given visibility and scale height, ozone and the default ground (albedo 0.2); ``changes``
    on top."""
    base = dict(spectral=False, fog_visibility=float(visibility_m), fog_height=float(fog_height))
    return AtmosphereParams(**{**base, **changes})


def fog_radiance_by_order(params: AtmosphereParams, geometries: dict = None, orders: int = 8,
                          paths: int = DEFAULT_PATHS, seed: int = 0) -> dict:
    """{name: monte_carlo.OrderRadiance} of ``radiance_by_order`` on every geometry
    (``fog_geometries(params.fog_height)`` by default), each with its own seed (seed + index).
    Inside a thick fog the horizontal views need tens of orders (see ``OrderRadiance.atmosphere``
    per order before trusting a sum)."""
    geometries = fog_geometries(params.fog_height) if geometries is None else geometries
    return {name: radiance_by_order(params, *geometry, orders=orders, paths=paths, seed=seed + i)
            for i, (name, geometry) in enumerate(geometries.items())}


def energy_balance(visibility_m: float = 200.0, fog_height: float = 100.0, fog_g: float = 0.5,
                   cos_sun_zenith: float = 0.5, orders: int = 40, paths: int = 4096, seed: int = 0):
    """(ratio (3,), standard error (3,), result): the upward irradiance 30 fog scale heights up
    (all orders up to ``orders``, air and ground parts) over cos_sun_zenith, for a fog that only
    scatters (no air, no aerosol, no ozone) over a ground of albedo 1. Every photon that enters
    leaves through the top, so the ratio is 1 less the orders beyond ``orders`` (under 1% at the
    defaults, whose fog has a vertical optical depth of 1.96). ``result``: the
    ``irradiance_by_order`` itself.

    (The downward irradiance on the ground under the fog is *not* cos_sun_zenith in general: with
    no net flux at any height, the K-integral of the radiance is the same at the ground and at
    the top, which makes the ground's irradiance depend on the sun's zenith angle and on g.)"""
    params = AtmosphereParams(spectral=False, ozone=False, ground_albedo=1.0, rayleigh_scattering=(0.0, 0.0, 0.0),
                              mie_scattering=(0.0, 0.0, 0.0), fog_visibility=float(visibility_m),
                              fog_height=float(fog_height), fog_g=float(fog_g))
    result = irradiance_by_order(params, 30.0 * fog_height, cos_sun_zenith, facing_up=False, orders=orders,
                                 paths=paths, seed=seed)
    cov = result.atmosphere_cov.sum(axis=(0, 1)) + result.ground_cov.sum(axis=(0, 1))
    return result.total / cos_sun_zenith, (cov ** 0.5) / cos_sun_zenith, result

