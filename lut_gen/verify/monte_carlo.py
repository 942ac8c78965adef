"""Monte Carlo path tracer of the atmosphere: an independent reference for multiple scattering.

``radiance_by_order`` estimates the radiance reaching a viewer, per unit extraterrestrial sun
irradiance (the unit of ``lut_gen.verify.reference.single_scattering``), split by scattering order.
It shares no code with the baker (lut_gen.bake, sampling, ground): only the media definitions
of lut_gen.model.atmosphere (densities, phase functions). Everything is float64 numpy, vectorised over
the paths of a batch.

Orders
------
The order of a light path is the number of events on it: scatterings in the atmosphere plus
reflections off the ground, the ground point the view ray itself ends on included. The result
holds two parts by the *last* event before the light reaches the viewer:

* ``atmosphere[n-1]``: order-n light last scattered in the atmosphere (``atmosphere[0]`` is
  single scattering, ``atmosphere[1:]`` the higher orders; ground reflections earlier on the
  path count as events).
* ``ground[n-1]``: order-n light reflected by the ground point the view ray ends on, as seen
  through the atmosphere (``ground[0]``: the directly sunlit ground); 0 for views that miss
  the ground.

Estimator
---------
Paths start at the viewer along the view direction; vertex k of a path (k = 1, 2, ...) is its
k-th event, and next-event estimation towards the sun there gives its order-k contribution:
phase function x scattering coefficient x sun transmittance at an atmospheric vertex,
albedo / pi x cos(sun zenith) x sun transmittance at a ground vertex (0 where the Earth
hides the sun). The path continues from the vertex along a direction drawn from the phase
functions or, on the ground, a cosine-weighted direction (lut_gen.verify.monte_carlo_events).

The next vertex along a segment is either the segment's ground end or a collision *forced* into
the air of the segment, with weights that carry absorption exactly
(lut_gen.verify.monte_carlo_segments, which also integrates the optical depths). Forced
collisions mean no path leaves the atmosphere early; paths end after ``orders`` vertices. The
view ray's first vertex is split deterministically: one population of paths is forced into the
atmosphere (the ``atmosphere`` part), a second one starts on the ground point the view ray hits
(the ``ground`` part).

Fog (``params.has_fog``): a fourth medium, grey, that only scatters, with its own
Cornette-Shanks phase function (fog_g); lut_gen.verify.monte_carlo_media holds the media.

Standard errors and the covariances between orders come from the per-path contributions (each
path contributes to every order, so the orders' errors are correlated). At the default 16 384
paths, 4 orders take ~2 s per view (twice that for views of the ground, with its own paths)
on one core, with standard errors of ~0.1-1 % for single scattering, ~1-2.5 % for order 2 and
~3-6 % for order 4.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.atmosphere import AtmosphereParams
from .monte_carlo_events import _scatter_atmosphere, _scatter_ground, _sun_events
from .monte_carlo_media import _Media, _around
from .monte_carlo_segments import _ground_probability, _next_vertex, _Segment, _segment

__all__ = ["OrderRadiance", "radiance_by_order", "irradiance_by_order", "DEFAULT_PATHS"]

DEFAULT_PATHS = 16_384
# Paths traced together; bounds the work arrays to a few tens of MB.
BATCH_PATHS = 2048


@dataclass(frozen=True)
class OrderRadiance:
    """Radiance by order (see the module docstring): arrays (orders, 3), per unit sun, and the
    covariances (orders, orders, 3) of the estimates between orders, per channel (the orders
    of one path are correlated: sums of orders need the whole matrix, ``atmosphere_sum``)."""

    atmosphere: np.ndarray
    ground: np.ndarray
    atmosphere_cov: np.ndarray
    ground_cov: np.ndarray
    paths: int

    @property
    def atmosphere_se(self) -> np.ndarray:
        """(orders, 3) standard errors of ``atmosphere``."""
        return np.sqrt(np.maximum(np.diagonal(self.atmosphere_cov).T, 0.0))

    @property
    def ground_se(self) -> np.ndarray:
        """(orders, 3) standard errors of ``ground``."""
        return np.sqrt(np.maximum(np.diagonal(self.ground_cov).T, 0.0))

    def atmosphere_sum(self, start: int = 0, stop=None):
        """((3,), (3,)): ``atmosphere[start:stop].sum(0)`` and its standard error."""
        sl = slice(start, stop)
        cov = self.atmosphere_cov[sl, sl]
        return self.atmosphere[sl].sum(axis=0), np.sqrt(np.maximum(cov.sum(axis=(0, 1)), 0.0))

    @property
    def total(self) -> np.ndarray:
        """(3,) atmosphere + ground, all orders."""
        return self.atmosphere.sum(axis=0) + self.ground.sum(axis=0)


# -- paths -------------------------------------------------------------------------------------

def _trace(media: _Media, camera, view, sun, ground_first: bool, orders: int, n: int, rng) -> np.ndarray:
    """(n, orders, 3) contributions of n paths from the viewer. ``ground_first``: the first
    vertex is the ground point the view ray hits (weight T(view ray)); else a forced
    collision on the view ray. ``view``: one direction (3,) for every path, or one per path
    (n, 3)."""
    out = np.zeros((n, orders, 3))
    ids = np.arange(n)
    if view.ndim == 2:
        seg = _segment(media, np.repeat(camera[None], n, axis=0), view)
    else:
        # Every path starts on the same view ray: integrate it once.
        ray = _segment(media, camera[None], view[None])
        seg = _Segment(*(np.repeat(a, n, axis=0) for a in (ray.origin, ray.direction, ray.r, ray.mu,
                                                           ray.hits_ground, ray.nodes, ray.depth)))
    direction = seg.direction
    first_prob = np.where(seg.hits_ground, 1.0, 0.0) if ground_first else np.zeros(n)
    points, on_ground, weight = _next_vertex(media, seg, first_prob, rng)
    if ground_first:
        weight[~seg.hits_ground] = 0.0
    for k in range(orders):
        alive = np.any(weight > 0.0, axis=1)
        ids, points, direction, on_ground, weight = (a[alive] for a in (ids, points, direction, on_ground, weight))
        if ids.size == 0:
            break
        out[ids, k] = weight * _sun_events(media, points, direction, on_ground, sun)
        if k == orders - 1:
            break
        new_dir = np.empty_like(direction)
        factor = np.empty_like(weight)
        air = ~on_ground
        new_dir[air], factor[air] = _scatter_atmosphere(media, points[air], direction[air], rng)
        new_dir[on_ground], factor[on_ground] = _scatter_ground(media, points[on_ground], rng)
        seg = _segment(media, points, new_dir)
        ground_prob = _ground_probability(media, seg)
        points, on_ground, step = _next_vertex(media, seg, ground_prob, rng)
        direction = new_dir
        weight = weight * factor * step
    return out


def _view_geometry(params: AtmosphereParams, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view):
    """Viewer position, view and sun unit vectors (the viewer on the z axis, the view in the xz
    plane); the sun-view cosine is clamped into the range the zenith cosines allow."""
    h = float(np.clip(height_m, 0.0, params.atmosphere_height))
    mu_v = float(np.clip(cos_view_zenith, -1.0, 1.0))
    mu_s = float(np.clip(cos_sun_zenith, -1.0, 1.0))
    sin_v = math.sqrt(max(1.0 - mu_v * mu_v, 0.0))
    sin_s = math.sqrt(max(1.0 - mu_s * mu_s, 0.0))
    if sin_v * sin_s > 1e-12:
        cos_phi = float(np.clip((cos_sun_view - mu_v * mu_s) / (sin_v * sin_s), -1.0, 1.0))
    else:
        cos_phi = 1.0
    sin_phi = math.sqrt(max(1.0 - cos_phi * cos_phi, 0.0))
    camera = np.array([0.0, 0.0, params.earth_radius + h])
    view = np.array([sin_v, 0.0, mu_v])
    sun = np.array([sin_s * cos_phi, sin_s * sin_phi, mu_s])
    return camera, view, sun


def _mean_and_cov(total: np.ndarray, cross: np.ndarray, n: int):
    """Mean (orders, 3) and covariance of the mean (orders, orders, 3) of n path samples from
    their sum and the sum of their outer products (per channel)."""
    mean = total / n
    cov = (cross / n - mean[:, None] * mean[None, :]) / max(n - 1, 1)
    return mean, cov


def radiance_by_order(params: AtmosphereParams, height_m: float, cos_view_zenith: float,
                      cos_sun_zenith: float, cos_sun_view: float, orders: int = 4,
                      paths: int = DEFAULT_PATHS, seed: int = 0) -> OrderRadiance:
    """Radiance reaching a viewer at ``height_m`` looking along the view direction, per unit
    extraterrestrial sun irradiance, by order (``orders`` of them), estimated from ``paths``
    paths (plus as many for the ground the view ray hits, if it does).

    Order n: light that scattered in the atmosphere or reflected off the ground n times in
    all, the ground point the view ray ends on counting as an event. ``atmosphere`` (orders, 3):
    light whose last event before the viewer is a scattering in the atmosphere
    (``atmosphere[0]`` = single scattering, as ``reference.single_scattering``);
    ``ground`` (orders, 3): light reflected towards the viewer by the ground point its view
    ray hits (``ground[0]``: the directly sunlit ground; lookups add this term themselves).
    ``*_se``: their standard errors, ``*_cov``: the covariances between orders, ``atmosphere_sum``:
    a sum of orders with its standard error. Three-channel params only (``spectral=False``;
    convert spectral ones per wavelength with ``spectrum.triple_params``). Deterministic for
    a given ``seed``. The height is clamped to the atmosphere and the sun-view cosine into the
    range the two zenith cosines allow.
    """
    if params.spectral:
        raise ValueError("radiance_by_order needs three-channel params (spectral=False); "
                         "convert with lut_gen.model.spectrum.triple_params")
    if int(orders) < 1 or int(paths) < 2:
        raise ValueError(f"need orders >= 1 and paths >= 2, got {orders}, {paths}")
    orders, paths = int(orders), int(paths)
    media = _Media.of(params)
    camera, view, sun = _view_geometry(params, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view)
    sees_ground = bool(_segment(media, camera[None], view[None]).hits_ground[0])
    rng = np.random.default_rng(seed)
    sums = {part: [np.zeros((orders, 3)), np.zeros((orders, orders, 3))] for part in ("atmosphere", "ground")}
    for start in range(0, paths, BATCH_PATHS):
        n = min(BATCH_PATHS, paths - start)
        for part, ground_first in (("atmosphere", False), ("ground", True)):
            if ground_first and not sees_ground:
                continue
            c = _trace(media, camera, view, sun, ground_first, orders, n, rng)
            sums[part][0] += c.sum(axis=0)
            sums[part][1] += np.einsum("pic,pjc->ijc", c, c)
    atmosphere, atmosphere_cov = _mean_and_cov(*sums["atmosphere"], paths)
    ground, ground_cov = _mean_and_cov(*sums["ground"], paths)
    return OrderRadiance(atmosphere, ground, atmosphere_cov, ground_cov, paths)


def irradiance_by_order(params: AtmosphereParams, height_m: float, cos_sun_zenith: float, facing_up: bool = True,
                        orders: int = 4, paths: int = DEFAULT_PATHS, seed: int = 0) -> OrderRadiance:
    """Diffuse irradiance on a horizontal plane at ``height_m`` facing up (the sky above it) or
    down (``facing_up=False``: the air and the ground below it), per unit extraterrestrial sun
    irradiance, by order: pi x the mean radiance (``radiance_by_order``'s orders and parts) of
    ``paths`` cosine-weighted lines of sight about the plane's normal (each population, the
    ``atmosphere`` part and the ``ground`` part of the lines of sight that hit the ground, traced
    on the same lines of sight). The sun's direct beam is not included (add cos_sun_zenith x
    T_sun for a plane facing up). Energy: in a medium that only scatters, over a ground of
    albedo 1, all the light leaves through the top, so the ``total`` of all orders facing down
    above the media is cos_sun_zenith."""
    if params.spectral:
        raise ValueError("irradiance_by_order needs three-channel params (spectral=False); "
                         "convert with lut_gen.model.spectrum.triple_params")
    if int(orders) < 1 or int(paths) < 2:
        raise ValueError(f"need orders >= 1 and paths >= 2, got {orders}, {paths}")
    orders, paths = int(orders), int(paths)
    media = _Media.of(params)
    camera, _, sun = _view_geometry(params, height_m, 1.0, cos_sun_zenith, cos_sun_zenith)
    normal = np.array([0.0, 0.0, 1.0 if facing_up else -1.0])
    rng = np.random.default_rng(seed)
    sums = {part: [np.zeros((orders, 3)), np.zeros((orders, orders, 3))] for part in ("atmosphere", "ground")}
    for start in range(0, paths, BATCH_PATHS):
        n = min(BATCH_PATHS, paths - start)
        views = _around(np.repeat(normal[None], n, axis=0), np.sqrt(rng.random(n)), rng)
        for part, ground_first in (("atmosphere", False), ("ground", True)):
            if ground_first and facing_up:
                continue  # lines of sight above the horizontal plane never reach the ground
            c = math.pi * _trace(media, camera, views, sun, ground_first, orders, n, rng)
            sums[part][0] += c.sum(axis=0)
            sums[part][1] += np.einsum("pic,pjc->ijc", c, c)
    atmosphere, atmosphere_cov = _mean_and_cov(*sums["atmosphere"], paths)
    ground, ground_cov = _mean_and_cov(*sums["ground"], paths)
    return OrderRadiance(atmosphere, ground, atmosphere_cov, ground_cov, paths)
