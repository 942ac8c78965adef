""""OLS Cloud Shadow": the material group of the shadow-only cloud layer. Shadow rays toward the
sun take the cloud column's transmittance at the point they cross the layer; every other ray
passes (the plane is also invisible to camera, diffuse and glossy rays by its object's
visibility). Twin: lut_gen.clouds.shadow.sun_transmittance.
"""
from __future__ import annotations

from ...lut_gen.clouds import slab
from ..scene import names
from .builder import group_io, new_group
from .clouds import column_fraction

INPUTS = [
    ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)),
    ("Coverage", "NodeSocketFloat", 0.4),
    ("Thickness", "NodeSocketFloat", 600.0),
    ("Density", "NodeSocketFloat", 20.0 / 600.0),
    ("Scale", "NodeSocketFloat", 2000.0),
    ("Offset", "NodeSocketVector", (0.0, 0.0, 0.0)),
]
# Shadow rays within this angle of the sun's direction are the sun's (the disc is 0.27 deg in
# radius; a soft sun up to ~8 deg across still counts).
SUN_RAY_COS = 0.99


def build_cloud_shadow_group(map_image):
    tree = new_group(names.CLOUD_SHADOW_GROUP)
    g, gin, gout = group_io(tree, INPUTS, [("Shader", "NodeSocketShader", None)])
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    geometry = g.node("ShaderNodeNewGeometry")
    x, y, _ = g.separate(geometry.outputs["Position"])
    fraction = column_fraction(g, map_image, x, y, gin.outputs["Scale"], gin.outputs["Offset"], gin.outputs["Coverage"])
    tau = g.mul(g.mul(gin.outputs["Density"], gin.outputs["Thickness"]), fraction)
    mu_s = g.math("MAXIMUM", g.separate(sun)[2], slab.MIN_COS)
    transmittance = g.math("EXPONENT", g.div(g.mul(tau, -1.0), mu_s))
    # "Incoming" points back along the ray: a shadow ray toward the sun has it opposite the sun.
    toward_sun = g.math("LESS_THAN", g.vmath("DOT_PRODUCT", geometry.outputs["Incoming"], sun), -SUN_RAY_COS)
    shadow_ray = g.node("ShaderNodeLightPath").outputs["Is Shadow Ray"]
    weight = g.mul(toward_sun, shadow_ray)
    passed = g.select(1.0, transmittance, weight)
    bsdf = g.node("ShaderNodeBsdfTransparent")
    g.feed(bsdf.inputs["Color"], g.combine(passed, passed, passed))
    g.links.new(bsdf.outputs[0], gout.inputs["Shader"])
    return tree
