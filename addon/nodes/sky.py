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


def build_sky_group(optical_depth_image, params, skylight_image):
    """``skylight_image``: the sky for the current sun and camera height as an equirectangular
    panorama (scene/skylight.py keeps it current). Camera rays evaluate the exact 4D look-up;
    every other ray (lighting, reflections, EEVEE's world probe) reads the panorama, which costs
    one texture fetch: Cycles skips the unused branch of a Mix Shader."""
    tree = new_group(GROUP_NAME)
    g, gin, gout = group_io(tree, INPUTS, [("Color", "NodeSocketColor", None), ("Background", "NodeSocketShader", None)])
    view = g.vmath("NORMALIZE", g.node("ShaderNodeTexCoord").outputs["Generated"])
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    view_x, view_y, cos_view = g.separate(view)
    cos_sun = g.separate(sun)[2]
    cos_sun_view = g.vmath("DOT_PRODUCT", view, sun)
    height = g.math("MAXIMUM", gin.outputs["Camera Height"], 0.0)
    strength = gin.outputs["Sun Strength"]
    sky_scale = g.mul(strength, gin.outputs["Scattering Scale"])

    lookup = g.node("ShaderNodeGroup")
    lookup.node_tree = tree_or_fail(LOOKUP_GROUP)
    for name, value in (("Height", height), ("Cos View Zenith", cos_view), ("Cos Sun Zenith", cos_sun),
                        ("Cos Sun View", cos_sun_view)):
        g.feed(lookup.inputs[name], value)
    sky = g.vscale(lookup.outputs["Radiance"], sky_scale)

    # Sun disc: radiance = irradiance / solid angle of a disc of the lamp's apparent size.
    radius = g.mul(gin.outputs["Sun Angle"], 0.5)
    solid_angle = g.mul(g.sub(1.0, g.math("COSINE", radius)), 2 * math.pi)
    in_disc = g.math("GREATER_THAN", cos_sun_view, g.math("COSINE", radius))
    disc = g.vscale(transmittance_to_top(g, optical_depth_image, height, cos_sun, params),
                    g.div(g.mul(strength, in_disc), g.math("MAXIMUM", solid_angle, 1e-9)))
    camera_view = g.node("ShaderNodeBackground")
    g.feed(camera_view.inputs["Color"], g.vmath("ADD", sky, disc))

    # Other rays: the panorama; diffuse/scatter rays only when "Light Scene" (glossy always).
    azimuth = g.math("ARCTAN2", view_x, view_y)
    elevation = g.math("ARCSINE", g.clamp(cos_view, -1.0, 1.0))
    uv = g.combine(g.add(g.div(azimuth, 2 * math.pi), 0.5), g.add(g.div(elevation, math.pi), 0.5), 0.0)
    panorama = g.node("ShaderNodeTexImage", image=skylight_image, interpolation="Linear", extension="REPEAT")
    g.feed(panorama.inputs["Vector"], uv)
    light_path = g.node("ShaderNodeLightPath")
    lit = g.math("MAXIMUM", light_path.outputs["Is Glossy Ray"], gin.outputs["Light Scene"])
    lighting = g.node("ShaderNodeBackground")
    g.feed(lighting.inputs["Color"], g.vscale(panorama.outputs["Color"], g.mul(sky_scale, lit)))

    mix = g.node("ShaderNodeMixShader")
    g.feed(mix.inputs["Fac"], light_path.outputs["Is Camera Ray"])
    g.links.new(lighting.outputs[0], mix.inputs[1])
    g.links.new(camera_view.outputs[0], mix.inputs[2])
    g.links.new(g.vmath("ADD", sky, disc), gout.inputs["Color"])
    g.links.new(mix.outputs[0], gout.inputs["Background"])
    return tree


def tree_or_fail(name):
    import bpy
    tree = bpy.data.node_groups.get(name)
    if tree is None:
        raise RuntimeError(f"node group {name!r} is missing; build the look-up group first")
    return tree
