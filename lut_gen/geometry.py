"""Spherical-Earth ray geometry shared by the baker, the look-ups and the reference."""
from __future__ import annotations

import numpy as np


def distance_to_sphere_exit(r, cos_zenith, sphere_radius):
    """Distance along the ray from radius r (inside the sphere) to where it leaves the sphere."""
    disc = r * r * (cos_zenith * cos_zenith - 1.0) + sphere_radius * sphere_radius
    return np.maximum(-r * cos_zenith + np.sqrt(np.maximum(disc, 0.0)), 0.0)


def ray_length(params, r, cos_zenith, hits_ground):
    """Length of a view ray inside the atmosphere; ``hits_ground`` selects the ground end
    (the table's horizon flag), which keeps grazing rays on their own side of the seam."""
    to_top = distance_to_sphere_exit(r, cos_zenith, params.top_radius)
    disc = r * r * (cos_zenith * cos_zenith - 1.0) + params.earth_radius ** 2
    to_ground = np.maximum(-r * cos_zenith - np.sqrt(np.maximum(disc, 0.0)), 0.0)
    return np.where(hits_ground, np.minimum(to_ground, to_top), to_top)


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
