"""Spherical-Earth ray geometry shared by the baker, the look-ups and the reference."""
from __future__ import annotations

import numpy as np


def distance_to_sphere_exit(r, cos_zenith, sphere_radius):
    """Distance along the ray from radius r (inside the sphere) to where it leaves the sphere."""
    disc = r * r * (cos_zenith * cos_zenith - 1.0) + sphere_radius * sphere_radius
    return np.maximum(-r * cos_zenith + np.sqrt(np.maximum(disc, 0.0)), 0.0)


# Ground-hitting rays are at least this long in the tables, so that the ground-ray scale
# below never divides by zero (the row of the ground itself, h = 0).
MIN_GROUND_RAY_M = 1e-3
# Length scale of the ground-ray scale: well under the extinction length of every channel.
GROUND_RAY_SCALE_M = 20_000.0
GROUND_DISTANCE_MIN_DENOMINATOR = 1e-3


def distance_to_ground(r, cos_zenith, earth_radius):
    """Distance to the ground along the ray, in the cancellation-free form
    h (2R + h) / (-r c + sqrt(r^2 c^2 - h (2R + h))) (float32-safe, as the node groups need).
    Rays that miss the ground (forced onto the ground half of a table) continue smoothly with
    the square root clamped at 0, and upward ones get a very large distance."""
    r = np.asarray(r, dtype=np.float64)
    c = np.asarray(cos_zenith, dtype=np.float64)
    h = np.maximum(r - earth_radius, 0.0)
    rise = h * (2.0 * earth_radius + h)
    denominator = -r * c + np.sqrt(np.maximum(r * r * c * c - rise, 0.0))
    return rise / np.maximum(denominator, GROUND_DISTANCE_MIN_DENOMINATOR)


def ray_length(params, r, cos_zenith, hits_ground):
    """Length of a view ray inside the atmosphere; ``hits_ground`` selects the ground end
    (the table's horizon flag), which keeps grazing rays on their own side of the seam."""
    to_top = distance_to_sphere_exit(r, cos_zenith, params.top_radius)
    to_ground = np.maximum(distance_to_ground(r, cos_zenith, params.earth_radius), MIN_GROUND_RAY_M)
    return np.where(hits_ground, np.minimum(to_ground, to_top), to_top)


def ground_ray_scale(r, cos_zenith, hits_ground, earth_radius, length=GROUND_RAY_SCALE_M):
    """The factor the 4D tables are divided by: S(d) = l (1 - exp(-d / l)) for rays on the
    ground half of the view axis (d: their length, at least MIN_GROUND_RAY_M), 1 for the others.

    In-scattered light along a short ground ray grows like its length d, which falls to 0 at
    the ground as h / cos; interpolating it across the height nodes (0, 83 m, 333 m, ...) made
    the rays of a camera a few metres up 2x to 7x too bright. L / S(d) tends to the scattering
    density at the ray start instead, which interpolates well; S saturates for long rays,
    whose radiance does too. ``length``: l, GROUND_RAY_SCALE_M or shorter (in fog, see
    parameterization.ground_ray_length)."""
    d = np.maximum(distance_to_ground(r, cos_zenith, earth_radius), MIN_GROUND_RAY_M)
    scale = length * -np.expm1(-d / length)
    return np.where(hits_ground, scale, 1.0)


def radius_along(r, cos_zenith, s):
    """Distance to the Earth centre at distance s along the ray."""
    return np.sqrt(np.maximum(r * r + s * s + 2.0 * r * cos_zenith * s, 0.0))


def clustered_nodes(r, cos_zenith, length, n: int, uniform_share: float = 0.0):
    """(..., n) distances in [0, length], denser near the lowest point of the ray.

    The lowest point is the start for upward rays, the end for rays that reach the ground and
    the tangent point otherwise; density (and so the integrand) peaks there. The mapping is a
    quadratic on each side of that point, so node counts follow the side's share of the ray;
    ``uniform_share`` blends in evenly spaced nodes so that no stretch of the ray is left coarse.
    """
    r, cos_zenith, length = np.broadcast_arrays(np.asarray(r, float), np.asarray(cos_zenith, float), np.asarray(length, float))
    s_low = np.clip(-r * cos_zenith, 0.0, length)[..., None]
    total = np.maximum(length, 1e-9)[..., None]
    a = s_low / total
    t = np.linspace(0.0, 1.0, n)
    before = t <= a
    # Distance from the lowest point in units of its side of the ray, squared: the quadratic
    # clustering on both sides in one expression.
    q = (t - a) / np.where(before, np.maximum(a, 1e-12), np.maximum(1.0 - a, 1e-12))
    s = s_low + np.where(before, -s_low, total - s_low) * (q * q)
    if uniform_share:
        s = s * (1.0 - uniform_share) + uniform_share * t * total
    s[..., 0] = 0.0
    s[..., -1] = length
    return s
