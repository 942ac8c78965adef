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
    sun line crosses; 1 above the layer and with the sun down.

    Every march step of every pixel pays for this, and the compositor pays per node for the
    whole image (only nodes fed by frame values alone cost a single value): so the map
    coordinates are one vector expression, uv = (P + (middle - P_z) sun / sun_z + offset) /
    tile with z = 1 (Map UV reads z as alpha), the coverage threshold and the clamp are one
    clamped Math node (thickness_fraction) and the exponent's factors one product: 12 image-wide nodes a step against
    24 before. (What that saves was within the timing noise of bench/bench_clouds.py at one
    sample, where the clouds add 0-30% to a 3-4 s pass on two cores.)"""
    sx, sy, sz = g.separate(sun)
    threshold, middle, optical_depth = g.separate(layer_row)
    inverse_tile, offset_x, offset_y = g.separate(map_row)
    sun_up = g.math("GREATER_THAN", sz, 0.0)
    along_sun = g.div(inverse_tile, g.math("MAXIMUM", sz, 1e-6))
    rise = g.sub(middle, g.separate(point)[2])
    uv = g.vmath("ADD", g.vmath("MULTIPLY_ADD", point, g.combine(inverse_tile, inverse_tile, 0.0),
                                g.combine(g.mul(offset_x, inverse_tile), g.mul(offset_y, inverse_tile), 1.0)),
                 g.vscale(g.combine(g.mul(sx, along_sun), g.mul(sy, along_sun), 0.0), rise))
    fraction = thickness_fraction(g, map_image, uv, threshold)
    # exp(-optical depth x fraction / mu_s) where the sun line climbs to the layer with the sun up.
    per_fraction = g.div(g.mul(g.mul(optical_depth, sun_up), -1.0), g.math("MAXIMUM", sz, slab.MIN_COS))
    below = g.math("GREATER_THAN", rise, 0.0)
    return g.math("EXPONENT", g.mul(g.mul(fraction, per_fraction), below))


def march_distance(g, camera, direction, layer_row, earth_radius: float):
    """Distance from the camera along unit ``direction`` to the layer's middle, at most
    SHAFT_RANGE; 0 where the ray does not meet it."""
    middle = g.separate(layer_row)[1]
    height = g.math("MAXIMUM", g.separate(camera)[2], 0.0)
    distance, meets, _ = middle_hit(g, height, middle, g.separate(direction)[2], earth_radius)
    return g.mul(g.math("MINIMUM", distance, shafts.SHAFT_RANGE), meets)
