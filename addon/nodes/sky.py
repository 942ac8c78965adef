""""OLS Sky": the world shader. Sky radiance from the multiple-scattering atlas for the view
direction and the camera altitude, plus the camera's twilight correction (nodes/sky_view.py),
times the extraterrestrial sun strength and the scattering scale; the lit ground below the
horizon (times the sun strength, like the terrain) and the limb-darkened sun disc attenuated by
the atmosphere (camera rays only: the Sun lamp already lights the scene). Twin:
lut_gen.passes.sky_view.camera_sky + Luts.ground_radiance (+ transmittance_to_top and
lut_gen.model.sun_disc for the disc).

The local zenith is +Z: the camera is assumed within a few km of the origin, where the Earth's
curvature tilts the zenith by less than 0.05 deg.
"""
from __future__ import annotations

import math

import bpy

from ...lut_gen.model import sun_disc
from .builder import group_io, new_group
from .clouds import INPUTS as _CLOUD_GROUP_INPUTS
from .optical import below_horizon, ground_radiance, transmittance_to_top
from .sky_view import correction as twilight_correction
from ..scene import names

# The cloud group's settings, fed through as "Cloud <name>" inputs of the sky group.
CLOUD_INPUTS = [item for item in _CLOUD_GROUP_INPUTS if item[0] not in {"View", "Sun Direction", "Camera Height", "Camera XY"}]

INPUTS = [
    ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)),   # unit vector toward the sun
    ("Camera Height", "NodeSocketFloat", 2.0),                # metres above the ground
    ("Sun Strength", "NodeSocketFloat", 10.0),                # extraterrestrial, the lamp's Strength
    ("Scattering Scale", "NodeSocketFloat", 0.5),             # the sample's scattering scale
    ("Sun Angle", "NodeSocketFloat", math.radians(0.545)),    # apparent diameter (lamp's Angle)
    ("Light Scene", "NodeSocketFloat", 1.0),                  # 0: sky seen by camera/glossy rays only
    ("Clouds", "NodeSocketFloat", 0.0),                       # 1: the cloud layer is on
    ("Light Shafts", "NodeSocketFloat", 0.0),                 # 1: the shafts pass redoes the air's single scattering
    ("Camera XY", "NodeSocketVector", (0.0, 0.0, 0.0)),       # the camera's world x, y (clouds only)
    *[(f"Cloud {name}", kind, default) for name, kind, default in CLOUD_INPUTS],
]


def limb_darkened_disc(g, cos_sun_view, angle):
    """lut_gen.model.sun_disc.limb_profile / solid angle: disc radiance per unit irradiance."""
    radius = g.mul(angle, 0.5)
    rho = g.div(g.math("ARCCOSINE", g.clamp(cos_sun_view, -1.0, 1.0)), g.math("MAXIMUM", radius, 1e-9))
    mu = g.math("SQRT", g.math("MAXIMUM", g.sub(1.0, g.mul(rho, rho)), 0.0))
    inside = g.math("LESS_THAN", rho, 1.0)
    solid_angle = g.math("MAXIMUM", g.mul(g.sub(1.0, g.math("COSINE", radius)), 2 * math.pi), 1e-12)
    per_channel = [g.mul(g.math("POWER", mu, alpha), (alpha + 2.0) / 2.0) for alpha in sun_disc.LIMB_DARKENING_ALPHA]
    return g.vscale(g.combine(*per_channel), g.div(inside, solid_angle))


def _background(g, color):
    node = g.node("ShaderNodeBackground")
    g.feed(node.inputs["Color"], color)
    return node.outputs[0]


def _only_where(g, weight, shader):
    """``shader`` where ``weight`` (0 or 1) is 1, no closure where it is 0: Cycles then skips
    the nodes only ``shader`` needs."""
    mix = g.node("ShaderNodeMixShader")
    g.feed(mix.inputs["Fac"], weight)
    g.links.new(shader, mix.inputs[2])
    return mix.outputs[0]


def _add_shaders(g, *shaders):
    total = shaders[0]
    for shader in shaders[1:]:
        add = g.node("ShaderNodeAddShader")
        g.links.new(total, add.inputs[0])
        g.links.new(shader, add.inputs[1])
        total = add.outputs[0]
    return total


def _cloudy(g, gin, clouds_tree, view, sun, height, sky, disc, ground, strength, sky_scale):
    """(sky, disc, ground) with the cloud layer: lut_gen.clouds.sky.composite (camera rays:
    light_shafts is the "Light Shafts" input), and what lies behind a cloud (the disc; the
    ground, seen from above the layer) dimmed by it."""
    node = g.node("ShaderNodeGroup")
    node.node_tree = clouds_tree
    g.feed(node.inputs["View"], view)
    g.feed(node.inputs["Sun Direction"], sun)
    g.feed(node.inputs["Camera Height"], height)
    g.feed(node.inputs["Camera XY"], gin.outputs["Camera XY"])
    for name, _, _ in CLOUD_INPUTS:
        g.feed(node.inputs[name], gin.outputs[f"Cloud {name}"])
    alpha, light, behind, shade, shade_single = (node.outputs[name] for name in (
        "Alpha", "Light", "Sky Behind", "Air Shade", "Air Shade Single"))
    taken = g.vmath("ADD", g.vscale(behind, alpha),
                    g.vmath("ADD", shade, g.vscale(shade_single, g.sub(1.0, g.clamp(gin.outputs["Light Shafts"], 0.0, 1.0)))))
    cloud_light = g.vmath("SUBTRACT", g.vscale(light, strength), g.vscale(taken, sky_scale))
    clear = g.sub(1.0, alpha)
    return (g.vmath("ADD", sky, cloud_light), g.vscale(disc, clear), g.vscale(ground, clear))


def build_sky_group(optical_depth_image, params, skylight_image, ambient_image, ground_light_image, clouds_tree=None,
                    *, sky_view_image):
    """``skylight_image`` and ``ground_light_image``: the sky and the lit ground for the current
    sun and camera height as equirectangular panoramas, ``sky_view_image`` the camera's twilight
    correction (lut_gen.passes.sky_view; scene/frame/skylight.py keeps all three current).
    Camera rays evaluate the exact 4D look-up and ground term; every other ray (lighting,
    reflections, EEVEE's world probe) reads the panoramas, two texture fetches: Cycles skips the
    unused branch of a Mix Shader."""
    tree = new_group(names.SKY_GROUP)
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
    lookup.node_tree = tree_or_fail(names.LOOKUP_GROUP)
    for name, value in (("Height", height), ("Cos View Zenith", cos_view), ("Cos Sun Zenith", cos_sun),
                        ("Cos Sun View", cos_sun_view)):
        g.feed(lookup.inputs[name], value)
    radiance = g.vmath("ADD", lookup.outputs["Radiance"],
                       twilight_correction(g, sky_view_image, height, cos_view, cos_sun, cos_sun_view, params,
                                           lookup.node_tree.get(names.FILTERING_KEY, "HARDWARE")))
    sky = g.vscale(radiance, sky_scale)

    # Sun disc: the attenuated irradiance spread over a limb-darkened disc of the lamp's size.
    disc = g.vmath("MULTIPLY", transmittance_to_top(g, optical_depth_image, height, cos_sun, params),
                   g.vscale(limb_darkened_disc(g, cos_sun_view, gin.outputs["Sun Angle"]), strength))
    ground = g.vscale(ground_radiance(g, optical_depth_image, ambient_image, height, cos_view, cos_sun,
                                      cos_sun_view, params), strength)
    camera_color = g.vmath("ADD", g.vmath("ADD", sky, disc), ground)
    # Camera rays: the sky, plus the disc and the ground each as a closure that only the rays
    # that see it evaluate (Cycles skips the side of a Mix Shader whose weight is 0; the
    # ground's term cost 0.17 s and the disc's 0.1 s of the sample's 5 s render otherwise).
    below = below_horizon(g, g.clamp(height, 0.0, params.atmosphere_height), cos_view, params)
    on_disc = g.math("GREATER_THAN", cos_sun_view, g.math("COSINE", g.mul(gin.outputs["Sun Angle"], 0.5)))
    camera_view = _add_shaders(g, _background(g, sky), _only_where(g, on_disc, _background(g, disc)),
                               _only_where(g, below, _background(g, ground)))
    if clouds_tree is not None:
        # Clouds off: the clear closure alone, and Cycles skips every cloud node.
        on = g.clamp(gin.outputs["Clouds"], 0.0, 1.0)
        cloudy_sky, cloudy_disc, cloudy_ground = _cloudy(g, gin, clouds_tree, view, sun, height, sky, disc, ground,
                                                         strength, sky_scale)
        cloudy_view = _add_shaders(g, _background(g, cloudy_sky),
                                   _only_where(g, on_disc, _background(g, cloudy_disc)),
                                   _only_where(g, below, _background(g, cloudy_ground)))
        camera_view = _add_shaders(g, _only_where(g, g.sub(1.0, on), camera_view), _only_where(g, on, cloudy_view))

    # Other rays: the panorama; diffuse/scatter rays only when "Light Scene" (glossy always).
    azimuth = g.math("ARCTAN2", view_x, view_y)
    elevation = g.math("ARCSINE", g.clamp(cos_view, -1.0, 1.0))
    uv = g.combine(g.add(g.div(azimuth, 2 * math.pi), 0.5), g.add(g.div(elevation, math.pi), 0.5), 0.0)
    panorama = g.node("ShaderNodeTexImage", image=skylight_image, interpolation="Linear", extension="REPEAT")
    g.feed(panorama.inputs["Vector"], uv)
    ground_light = g.node("ShaderNodeTexImage", image=ground_light_image, interpolation="Linear", extension="REPEAT")
    g.feed(ground_light.inputs["Vector"], uv)
    light_path = g.node("ShaderNodeLightPath")
    lit = g.math("MAXIMUM", light_path.outputs["Is Glossy Ray"], gin.outputs["Light Scene"])
    lighting = g.node("ShaderNodeBackground")
    surroundings = g.vmath("ADD", g.vscale(panorama.outputs["Color"], sky_scale),
                           g.vscale(ground_light.outputs["Color"], strength))
    g.feed(lighting.inputs["Color"], g.vscale(surroundings, lit))

    mix = g.node("ShaderNodeMixShader")
    g.feed(mix.inputs["Fac"], light_path.outputs["Is Camera Ray"])
    g.links.new(lighting.outputs[0], mix.inputs[1])
    g.links.new(camera_view, mix.inputs[2])
    g.links.new(camera_color, gout.inputs["Color"])
    g.links.new(mix.outputs[0], gout.inputs["Background"])
    return tree


def tree_or_fail(name):
    tree = bpy.data.node_groups.get(name)
    if tree is None:
        raise RuntimeError(f"node group {name!r} is missing; build the look-up group first")
    return tree
