""""OLS Cloud Veil": the compositor group that puts the cloud layer in front of the render's
surfaces, as extra Mie density along the camera -> surface segment (a peak in the cloud is veiled
by it). Twin: lut_gen.clouds.veil.veil and veiled; the reasons are in lut_gen/clouds/veil.py.

It sits between the render's image and the atmosphere groups (which then haze the veiled
surface), and is muted while Clouds is off. The layer and its light arrive as "OLS Frame Values"
rows (lut_gen.clouds.shafts.frame_rows, lut_gen.clouds.veil.frame_rows) written before each
frame, so a keyframed offset moves the veil with the clouds.
"""
from __future__ import annotations

import math

from ...lut_gen.clouds import slab, veil
from ..scene import names
from .builder import group_io, new_group
from .cloud_shafts import INPUTS as LAYER_INPUTS
from .clouds import diffuse_two_stream, phase, thickness_fraction, two_stream

INPUTS = [
    ("Image", "NodeSocketColor", (0.0, 0.0, 0.0, 1.0)),
    ("Position", "NodeSocketVector", (0.0, 0.0, 0.0)),
    ("Depth", "NodeSocketFloat", 1e10),
    ("Sky Depth", "NodeSocketFloat", 1e9),
    ("Camera Position", "NodeSocketVector", (0.0, 0.0, 2.0)),
    ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)),
    ("Sun Strength", "NodeSocketFloat", 10.0),
] + LAYER_INPUTS + [
    ("Cloud Shape", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Cloud Sun", "NodeSocketVector", (0.0, 0.0, 0.0)),
    ("Cloud Ambient", "NodeSocketVector", (0.0, 0.0, 0.0)),
]


def toward(g, down, up, view_z):
    """lut_gen.clouds.veil.toward."""
    return g.div(g.mul_add(g.add(view_z, 1.0), down, g.mul(g.sub(1.0, view_z), up)), 2.0 * math.pi)


def build_cloud_veil_group(map_image):
    tree = new_group(names.CLOUD_VEIL_GROUP, "CompositorNodeTree")
    g, gin, gout = group_io(tree, INPUTS, [("Image", "NodeSocketColor", None)])
    camera, point = gin.outputs["Camera Position"], gin.outputs["Position"]
    cx, cy, cz = g.separate(camera)
    d = g.vmath("SUBTRACT", point, camera)
    dx, dy, dz = g.separate(d)
    length = g.vmath("LENGTH", d)
    view = g.vmath("NORMALIZE", d)
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    threshold, middle, _ = g.separate(gin.outputs["Cloud Layer"])
    inverse_tile, offset_x, offset_y = g.separate(gin.outputs["Cloud Map"])
    base, thickness, density = g.separate(gin.outputs["Cloud Shape"])
    top_of_band = g.add(base, thickness)
    # The segment's parameter range inside the band (a level ray: rise held at 1e-6, so the
    # range is all or nothing as the camera's height lies in the band or not).
    small = g.math("LESS_THAN", g.math("ABSOLUTE", dz), 1e-6)
    rise = g.select(dz, 1e-6, small)
    a, b = g.div(g.sub(base, cz), rise), g.div(g.sub(top_of_band, cz), rise)
    enter = g.clamp(g.math("MINIMUM", a, b), 0.0, 1.0)
    leave = g.clamp(g.math("MAXIMUM", a, b), 0.0, 1.0)
    span = g.sub(leave, enter)
    step_length = g.div(g.mul(span, length), float(veil.STEPS))
    mu_s = g.math("MAXIMUM", g.separate(sun)[2], slab.MIN_COS)
    p = phase(g, g.vmath("DOT_PRODUCT", view, sun))
    up = g.separate(view)[2]
    sun_light, ambient = gin.outputs["Cloud Sun"], gin.outputs["Cloud Ambient"]
    through, glow = 1.0, None
    for k in range(veil.STEPS):
        s0 = g.mul_add(span, k / veil.STEPS, enter)
        s1 = g.mul_add(span, (k + 1) / veil.STEPS, enter)
        mid = g.mul(g.add(s0, s1), 0.5)
        x, y = g.mul_add(dx, mid, cx), g.mul_add(dy, mid, cy)
        z0, z1 = g.mul_add(dz, s0, cz), g.mul_add(dz, s1, cz)
        centre = g.mul(g.add(z0, z1), 0.5)
        half = g.math("MAXIMUM", g.mul(g.math("ABSOLUTE", g.sub(z1, z0)), 0.5), 0.5 * veil.MIN_RISE)
        u = g.mul(g.add(x, offset_x), inverse_tile)
        v = g.mul(g.add(y, offset_y), inverse_tile)
        # z = 1: the compositor's Map UV reads it as the alpha of what it samples.
        fraction = thickness_fraction(g, map_image, g.combine(u, v, 1.0), threshold)
        slab_half = g.mul(g.mul(thickness, fraction), 0.5)
        bottom, top = g.sub(middle, slab_half), g.add(middle, slab_half)
        overlap = g.sub(g.math("MINIMUM", g.add(centre, half), top), g.math("MAXIMUM", g.sub(centre, half), bottom))
        share = g.clamp(g.div(overlap, g.mul(half, 2.0)), 0.0, 1.0)
        dtau = g.mul(g.mul(density, share), step_length)
        column = g.mul(density, g.sub(top, bottom))
        above = g.mul(density, g.sub(top, g.clamp(centre, bottom, top)))
        depth = g.div(above, g.math("MAXIMUM", column, 1e-9))
        reflected, transmitted = two_stream(g, column, mu_s)
        back, diffuse = diffuse_two_stream(g, column)
        below_top = g.sub(1.0, depth)
        sun_part = g.add(g.mul(p, g.math("EXPONENT", g.div(g.mul(above, -1.0), mu_s))),
                         toward(g, g.mul(g.mul(depth, transmitted), mu_s), g.mul(g.mul(below_top, reflected), mu_s), up))
        ambient_part = toward(g, g.mul_add(depth, diffuse, below_top), g.mul(below_top, back), up)
        source = g.vmath("ADD", g.vscale(sun_light, sun_part), g.vscale(ambient, ambient_part))
        weight = g.mul(through, g.sub(1.0, g.math("EXPONENT", g.mul(dtau, -1.0))))
        term = g.vscale(source, weight)
        glow = term if glow is None else g.vmath("ADD", glow, term)
        through = g.mul(through, g.math("EXPONENT", g.mul(dtau, -1.0)))
    geometry = g.math("LESS_THAN", gin.outputs["Depth"], gin.outputs["Sky Depth"])
    kept = g.select(1.0, through, geometry)
    added = g.vscale(glow, g.mul(gin.outputs["Sun Strength"], geometry))
    result = g.vmath("MULTIPLY_ADD", gin.outputs["Image"], g.combine(kept, kept, kept), added)
    g.links.new(g.with_alpha_of(gin.outputs["Image"], result), gout.inputs["Image"])
    return tree
