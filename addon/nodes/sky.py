""""OLS Sky": the world shader. Sky radiance from the multiple-scattering atlas for the view
direction and the camera altitude, times the extraterrestrial sun strength and the scattering
scale, plus the sun disc attenuated by the atmosphere (camera rays only: the Sun lamp already
lights the scene). Twin: lut_gen.Luts.sky_radiance (+ transmittance_to_top for the disc).

The local zenith is +Z: the camera is assumed within a few km of the origin, where the Earth's
curvature tilts the zenith by less than 0.05 deg.
"""
from __future__ import annotations

import math

from .builder import group_io, new_group
from .lookup import GROUP_NAME as LOOKUP_GROUP
from .optical import transmittance_to_top

GROUP_NAME = "OLS Sky"
INPUTS = [
    ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)),   # unit vector toward the sun
    ("Camera Height", "NodeSocketFloat", 2.0),                # metres above the ground
    ("Sun Strength", "NodeSocketFloat", 10.0),                # extraterrestrial, the lamp's Strength
    ("Scattering Scale", "NodeSocketFloat", 0.5),             # the sample's scattering scale
    ("Sun Angle", "NodeSocketFloat", math.radians(0.545)),    # apparent diameter (lamp's Angle)
    ("Light Scene", "NodeSocketFloat", 1.0),                  # 0: sky seen by camera/glossy rays only
]


def build_sky_group(optical_depth_image, params):
    tree = new_group(GROUP_NAME)
    g, gin, gout = group_io(tree, INPUTS, [("Color", "NodeSocketColor", None), ("Background", "NodeSocketShader", None)])
    view = g.vmath("NORMALIZE", g.node("ShaderNodeTexCoord").outputs["Generated"])
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    cos_view = g.separate(view)[2]
    cos_sun = g.separate(sun)[2]
    cos_sun_view = g.vmath("DOT_PRODUCT", view, sun)
    height = g.math("MAXIMUM", gin.outputs["Camera Height"], 0.0)

    lookup = g.node("ShaderNodeGroup")
    lookup.node_tree = tree_or_fail(LOOKUP_GROUP)
    for name, value in (("Height", height), ("Cos View Zenith", cos_view), ("Cos Sun Zenith", cos_sun),
                        ("Cos Sun View", cos_sun_view)):
        g.feed(lookup.inputs[name], value)
    strength = gin.outputs["Sun Strength"]
    sky = g.vscale(lookup.outputs["Radiance"], g.mul(strength, gin.outputs["Scattering Scale"]))

    # Sun disc: radiance = irradiance / solid angle of a disc of the lamp's apparent size.
    radius = g.mul(gin.outputs["Sun Angle"], 0.5)
    solid_angle = g.mul(g.sub(1.0, g.math("COSINE", radius)), 2 * math.pi)
    in_disc = g.math("GREATER_THAN", cos_sun_view, g.math("COSINE", radius))
    disc = g.vscale(transmittance_to_top(g, optical_depth_image, height, cos_sun, params),
                    g.div(g.mul(strength, in_disc), g.math("MAXIMUM", solid_angle, 1e-9)))
    light_path = g.node("ShaderNodeLightPath")
    camera = light_path.outputs["Is Camera Ray"]
    seen = g.vmath("ADD", sky, g.vscale(disc, camera))
    # Non-camera rays see the sky scaled by "Light Scene" (glossy rays always see it).
    lit = g.math("MAXIMUM", g.math("MAXIMUM", camera, light_path.outputs["Is Glossy Ray"]),
                 gin.outputs["Light Scene"])
    color = g.vscale(seen, lit)
    background = g.node("ShaderNodeBackground")
    g.feed(background.inputs["Color"], color)
    g.feed(background.inputs["Strength"], 1.0)
    g.links.new(g.vmath("ADD", sky, disc), gout.inputs["Color"])
    g.links.new(background.outputs[0], gout.inputs["Background"])
    return tree


def tree_or_fail(name):
    import bpy
    tree = bpy.data.node_groups.get(name)
    if tree is None:
        raise RuntimeError(f"node group {name!r} is missing; build the look-up group first")
    return tree
