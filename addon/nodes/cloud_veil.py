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


STEP_INPUTS = [
    ("Camera Position", "NodeSocketVector", (0.0, 0.0, 2.0)),
    ("Segment", "NodeSocketVector", (0.0, 0.0, 0.0)),        # surface - camera
    ("Enter", "NodeSocketFloat", 0.0),                         # the band's part of the segment
    ("Span", "NodeSocketFloat", 0.0),
    ("Step", "NodeSocketFloat", 0.0),                          # the step's index
    ("Step Length", "NodeSocketFloat", 0.0),                   # metres
    ("Mu Sun", "NodeSocketFloat", 1.0),
    ("Phase", "NodeSocketFloat", 0.0),
    ("View Z", "NodeSocketFloat", 0.0),
] + LAYER_INPUTS + [
    ("Cloud Shape", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Cloud Sun", "NodeSocketVector", (0.0, 0.0, 0.0)),
    ("Cloud Ambient", "NodeSocketVector", (0.0, 0.0, 0.0)),
    ("Through", "NodeSocketFloat", 1.0),
    ("Glow", "NodeSocketVector", (0.0, 0.0, 0.0)),
]
# The rows every step reads from the main group's inputs.
_SHARED = ("Camera Position", "Cloud Layer", "Cloud Map", "Cloud Shape", "Cloud Sun", "Cloud Ambient")


def build_cloud_veil_step_group(map_image):
    """"OLS Cloud Veil Step": one of veil.STEPS steps of the march, (Through, Glow) carried on.
    A group of its own so that no tree grows past a thousand links (the editor and the
    compositor's compile time)."""
    tree = new_group(names.CLOUD_VEIL_STEP_GROUP, "CompositorNodeTree")
    g, gin, gout = group_io(tree, STEP_INPUTS, [("Through", "NodeSocketFloat", None), ("Glow", "NodeSocketVector", None)])
    cx, cy, cz = g.separate(gin.outputs["Camera Position"])
    dx, dy, dz = g.separate(gin.outputs["Segment"])
    threshold, middle, _ = g.separate(gin.outputs["Cloud Layer"])
    inverse_tile, offset_x, offset_y = g.separate(gin.outputs["Cloud Map"])
    _, thickness, density = g.separate(gin.outputs["Cloud Shape"])
    enter, span, index = gin.outputs["Enter"], gin.outputs["Span"], gin.outputs["Step"]
    mu_s, up = gin.outputs["Mu Sun"], gin.outputs["View Z"]
    s0 = g.mul_add(span, g.div(index, float(veil.STEPS)), enter)
    s1 = g.mul_add(span, g.div(g.add(index, 1.0), float(veil.STEPS)), enter)
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
    dtau = g.mul(g.mul(density, share), gin.outputs["Step Length"])
    column = g.mul(density, g.sub(top, bottom))
    above = g.mul(density, g.sub(top, g.clamp(centre, bottom, top)))
    depth = g.div(above, g.math("MAXIMUM", column, 1e-9))
    reflected, transmitted = two_stream(g, column, mu_s)
    back, diffuse = diffuse_two_stream(g, column)
    below_top = g.sub(1.0, depth)
    sun_part = g.add(g.mul(gin.outputs["Phase"], g.math("EXPONENT", g.div(g.mul(above, -1.0), mu_s))),
                     toward(g, g.mul(g.mul(depth, transmitted), mu_s), g.mul(g.mul(below_top, reflected), mu_s), up))
    ambient_part = toward(g, g.mul_add(depth, diffuse, below_top), g.mul(below_top, back), up)
    source = g.vmath("ADD", g.vscale(gin.outputs["Cloud Sun"], sun_part), g.vscale(gin.outputs["Cloud Ambient"], ambient_part))
    through = gin.outputs["Through"]
    step_through = g.math("EXPONENT", g.mul(dtau, -1.0))
    glow = g.vmath("ADD", gin.outputs["Glow"], g.vscale(source, g.mul(through, g.sub(1.0, step_through))))
    g.links.new(g.mul(through, step_through), gout.inputs["Through"])
    g.links.new(glow, gout.inputs["Glow"])
    return tree


def build_cloud_veil_group(map_image):
    step_tree = build_cloud_veil_step_group(map_image)
    tree = new_group(names.CLOUD_VEIL_GROUP, "CompositorNodeTree")
    g, gin, gout = group_io(tree, INPUTS, [("Image", "NodeSocketColor", None)])
    camera, point = gin.outputs["Camera Position"], gin.outputs["Position"]
    cz = g.separate(camera)[2]
    d = g.vmath("SUBTRACT", point, camera)
    dz = g.separate(d)[2]
    length = g.vmath("LENGTH", d)
    view = g.vmath("NORMALIZE", d)
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    base, thickness, _ = g.separate(gin.outputs["Cloud Shape"])
    # The segment's parameter range inside the band (a level ray: rise held at 1e-6, so the
    # range is all or nothing as the camera's height lies in the band or not).
    small = g.math("LESS_THAN", g.math("ABSOLUTE", dz), 1e-6)
    rise = g.select(dz, 1e-6, small)
    a, b = g.div(g.sub(base, cz), rise), g.div(g.sub(g.add(base, thickness), cz), rise)
    enter = g.clamp(g.math("MINIMUM", a, b), 0.0, 1.0)
    span = g.sub(g.clamp(g.math("MAXIMUM", a, b), 0.0, 1.0), enter)
    common = {name: gin.outputs[name] for name in _SHARED}
    common.update({"Segment": d, "Enter": enter, "Span": span,
                   "Step Length": g.div(g.mul(span, length), float(veil.STEPS)),
                   "Mu Sun": g.math("MAXIMUM", g.separate(sun)[2], slab.MIN_COS),
                   "Phase": phase(g, g.vmath("DOT_PRODUCT", view, sun)), "View Z": g.separate(view)[2]})
    through, glow = 1.0, (0.0, 0.0, 0.0)
    for k in range(veil.STEPS):
        out = g.group(step_tree, **common, Step=float(k), Through=through, Glow=glow)
        through, glow = out["Through"], out["Glow"]
    geometry = g.math("LESS_THAN", gin.outputs["Depth"], gin.outputs["Sky Depth"])
    kept = g.select(1.0, through, geometry)
    added = g.vscale(glow, g.mul(gin.outputs["Sun Strength"], geometry))
    result = g.vmath("MULTIPLY_ADD", gin.outputs["Image"], g.combine(kept, kept, kept), added)
    g.links.new(g.with_alpha_of(gin.outputs["Image"], result), gout.inputs["Image"])
    return tree
