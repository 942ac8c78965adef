"""The cloud layer in the light-shaft compositor groups: the sun's transmittance through the
cloud column over a march point (in "OLS Shadow Test") and how far a sky pixel's march runs to
the layer (in "OLS Light Shafts"). Twins: lut_gen.clouds.shadow.ground_transmittance and
lut_gen.clouds.shafts.march_distance; the reasons are in lut_gen/clouds/shafts.py.

The layer arrives as the two "OLS Frame Values" rows of lut_gen.clouds.shafts.frame_rows,
written before each frame, so a keyframed offset reaches every render (compositor inputs set
from handlers arrive a frame late in animations).
"""
from __future__ import annotations

from ...lut_gen.clouds import shafts, slab
from .clouds import middle_hit, thickness_fraction

INPUTS = [("Cloud Layer", "NodeSocketVector", (2.0, 0.0, 0.0)), ("Cloud Map", "NodeSocketVector", (0.0, 0.0, 0.0))]


def sun_transmittance(g, map_image, point, sun, layer_row, map_row):
    """Transmittance toward the unit ``sun`` through the cloud column whose middle the point's
    sun line crosses; 1 above the layer and with the sun down."""
    px, py, pz = g.separate(point)
    sx, sy, sz = g.separate(sun)
    threshold, middle, optical_depth = g.separate(layer_row)
    inverse_tile, offset_x, offset_y = g.separate(map_row)
    rise = g.div(g.sub(middle, pz), g.math("MAXIMUM", sz, 1e-6))
    u = g.mul(g.add(g.mul_add(rise, sx, px), offset_x), inverse_tile)
    v = g.mul(g.add(g.mul_add(rise, sy, py), offset_y), inverse_tile)
    # z = 1: the compositor's Map UV reads it as the alpha of what it samples (addon/nodes/optical.py).
    fraction = thickness_fraction(g, map_image, g.combine(u, v, 1.0), threshold)
    transmittance = g.math("EXPONENT", g.div(g.mul(g.mul(optical_depth, fraction), -1.0),
                                             g.math("MAXIMUM", sz, slab.MIN_COS)))
    applies = g.mul(g.math("GREATER_THAN", rise, 0.0), g.math("GREATER_THAN", sz, 0.0))
    return g.select(1.0, transmittance, applies)


def march_distance(g, camera, direction, layer_row, earth_radius: float):
    """Distance from the camera along unit ``direction`` to the layer's middle, at most
    SHAFT_RANGE; 0 where the ray does not meet it."""
    middle = g.separate(layer_row)[1]
    height = g.math("MAXIMUM", g.separate(camera)[2], 0.0)
    distance, meets, _ = middle_hit(g, height, middle, g.separate(direction)[2], earth_radius)
    return g.mul(g.math("MINIMUM", distance, shafts.SHAFT_RANGE), meets)
