""""OLS Light Shafts" under the analytic model (Hoffman & Preetham): the tables' shaft group
(nodes/light_shafts.py: the pixel's ray, the shadow test, the march chunks, the shaft edge, the
epipolar lit-length tables, the sky's share) with the air's light in closed form instead of
table look-ups. Twin: lut_gen.passes.analytic_shafts (its module docstring gives the modes'
analytic meaning).

Along a pixel's ray the media are those the analytic aerial perspective holds (the densities of
the ray's middle height, E_sun at the camera), so a lit section [a, a + L] gives
E_sun beta_sc exp(-beta a) (1 - exp(-beta L)) / beta per channel: LUT takes the first lit
distance and the lit length, INTEGRATION the sum over the march's steps (brute force: the chunk
groups carry sum lit_j exp(-beta t_j) through "OLS Analytic Integration Step"; epipolar: the
integral table, built per frame by lut_gen.passes.analytic_shafts.epipolar_integral). No table
image and no bake: the media are "OLS Analytic Media (Compositor)".
"""
from __future__ import annotations

from . import analytic, epipolar
from .builder import group_io, new_group
from .light_shafts import ShaftLayout, build_shadow_test_group, build_shaft_group, march_lit
from ..scene import names

EXTINCTION_INPUT = ("Extinction", "NodeSocketVector", (0.0, 0.0, 0.0))
CHUNK_NAMES = (names.ANALYTIC_MARCH_CHUNK_GROUP, names.ANALYTIC_MARCH_REST_GROUP)


def build_analytic_integration_group():
    """"OLS Analytic Integration Step": one march step's share of J = sum_j lit_j exp(-beta t_j)
    (the shaft group multiplies J by E_sun beta_sc (1 - exp(-beta dt)) / beta, the same for every
    step), the optical depth beta t carried from step to step: exact sections, not a midpoint
    rule. Its interface is "OLS Integration Step"'s plus the ray's extinction, so the march
    chunks drive either. Twin: lut_gen.passes.analytic_shafts.step_integral."""
    tree = new_group(names.ANALYTIC_INTEGRATION_GROUP, "CompositorNodeTree")
    inputs = [("Point", "NodeSocketVector", (0.0, 0.0, 0.0)), ("Direction", "NodeSocketVector", (0.0, 1.0, 0.0)),
              ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)), ("Lit", "NodeSocketFloat", 1.0),
              ("Step", "NodeSocketFloat", 1.0), ("Optical Depth Before", "NodeSocketVector", (0.0, 0.0, 0.0)),
              EXTINCTION_INPUT]
    g, gin, gout = group_io(tree, inputs, [("Radiance", "NodeSocketVector", None),
                                           ("Optical Depth After", "NodeSocketVector", None)])
    before = gin.outputs["Optical Depth Before"]
    g.links.new(g.vmath("MULTIPLY_ADD", gin.outputs["Extinction"], g.combine(*(gin.outputs["Step"],) * 3), before),
                gout.inputs["Optical Depth After"])
    weight = g.combine(*(analytic.exp_neg(g, depth) for depth in g.separate(before)))
    g.links.new(g.vscale(weight, gin.outputs["Lit"]), gout.inputs["Radiance"])
    return tree


def _ray_media(g, m, ray):
    """Per channel: (extinction beta, source E_sun beta_sc(theta)) of the pixel's ray (twin:
    analytic_shafts.RayMedia.of)."""
    camera_z, end_z = g.separate(ray.camera)[2], g.separate(ray.end)[2]
    e_sun = analytic.sun_transmittance(g, m, g.separate(ray.sun)[2], g.math("MAXIMUM", camera_z, 0.0))
    air, haze = analytic.densities(g, m, g.math("MAXIMUM", g.mul(g.add(camera_z, end_z), 0.5), 0.0))
    rayleigh_phase, haze_phase = analytic.phases(g, m, g.vmath("DOT_PRODUCT", ray.direction, ray.sun))
    extinction, source = [], []
    for i in range(3):
        extinction.append(g.add(g.mul(m.rayleigh[i], air), g.mul(m.haze_extinction[i], haze)))
        scattering = g.add(g.mul(g.mul(m.rayleigh[i], air), rayleigh_phase),
                           g.mul(g.mul(m.haze_scattering[i], haze), haze_phase))
        source.append(g.mul(scattering, e_sun[i]))
    return extinction, source


def _section(g, beta, start, length):
    """exp(-beta start) (1 - exp(-beta length)) / beta: one channel's lit section per unit source."""
    _, reach = analytic.transmittance_and_reach(g, beta, length)
    return g.mul(analytic.exp_neg(g, g.mul(beta, start)), reach)


def build_analytic_light_shaft_groups(atlas_image, parameter_image, params, layout: ShaftLayout,
                                      epipolar_images=(None, None, None, {})):
    """(Re)build "OLS Light Shafts" and its sub-groups for ``layout`` under the analytic model
    (``params``: the scene's media, analytic_params). The epipolar technique reads the lit and
    integral images of ``epipolar_images`` (no in-scattering images). The cloud layer is not
    part of the analytic model: the layout has no clouds."""
    analytic.build_media_group(params, compositor=True)
    shadow_test_tree = (build_shadow_test_group(layout, atlas_image, parameter_image)
                        if layout.reads_shadow_maps else None)
    integrate = layout.single_mode == "INTEGRATION"

    def air_light(ray):
        g, gin = ray.g, ray.gin
        m = analytic.Media(g, compositor=True)
        beta, source = _ray_media(g, m, ray)
        if layout.epipolar:
            lit = epipolar.read_lit_tables(g, gin, ray.direction, ray.length, ray.sun, epipolar_images[0],
                                           epipolar_images[1] if integrate else None)
            lit_length, first_lit = lit.lit_length, lit.first_lit
            if integrate:       # the table to its reach, then lit air (twin: epipolar_difference)
                inside = g.math("MINIMUM", ray.length, lit.t_max)
                beyond = g.math("MAXIMUM", g.sub(ray.length, lit.t_max), 0.0)
                integral = [g.add(j, _section(g, beta[i], inside, beyond))
                            for i, j in enumerate(g.separate(lit.integral))]
        else:
            lit_length, first_lit, summed = march_lit(ray, layout, shadow_test_tree, build_analytic_integration_group(),
                                                      CHUNK_NAMES, [(EXTINCTION_INPUT, g.combine(*beta))])
            if integrate:
                step = g.div(ray.length, float(layout.steps))
                integral = [g.mul(j, analytic.transmittance_and_reach(g, beta[i], step)[1])
                            for i, j in enumerate(g.separate(summed))]
        has_lit = g.math("GREATER_THAN", lit_length, 0.0)
        unshadowed, shadowed = [], []
        for i in range(3):
            unshadowed.append(g.mul(source[i], analytic.transmittance_and_reach(g, beta[i], ray.length)[1]))
            if layout.single_mode == "LUT":
                shadowed.append(g.mul(g.mul(source[i], _section(g, beta[i], first_lit, lit_length)), has_lit))
            elif integrate:
                shadowed.append(g.mul(source[i], integral[i]))
            else:               # NONE: no single scattering, and the model has no higher orders
                shadowed.append(0.0)
        unshadowed = g.combine(*unshadowed)
        difference = g.vmath("SUBTRACT", g.combine(*shadowed), unshadowed)
        if layout.epipolar:     # the whole image, as the tables' epipolar group makes it
            light = g.vmath("MULTIPLY_ADD", unshadowed, g.combine(*(ray.geometry,) * 3), difference)
            return light, unshadowed, g.vmath("MULTIPLY", gin.outputs["Surface"], gin.outputs["Transmittance"])
        return difference, unshadowed, gin.outputs["Image"]

    return build_shaft_group(layout, params, shadow_test_tree, parameter_image, epipolar_images, air_light)
