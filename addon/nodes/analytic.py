"""The analytic model's node groups (Hoffman & Preetham, lut_gen.model.analytic): no tables and
no images.

The numbers of the media (coefficients, g, optical lengths, albedo, the ambient skylight's nodes)
live in two small groups of constants, "OLS Analytic Media" (shader) and its compositor twin;
the sky, terrain and aerial groups read them through a group node. A slider change rebuilds
only those (some 40 nodes), not the ~1500 nodes of formula: the groups' structure never depends
on the media.

The formula groups are built under the precomputed groups' names ("OLS Sky", "OLS Aerial
Perspective", "OLS Terrain") with the same interfaces, so the world, the compositor, the
materials, their drivers and the frame values are wired the same way under either model; only
what the groups compute differs. Inputs only the precomputed groups use (the clouds, "Light
Shafts") are accepted and ignored. Twins: lut_gen.model.analytic.media, sky_parts,
aerial_perspective and terrain_radiance.
"""
from __future__ import annotations

import math

import bpy

from ...lut_gen.model import analytic
from .aerial import INPUTS as AERIAL_INPUTS
from .builder import group_io, new_group
from .sky import INPUTS as SKY_INPUTS, limb_darkened_disc
from .terrain import INPUTS as TERRAIN_INPUTS, MIN_ORIGIN_TRANSMITTANCE
from ..scene import names

# Below this optical depth (1 - exp(-x)) / x is its series: float32 loses 1 - exp(-x) to
# cancellation (x = 1e-5, a metre of air: 0.6% off).
SERIES_BELOW = 1e-2
# exp's argument floor, as optical.transmittance_from_net_density keeps it.
MAX_DEPTH = 80.0

MEDIA_VECTORS = ("Rayleigh", "Haze Scattering", "Haze Extinction")
MEDIA_FLOATS = ("G", "Air Length", "Haze Length", "Ground Albedo")


def _ambient_socket(k: int) -> str:
    return f"Ambient {k}"


def media_outputs(compositor: bool):
    vectors = list(MEDIA_VECTORS) + ([] if compositor else [_ambient_socket(k) for k in range(analytic.AMBIENT_NODES)])
    return [(name, "NodeSocketVector", None) for name in vectors] + [(name, "NodeSocketFloat", None) for name in MEDIA_FLOATS]


def build_media_group(params, compositor: bool = False):
    """The media of ``params`` as constants (analytic.media; the shader group also the ambient
    skylight's nodes, analytic.ambient_table). Rebuilt on every slider change: cheap."""
    m = analytic.media(params)
    tree = new_group(names.ANALYTIC_MEDIA_COMPOSITOR_GROUP if compositor else names.ANALYTIC_MEDIA_GROUP,
                     "CompositorNodeTree" if compositor else "ShaderNodeTree")
    g, _, gout = group_io(tree, [], media_outputs(compositor))
    values = {"Rayleigh": m.rayleigh, "Haze Scattering": m.haze_scattering, "Haze Extinction": m.haze_extinction}
    if not compositor:
        for k, value in enumerate(analytic.ambient_table(m)[1]):
            values[_ambient_socket(k)] = value
    for name, value in values.items():
        g.links.new(g.combine(*(float(v) for v in value)), gout.inputs[name])
    for name, value in (("G", m.g), ("Air Length", m.air_length), ("Haze Length", m.haze_length),
                        ("Ground Albedo", m.ground_albedo)):
        g.links.new(g.math("ADD", float(value), 0.0), gout.inputs[name])
    return tree


class Media:
    """The media group's outputs inside a formula group: per-channel sockets of the coefficients."""

    def __init__(self, g, compositor: bool = False):
        node = g.node("CompositorNodeGroup" if compositor else "ShaderNodeGroup")
        node.node_tree = bpy.data.node_groups[names.ANALYTIC_MEDIA_COMPOSITOR_GROUP if compositor
                                              else names.ANALYTIC_MEDIA_GROUP]
        out = node.outputs
        self.rayleigh, self.haze_scattering, self.haze_extinction = (g.separate(out[name]) for name in MEDIA_VECTORS)
        self.g, self.air_length, self.haze_length, self.ground_albedo = (out[name] for name in MEDIA_FLOATS)
        self.ambient = [out[_ambient_socket(k)] for k in range(analytic.AMBIENT_NODES)] if not compositor else []


def exp_neg(g, x):
    """exp(-x), its argument capped at MAX_DEPTH."""
    return g.math("EXPONENT", g.mul(g.math("MINIMUM", x, MAX_DEPTH), -1.0))


def air_mass(g, cos_zenith):
    """analytic.air_mass: Hoffman & Preetham Eq. 5 over l_zenith, clamped at the horizon."""
    c = g.clamp(cos_zenith, 0.0, 1.0)
    theta = g.mul(g.math("ARCCOSINE", c), 180.0 / math.pi)
    return g.div(1.0, g.add(c, g.mul(0.15, g.math("POWER", g.sub(93.885, theta), -1.253))))


def sun_visibility(g, cos_sun):
    elevation = g.math("ARCSINE", g.clamp(cos_sun, -1.0, 1.0))
    r = analytic.SUN_RADIUS_RAD
    return g.clamp(g.div(g.add(elevation, r), 2 * r), 0.0, 1.0)


def densities(g, m, height):
    """Air and haze densities relative to the ground at ``height`` (>= 0)."""
    below = g.mul(height, -1.0)
    return g.math("EXPONENT", g.div(below, m.air_length)), g.math("EXPONENT", g.div(below, m.haze_length))


def _scaled(g, coefficient, density):
    """coefficient x density, with no node for the plain densities 0 and 1."""
    if isinstance(density, float):
        return 0.0 if density == 0.0 else coefficient if density == 1.0 else g.mul(coefficient, density)
    return g.mul(coefficient, density)


def _sum(g, a, b):
    return a if b == 0.0 else b if a == 0.0 else g.add(a, b)


def sun_transmittance(g, m, cos_sun, height):
    """analytic.sun_transmittance: three channel sockets."""
    mass = air_mass(g, cos_sun)
    air, haze = densities(g, m, height)
    s_air, s_haze = g.mul(g.mul(mass, m.air_length), air), g.mul(g.mul(mass, m.haze_length), haze)
    visible = sun_visibility(g, cos_sun)
    return [g.mul(exp_neg(g, g.add(g.mul(s_air, m.rayleigh[i]), g.mul(s_haze, m.haze_extinction[i]))), visible)
            for i in range(3)]


def phases(g, m, cos_sun_view):
    """(Rayleigh, Henyey-Greenstein) phase of the sun-view angle."""
    c = g.clamp(cos_sun_view, -1.0, 1.0)
    rayleigh = g.mul(g.mul_add(c, c, 1.0), 3.0 / (16.0 * math.pi))
    gg = m.g
    base = g.math("MAXIMUM", g.mul_add(g.mul(gg, -2.0), c, g.mul_add(gg, gg, 1.0)), 1e-6)
    haze = g.div(g.mul(g.sub(1.0, g.mul(gg, gg)), 1.0 / (4.0 * math.pi)), g.math("POWER", base, 1.5))
    return rayleigh, haze


def transmittance_and_reach(g, beta, length):
    """(exp(-beta s), (1 - exp(-beta s)) / beta) of one channel for a segment of ``length`` s:
    the second is the distance the segment weighs in Hoffman & Preetham Eq. 4
    (lut_gen.passes.analytic_shafts.reach)."""
    depth = g.mul(length, beta)
    t = exp_neg(g, depth)
    # (1 - exp(-x)) / x, its series below SERIES_BELOW; times the length gives the reach
    exact = g.div(g.sub(1.0, t), g.math("MAXIMUM", depth, 1e-30))
    series = g.mul_add(depth, g.mul_add(depth, 1.0 / 6.0, -0.5), 1.0)
    small = g.math("LESS_THAN", depth, SERIES_BELOW)
    return t, g.mul(g.select(exact, series, small), length)


def segment(g, m, phase, length, e_sun, air=1.0, haze=1.0):
    """analytic.segment per channel: ([F_ex], [L_in]) for a constant-density segment."""
    rayleigh_phase, haze_phase = phase
    transmittance, inscatter = [], []
    for i in range(3):
        beta = _sum(g, _scaled(g, m.rayleigh[i], air), _scaled(g, m.haze_extinction[i], haze))
        t, reach = transmittance_and_reach(g, beta, length)
        air_sc, haze_sc = _scaled(g, m.rayleigh[i], air), _scaled(g, m.haze_scattering[i], haze)
        angular = _sum(g, g.mul(rayleigh_phase, air_sc), 0.0 if haze_sc == 0.0 else g.mul(haze_phase, haze_sc))
        transmittance.append(t)
        inscatter.append(g.mul(g.mul(angular, reach), e_sun[i]))
    return transmittance, inscatter


def sky_parts(g, m, view, sun, height):
    """analytic.sky_parts: ([air light], [ground light]) per unit E0, and E_sun."""
    cos_view = g.separate(view)[2]
    cos_sun = g.separate(sun)[2]
    phase = phases(g, m, g.vmath("DOT_PRODUCT", view, sun))
    e_sun = sun_transmittance(g, m, cos_sun, height)
    air, haze = densities(g, m, height)
    mass = air_mass(g, cos_view)
    s_air = g.mul(g.mul(mass, m.air_length), air)
    s_haze = g.math("MINIMUM", g.mul(g.mul(mass, m.haze_length), haze), s_air)
    inner_t, inner = segment(g, m, phase, s_haze, e_sun)
    _, outer = segment(g, m, phase, g.sub(s_air, s_haze), e_sun, 1.0, 0.0)
    sky = [g.mul_add(inner_t[i], outer[i], inner[i]) for i in range(3)]
    # Below the horizon: the flat ground at h / -cos, when nearer than the sky's length.
    down = g.math("LESS_THAN", cos_view, 0.0)
    distance = g.div(g.math("MAXIMUM", height, 1e-3), g.math("MAXIMUM", g.mul(cos_view, -1.0), 1e-9))
    hits = g.mul(down, g.math("LESS_THAN", distance, s_air))
    ground_t, ground_air = segment(g, m, phase, g.mul(distance, hits), e_sun, air, haze)
    lit = g.mul(g.math("MAXIMUM", cos_sun, 0.0), g.mul(m.ground_albedo, 1.0 / math.pi))
    air_light = [g.select(sky[i], ground_air[i], hits) for i in range(3)]
    ground_light = [g.mul(g.mul(g.mul(lit, e_sun[i]), ground_t[i]), hits) for i in range(3)]
    return air_light, ground_light, e_sun


def build_analytic_sky_group(params):
    """"OLS Sky" under the analytic model. Every ray evaluates the formula (a few hundred math
    nodes, no texture), camera rays with the limb-darkened sun disc; diffuse and scatter rays
    only with "Light Scene", glossy rays always, as in the precomputed group."""
    build_media_group(params)
    tree = new_group(names.SKY_GROUP)
    g, gin, gout = group_io(tree, SKY_INPUTS, [("Color", "NodeSocketColor", None), ("Background", "NodeSocketShader", None)])
    m = Media(g)
    view = g.vmath("NORMALIZE", g.node("ShaderNodeTexCoord").outputs["Generated"])
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    height = g.math("MAXIMUM", gin.outputs["Camera Height"], 0.0)
    strength = gin.outputs["Sun Strength"]
    air_light, ground_light, e_sun = sky_parts(g, m, view, sun, height)
    scale = g.mul(strength, gin.outputs["Scattering Scale"])
    surroundings = g.vmath("ADD", g.vscale(g.combine(*air_light), scale), g.vscale(g.combine(*ground_light), strength))
    disc = g.vmath("MULTIPLY", g.combine(*e_sun),
                   g.vscale(limb_darkened_disc(g, g.vmath("DOT_PRODUCT", view, sun), gin.outputs["Sun Angle"]), strength))
    camera_color = g.vmath("ADD", surroundings, disc)
    light_path = g.node("ShaderNodeLightPath")
    lit = g.math("MAXIMUM", light_path.outputs["Is Glossy Ray"], gin.outputs["Light Scene"])
    color = g.vlerp(g.vscale(surroundings, lit), camera_color, light_path.outputs["Is Camera Ray"])
    background = g.node("ShaderNodeBackground")
    g.feed(background.inputs["Color"], color)
    g.links.new(camera_color, gout.inputs["Color"])
    g.links.new(background.outputs[0], gout.inputs["Background"])
    return tree


def build_analytic_aerial_group(params):
    """"OLS Aerial Perspective" under the analytic model: Hoffman & Preetham Eq. 1 from the
    camera to each pixel's point through air and haze at the densities of the segment's middle
    height, E_sun at the camera's height. Sky pixels pass through, as in the precomputed group."""
    build_media_group(params, compositor=True)
    tree = new_group(names.AERIAL_GROUP, "CompositorNodeTree")
    g, gin, gout = group_io(tree, AERIAL_INPUTS, [("Image", "NodeSocketColor", None),
                                                  ("Transmittance", "NodeSocketColor", None),
                                                  ("Inscattering", "NodeSocketColor", None)])
    m = Media(g, compositor=True)
    camera, point = gin.outputs["Camera Position"], gin.outputs["Position"]
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    offset = g.vmath("SUBTRACT", point, camera)
    length = g.vmath("LENGTH", offset)
    cos_sun_view = g.div(g.vmath("DOT_PRODUCT", offset, sun), g.math("MAXIMUM", length, 1e-9))
    camera_z, point_z = g.separate(camera)[2], g.separate(point)[2]
    e_sun = sun_transmittance(g, m, g.separate(sun)[2], g.math("MAXIMUM", camera_z, 0.0))
    middle = g.math("MAXIMUM", g.mul(g.add(camera_z, point_z), 0.5), 0.0)
    air, haze = densities(g, m, middle)
    transmittance, inscatter = segment(g, m, phases(g, m, cos_sun_view), length, e_sun, air, haze)
    air_light = g.vscale(g.combine(*inscatter), g.mul(gin.outputs["Sun Strength"], gin.outputs["Scattering Scale"]))
    geometry = g.mul(g.math("LESS_THAN", gin.outputs["Depth"], gin.outputs["Sky Depth"]), gin.outputs["Enable"])
    kept = g.vscale(g.combine(*transmittance), g.sub(1.0, gin.outputs["Lighting Only"]))
    layer_transmittance = g.vlerp((1.0, 1.0, 1.0), kept, geometry)
    layer_inscattering = g.vscale(air_light, geometry)
    result = g.vmath("ADD", g.vmath("MULTIPLY", gin.outputs["Image"], layer_transmittance), layer_inscattering)
    g.links.new(g.with_alpha_of(gin.outputs["Image"], result), gout.inputs["Image"])
    g.links.new(layer_transmittance, gout.inputs["Transmittance"])
    g.links.new(layer_inscattering, gout.inputs["Inscattering"])
    return tree


def ambient_irradiance(g, m, cos_sun):
    """analytic.ambient_irradiance: the media group's ambient nodes, linear between them (a sum
    of hat functions), times the sun's visibility."""
    x = g.mul(g.clamp(cos_sun, 0.0, 1.0), float(len(m.ambient) - 1))
    total = (0.0, 0.0, 0.0)
    for k, value in enumerate(m.ambient):
        hat = g.math("MAXIMUM", g.sub(1.0, g.math("ABSOLUTE", g.sub(x, float(k)))), 0.0)
        total = g.vmath("MULTIPLY_ADD", value, g.combine(hat, hat, hat), total)
    return g.vscale(total, sun_visibility(g, cos_sun))


def build_analytic_terrain_group(params):
    """"OLS Terrain" under the analytic model: the precomputed group's shading (nodes/terrain.py)
    with Hoffman & Preetham Eq. 5's sun extinction at the point's height (over the origin's, which
    the lamp's colour carries) and the analytic sky's own ambient skylight. +Z is up and z the
    height."""
    build_media_group(params)
    tree = new_group(names.TERRAIN_GROUP)
    g, gin, gout = group_io(tree, TERRAIN_INPUTS, [("Shader", "NodeSocketShader", None)])
    m = Media(g)
    geometry = g.node("ShaderNodeNewGeometry")
    given = gin.outputs["Normal"]
    has_normal = g.math("GREATER_THAN", g.vmath("LENGTH", given), 0.5)
    normal = g.vmath("NORMALIZE", g.vlerp(geometry.outputs["Normal"], given, has_normal))
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    cos_sun = g.separate(sun)[2]
    height = g.math("MAXIMUM", g.separate(geometry.outputs["Position"])[2], 0.0)
    extinction = g.combine(*sun_transmittance(g, m, cos_sun, height))
    origin = g.vmath("MAXIMUM", gin.outputs["Origin Transmittance"], (MIN_ORIGIN_TRANSMITTANCE,) * 3)
    albedo = gin.outputs["Albedo"]
    diffuse = g.node("ShaderNodeBsdfDiffuse")
    g.feed(diffuse.inputs["Color"], g.vmath("MULTIPLY", albedo, g.vmath("DIVIDE", extinction, origin)))
    g.feed(diffuse.inputs["Normal"], normal)
    occlusion = g.clamp(g.mul_add(g.separate(normal)[2], 0.5, 0.5), 0.0, 1.0)
    sky_light = g.vscale(ambient_irradiance(g, m, cos_sun),
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


# The formula groups hold no number of the media (those are in the media groups), so a built one
# serves every later switch: a copy of each is kept under a hidden name (a leading dot), with no
# user, so a saved file drops it. Building them costs ~1 s (about 900 nodes, each node and socket
# set updating its tree in bpy 5.0.1); a copy swapped in with user_remap costs milliseconds.
FORMULA_GROUPS = (names.SKY_GROUP, names.TERRAIN_GROUP, names.AERIAL_GROUP)


def _kept_name(name: str) -> str:
    return f".{name} (analytic, kept)"


def keep_formula_groups():
    """Keep a copy of the freshly built formula groups for the next switch."""
    for name in FORMULA_GROUPS:
        old = bpy.data.node_groups.get(_kept_name(name))
        if old is not None:
            bpy.data.node_groups.remove(old)
        bpy.data.node_groups[name].copy().name = _kept_name(name)


def restore_formula_groups(params) -> bool:
    """The kept formula groups in place of the scene's current groups of the same names (the
    tables' ones), with the media of ``params``; False when none are kept (build them)."""
    kept = [bpy.data.node_groups.get(_kept_name(name)) for name in FORMULA_GROUPS]
    if any(tree is None for tree in kept):
        return False
    build_media_group(params)
    build_media_group(params, compositor=True)
    for name, template in zip(FORMULA_GROUPS, kept):
        tree = template.copy()
        current = bpy.data.node_groups.get(name)
        if current is not None:
            current.user_remap(tree)
            bpy.data.node_groups.remove(current)
        tree.name = name
    return True


def update_media(params) -> bool:
    """After a slider change: rebuild only the media groups when the formula groups are the
    analytic ones already (True), else nothing (False: build the groups)."""
    if not all(_reads_media(name, media) for name, media in (
            (names.SKY_GROUP, names.ANALYTIC_MEDIA_GROUP), (names.TERRAIN_GROUP, names.ANALYTIC_MEDIA_GROUP),
            (names.AERIAL_GROUP, names.ANALYTIC_MEDIA_COMPOSITOR_GROUP))):
        return False
    build_media_group(params)
    build_media_group(params, compositor=True)
    return True


def _reads_media(group_name, media_name) -> bool:
    tree = bpy.data.node_groups.get(group_name)
    return tree is not None and any(node.type == "GROUP" and node.node_tree is not None
                                    and node.node_tree.name == media_name for node in tree.nodes)
