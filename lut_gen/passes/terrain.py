"""The terrain material's light, in numpy: the twin of the "OLS Terrain" group with the Sun lamp
that renders beside it (the group divides the sun's extinction by the lamp's colour, the
extinction at the scene origin, so lamp x group = the sun through the air above the point).

    radiance = albedo / pi * E_sun * (T_sun(point) max(N . L, 0) + E_sky(cos sun) occlusion(N))

with the ambient skylight from the 1D table and the ground occlusion saturate((1 + N . up) / 2)
of Yusov 2013's terrain shader. Shadows are the renderer's; this twin has none.
"""
from __future__ import annotations

import math

import numpy as np

from ..tables.lookup import Luts


def terrain_radiance(luts: Luts, position, normal, sun_direction, sun_strength: float, albedo) -> np.ndarray:
    """(..., 3) radiance leaving a Lambertian terrain point at ``position`` (world metres, the
    ground at z = 0) with unit ``normal``, lit by the sun toward unit ``sun_direction``."""
    params = luts.params
    position = np.asarray(position, dtype=np.float64)
    normal = np.asarray(normal, dtype=np.float64)
    sun = np.asarray(sun_direction, dtype=np.float64)
    from_centre = position + np.array([0.0, 0.0, params.earth_radius])
    radius = np.linalg.norm(from_centre, axis=-1, keepdims=True)
    height, up = radius[..., 0] - params.earth_radius, from_centre / radius
    cos_sun = np.sum(up * sun, axis=-1)
    direct = luts.transmittance_to_top(height, cos_sun) * np.maximum(np.sum(normal * sun, axis=-1), 0.0)[..., None]
    occlusion = np.clip((1.0 + np.sum(normal * up, axis=-1)) / 2.0, 0.0, 1.0)[..., None]
    ambient = luts.ambient_skylight(cos_sun) * occlusion
    return np.asarray(albedo, dtype=np.float64) / math.pi * sun_strength * (direct + ambient)
