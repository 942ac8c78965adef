""""OLS Terrain": the material group of the sample's terrain shader.

Per shading point: the sun's extinction from the optical-depth table (relative to the scene
origin, whose extinction the Sun lamp's colour already carries, so the renderer's own lamp
lighting and shadows still apply) and the ambient skylight from the 1D table with the ground
occlusion factor saturate((1 + N . up) / 2) of Yusov 2013's terrain snippet, emitted as the
Lambertian radiance albedo * E / pi. Twin: lut_gen.passes.terrain.terrain_radiance.
"""
from __future__ import annotations

import math

from .builder import group_io, new_group
from .optical import ambient_skylight, point_frame, transmittance_to_top
from ..scene import names

INPUTS = [
    ("Albedo", "NodeSocketColor", (0.2, 0.2, 0.2, 1.0)),
    ("Normal", "NodeSocketVector", (0.0, 0.0, 0.0)),          # zero: use the shading normal
    ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)),
    ("Sun Strength", "NodeSocketFloat", 10.0),
    ("Origin Transmittance", "NodeSocketColor", (1.0, 1.0, 1.0, 1.0)),   # the lamp's colour
    ("Ambient Strength", "NodeSocketFloat", 1.0),
]
MIN_ORIGIN_TRANSMITTANCE = 1e-6


def build_terrain_group(optical_depth_image, ambient_image, params):
    tree = new_group(names.TERRAIN_GROUP)
    g, gin, gout = group_io(tree, INPUTS, [("Shader", "NodeSocketShader", None)])
    geometry = g.node("ShaderNodeNewGeometry")
    # Normal input if connected/non-zero, else the shading normal.
    given = gin.outputs["Normal"]
    has_normal = g.math("GREATER_THAN", g.vmath("LENGTH", given), 0.5)
    normal = g.vmath("NORMALIZE", g.vlerp(geometry.outputs["Normal"], given, has_normal))

    height, up = point_frame(g, geometry.outputs["Position"], params)
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    cos_sun = g.vmath("DOT_PRODUCT", up, sun)

    extinction = transmittance_to_top(g, optical_depth_image, height, cos_sun, params)
    origin = g.vmath("MAXIMUM", gin.outputs["Origin Transmittance"], (MIN_ORIGIN_TRANSMITTANCE,) * 3)
    albedo = gin.outputs["Albedo"]
    diffuse = g.node("ShaderNodeBsdfDiffuse")
    g.feed(diffuse.inputs["Color"], g.vmath("MULTIPLY", albedo, g.vmath("DIVIDE", extinction, origin)))
    g.feed(diffuse.inputs["Normal"], normal)

    occlusion = g.clamp(g.mul_add(g.vmath("DOT_PRODUCT", normal, up), 0.5, 0.5), 0.0, 1.0)
    sky_light = g.vscale(ambient_skylight(g, ambient_image, cos_sun),
                         g.div(g.mul(g.mul(gin.outputs["Sun Strength"], occlusion), gin.outputs["Ambient Strength"]),
                               math.pi))
    emission = g.node("ShaderNodeEmission")
    g.feed(emission.inputs["Color"], g.vmath("MULTIPLY", albedo, sky_light))
    g.feed(emission.inputs["Strength"], 1.0)
    add = g.node("ShaderNodeAddShader")
    g.links.new(diffuse.outputs[0], add.inputs[0])
    g.links.new(emission.outputs[0], add.inputs[1])
    g.links.new(add.outputs[0], gout.inputs["Shader"])
    return tree
