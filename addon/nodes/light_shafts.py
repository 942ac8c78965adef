""""OLS Light Shafts": the sun's shadows in the air, as a compositor group placed after
"OLS Aerial Perspective". Twin: lut_gen.passes.scattering_pass (with lut_gen.passes.aerial.light_shafts).

Each pixel's ray runs from the camera to its surface point, or for the sky to the end of the
last shadow cascade. The group marches ``steps`` samples through the cascaded shadow maps
("OLS Shadow Test", one per step), finds the lit length and the distance to the first lit
sample, applies the sample's single- and multiple-scattering modes and replaces the
unshadowed in-scattering the aerial pass (or the sky) already holds:

    out = image + (shadowed - unshadowed) x sun strength x scattering scale

The march length, the modes, the number of cascades, PCF and the cascade search change the
structure of the group: ``ShaftLayout`` names them and a change rebuilds the groups. Everything
else (camera, sun, cascade rectangles, first cascade, show cascades, and the epipolar tables'
slices, samples and steps) arrives as inputs.
"""
from __future__ import annotations

from dataclasses import dataclass

from ...lut_gen.passes import jitter as jitter_offsets, shadow_map, shaft_boundary
from ...lut_gen.passes.shadow_map import MIN_FORWARD_COSINE
from . import cloud_shafts, epipolar, jitter
from .aerial import PASS_INPUTS
from .builder import group_io, new_group
from .inscattering import section_node
from .lookup import mie_phase, rayleigh_phase
from .optical import (optical_depth_of, ozone_density, point_frame, segment_transmittance_node,
                      transmittance_of_optical_depth,
                      transmittance_to_top)
from ..scene import names

NEVER = 1e20                 # "no lit sample" in the first-lit minimum


@dataclass(frozen=True)
class ShaftLayout:
    """The settings that shape the node graph (scene.ols names)."""
    steps: int = 30
    cascades: int = 6
    single_mode: str = "LUT"
    multiple_mode: str = "UNOCCLUDED"
    smooth: bool = True
    best_search: bool = True
    resolution: int = 1024
    technique: str = "BRUTE_FORCE"
    show_cascades: bool = False     # the tint costs a shadow test per pixel: built only when shown
    clouds: bool = False            # the cloud layer shadows the air (lut_gen.clouds.shafts)
    # The air's model: the tables' look-ups, or the analytic model's closed forms
    # (nodes/analytic_shafts.py); switching models rebuilds the groups.
    analytic: bool = False

    @property
    def epipolar(self) -> bool:
        return self.technique == "EPIPOLAR_SAMPLING"

    @property
    def reads_shadow_maps(self) -> bool:
        """Whether the compositor reads the shadow-map images: brute force marches them, the
        epipolar technique only tints with them for Show Cascades (its tables are marched in
        numpy). Otherwise no shadow test group is built and no atlas written."""
        return not self.epipolar or self.show_cascades

    @classmethod
    def from_settings(cls, settings, technique=None, analytic: bool = False):
        """``technique`` overrides the setting (the add-on falls back to brute force where
        epipolar sampling cannot serve the frame); ``analytic``: the scene is wired to the
        analytic model, which has no clouds (its sky ignores them, and so do its shafts)."""
        technique = technique or settings.scattering_technique
        # The epipolar graph does not unroll the steps: the tables' sizes are frame values.
        steps = 0 if technique == "EPIPOLAR_SAMPLING" else settings.num_integration_steps
        clouds = bool(getattr(settings, "clouds_enabled", False)) and not analytic
        # The analytic model has no higher orders: its three multiple-scattering modes give the
        # same light (lut_gen.passes.analytic_shafts), so a change of that mode rebuilds nothing.
        multiple = "UNOCCLUDED" if analytic else settings.multiple_scattering_mode
        return cls(steps, settings.num_cascades, settings.single_scattering_mode, multiple,
                   settings.smooth_shadows, settings.best_cascade_search, int(settings.shadow_map_resolution),
                   technique, settings.show_cascades, clouds, analytic)

    def as_key(self) -> str:
        return repr(tuple(self.__dict__.values()))


def cascade_inputs(count):
    return [socket for i in range(count) for socket in
            ((f"Cascade {i} Center", "NodeSocketVector", (0.0, 0.0, 1.0)),
             (f"Cascade {i} Half", "NodeSocketVector", (1.0, 1.0, 0.0)))]


SHARED_INPUTS = [
    ("Camera Position", "NodeSocketVector", (0.0, 0.0, 2.0)),
    ("Camera Forward", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Light Right", "NodeSocketVector", (1.0, 0.0, 0.0)),
    ("Light Up", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)),
    ("First Cascade", "NodeSocketFloat", 0.0),
]


def test_inputs(layout: ShaftLayout):
    """The inputs every group that runs shadow tests takes and hands on to "OLS Shadow Test"."""
    return SHARED_INPUTS + cascade_inputs(layout.cascades) + (cloud_shafts.INPUTS if layout.clouds else [])


def build_shadow_test_group(layout: ShaftLayout, atlas_image, parameter_image, cloud_map=None):
    """"OLS Shadow Test": the sun visibility of a world point (1 lit, 0 shadowed, PCF fractions,
    times the cloud's transmittance with clouds on) and its cascade. Twin:
    lut_gen.passes.shadow_map.visibility and select_cascade (and lut_gen.clouds.shafts.sun_visibility)."""
    tree = new_group(names.SHADOW_TEST_GROUP, "CompositorNodeTree")
    inputs = [("Point", "NodeSocketVector", (0.0, 0.0, 0.0))] + test_inputs(layout)
    g, gin, gout = group_io(tree, inputs, [("Lit", "NodeSocketFloat", None), ("Cascade", "NodeSocketFloat", None)])
    n = layout.cascades
    point = gin.outputs["Point"]
    x, y = (g.vmath("DOT_PRODUCT", point, gin.outputs[axis]) for axis in ("Light Right", "Light Up"))
    sun_depth = g.vmath("DOT_PRODUCT", point, gin.outputs["Sun Direction"])
    light_xy = g.combine(x, y, 0.0)

    def inside(center, half):
        """1 where the point projects into the rectangle center +- half (x, y components)."""
        offset = g.vmath("ABSOLUTE", g.vmath("SUBTRACT", light_xy, g.combine(*g.separate(center)[:2], 0.0)))
        hx, hy, _ = g.separate(half)
        ox, oy, _ = g.separate(offset)
        return g.mul(g.math("LESS_THAN", ox, g.add(hx, 1e-6)), g.math("LESS_THAN", oy, g.add(hy, 1e-6)))

    def parameter(row, index):
        """Row ``row`` of the cascade parameter image at column ``index``."""
        u = g.div(g.add(index, 0.5), n + 1)
        v = (shadow_map.PARAM_ROWS.index(row) + 0.5) / len(shadow_map.PARAM_ROWS)
        return g.image(parameter_image, g.combine(u, v, 1.0), interpolation="Closest")

    if layout.best_search:      # nested cascades: the smallest one containing the point
        index = float(n)
        for i in range(n):
            index = g.sub(index, inside(gin.outputs[f"Cascade {i} Center"], gin.outputs[f"Cascade {i} Half"]))
    else:                        # the cascade whose view-depth range holds the point, if it covers it
        view_depth = g.vmath("DOT_PRODUCT", g.vmath("SUBTRACT", point, gin.outputs["Camera Position"]),
                             gin.outputs["Camera Forward"])
        index = 0.0
        for i in range(n):
            far = g.separate(gin.outputs[f"Cascade {i} Center"])[2]
            index = g.add(index, g.math("GREATER_THAN", view_depth, far))
        chosen = g.math("MINIMUM", index, n - 1)
        covered = inside(parameter("center_far", chosen), parameter("half_bias", chosen))
        index = g.lerp(float(n), index, covered)
    g.links.new(index, gout.inputs["Cascade"])
    # "First cascade to ray march": points of smaller cascades use that one (cascades nest).
    index = g.math("MAXIMUM", index, g.math("MINIMUM", gin.outputs["First Cascade"], n - 1))

    cascade = g.math("MINIMUM", index, n - 1)
    cx, cy, _ = g.separate(parameter("center_far", cascade))
    hx, hy, bias = g.separate(parameter("half_bias", cascade))
    mask = parameter("channel_mask", cascade)
    block = g.separate(parameter("block", cascade))[0]
    res = atlas_image.size[1]
    width = atlas_image.size[0]
    # Continuous texel coordinates (texel i spans [i, i + 1)); the taps as
    # lut_gen.passes.shadow_map.tap_texels: bilinear PCF when smooth, else the texel under the point.
    texel_x = g.mul(g.div(g.add(g.sub(x, cx), hx), g.mul(hx, 2.0)), res)
    texel_y = g.mul(g.div(g.add(g.sub(y, cy), hy), g.mul(hy, 2.0)), res)
    if layout.smooth:
        u, v = g.sub(texel_x, 0.5), g.sub(texel_y, 0.5)
        column, row = g.math("FLOOR", u), g.math("FLOOR", v)
        fx, fy = g.sub(u, column), g.sub(v, row)
        weights = {0: (g.sub(1.0, fx), g.sub(1.0, fy)), 1: (fx, fy)}
    else:
        column, row = g.math("FLOOR", texel_x), g.math("FLOOR", texel_y)
    taps = shadow_map.PCF_OFFSETS if layout.smooth else shadow_map.PCF_OFFSETS[:1]
    lit = 0.0
    for dx, dy in taps:
        c = g.clamp(g.add(column, float(dx)), 0.0, res - 1) if dx else g.clamp(column, 0.0, res - 1)
        r = g.clamp(g.add(row, float(dy)), 0.0, res - 1) if dy else g.clamp(row, 0.0, res - 1)
        u = g.div(g.add(g.mul_add(block, res, c), 0.5), width)
        v = g.div(g.add(r, 0.5), res)
        stored = g.vmath("DOT_PRODUCT", g.image(atlas_image, g.combine(u, v, 1.0), interpolation="Closest"), mask)
        passes = g.math("GREATER_THAN", sun_depth, g.sub(stored, bias))
        if layout.smooth:
            passes = g.mul(passes, g.mul(weights[dx][0], weights[dy][1]))
        lit = g.add(lit, passes)
    tested = g.math("LESS_THAN", index, n - 0.5)
    lit = g.lerp(1.0, lit, tested)
    if layout.clouds:
        lit = g.mul(lit, cloud_shafts.sun_transmittance(g, cloud_map, point, g.vmath("NORMALIZE", gin.outputs["Sun Direction"]),
                                                       gin.outputs["Cloud Layer"], gin.outputs["Cloud Map"]))
    g.links.new(lit, gout.inputs["Lit"])
    return tree


def build_integration_group(optical_image, params):
    """"OLS Integration Step": single scattering of one march step, sigma_s P(theta) T(C->X)
    T_sun(X) x lit x step (the sample's "Singl sctr: integration"), with the extinction from the
    camera accumulated step by step (the RGB optical depth in and out, midpoint rule: one
    vector whatever the number of media, fog included). Twin: the INTEGRATION branch of
    lut_gen.passes.aerial.light_shafts."""
    tree = new_group(names.INTEGRATION_GROUP, "CompositorNodeTree")
    inputs = [("Point", "NodeSocketVector", (0.0, 0.0, 0.0)), ("Direction", "NodeSocketVector", (0.0, 1.0, 0.0)),
              ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)), ("Lit", "NodeSocketFloat", 1.0),
              ("Step", "NodeSocketFloat", 1.0), ("Optical Depth Before", "NodeSocketVector", (0.0, 0.0, 0.0))]
    g, gin, gout = group_io(tree, inputs, [("Radiance", "NodeSocketVector", None),
                                           ("Optical Depth After", "NodeSocketVector", None)])
    point, direction, sun, step = (gin.outputs[n] for n in ("Point", "Direction", "Sun Direction", "Step"))
    height, up = point_frame(g, point, params)
    sun_transmittance = transmittance_to_top(g, optical_image, height, g.vmath("DOT_PRODUCT", up, sun), params)
    rho_r = g.math("EXPONENT", g.div(height, -params.rayleigh_scale_height))
    rho_m = g.math("EXPONENT", g.div(height, -params.mie_scale_height))
    media = [rho_r, rho_m, ozone_density(g, height)]
    if params.has_fog:
        rho_f = g.math("EXPONENT", g.div(height, -params.fog_height))
        media.append(rho_f)
    step_depth = g.vscale(optical_depth_of(g, media, params), step)
    before = gin.outputs["Optical Depth Before"]
    g.links.new(g.vmath("ADD", before, step_depth), gout.inputs["Optical Depth After"])
    view_transmittance = transmittance_of_optical_depth(g, g.vmath("MULTIPLY_ADD", step_depth, (0.5, 0.5, 0.5), before))
    cos_theta = g.vmath("DOT_PRODUCT", direction, sun)
    scattering = g.vmath("ADD", g.vscale(tuple(params.rayleigh), g.mul(rho_r, rayleigh_phase(g, cos_theta))),
                         g.vscale(tuple(params.mie), g.mul(rho_m, mie_phase(g, cos_theta, params.mie_g))))
    if params.has_fog:      # grey and non-absorbing: scattering = extinction
        scattering = g.vmath("ADD", scattering, g.vscale((params.fog,) * 3,
                                                         g.mul(rho_f, mie_phase(g, cos_theta, params.fog_g))))
    weight = g.mul(gin.outputs["Lit"], step)
    radiance = g.vscale(g.vmath("MULTIPLY", g.vmath("MULTIPLY", scattering, view_transmittance), sun_transmittance), weight)
    g.links.new(radiance, gout.inputs["Radiance"])
    return tree


MAIN_INPUTS = PASS_INPUTS + [
    ("Camera Right", "NodeSocketVector", (1.0, 0.0, 0.0)),
    ("Camera Up", "NodeSocketVector", (0.0, 0.0, 1.0)),
    ("Tan Half FOV", "NodeSocketVector", (0.5, 0.3, 0.0)),
    ("Far Depth", "NodeSocketFloat", 1000.0),
    ("Sun Strength", "NodeSocketFloat", 10.0),
    ("Scattering Scale", "NodeSocketFloat", 0.5),
    ("Enable", "NodeSocketFloat", 1.0),
    ("Show Cascades", "NodeSocketFloat", 0.0),
]

# Brute force only: 1 offsets each pixel's steps by its noise (lut_gen.passes.jitter).
MARCH_INPUTS = [("Jitter Steps", "NodeSocketFloat", 0.0)]


def build_light_shaft_groups(optical_image, atlas_image, parameter_image, params, layout: ShaftLayout,
                             epipolar_images=(None, None, None, {}), cloud_map=None):
    """(Re)build "OLS Light Shafts" and its sub-groups for ``layout``; the epipolar technique
    reads ``epipolar_images`` (lit, integral or None, sampling overlay, {name: in-scattering
    image}) instead of marching; with clouds the shadow test reads ``cloud_map``."""
    shadow_test_tree = (build_shadow_test_group(layout, atlas_image, parameter_image, cloud_map)
                        if layout.reads_shadow_maps else None)

    def air_light(ray):
        g, gin = ray.g, ray.gin
        if layout.epipolar:     # the whole image: surface x transmittance + the air's light
            light, unshadowed = epipolar.in_scattering(g, gin, ray.direction, ray.length, ray.sun, ray.geometry,
                                                       layout, epipolar_images, params)
            return light, unshadowed, g.vmath("MULTIPLY", gin.outputs["Surface"], gin.outputs["Transmittance"])
        # the aerial group's image + shadowed - unshadowed
        lit_length, first_lit, integrated = march_lit(ray, layout, shadow_test_tree,
                                                      build_integration_group(optical_image, params))
        light, unshadowed = _brute_force_difference(g, ray.camera, ray.end, ray.direction, ray.sun, layout, lit_length,
                                                    first_lit, integrated)
        return light, unshadowed, gin.outputs["Image"]

    return build_shaft_group(layout, params, shadow_test_tree, parameter_image, epipolar_images, air_light)


def shaft_model(analytic: bool) -> str:
    """The SHAFT_MODEL_KEY value of a shaft group built for the tables or the analytic model:
    a group of the other model must not run (its air would not match the aerial group's)."""
    return "analytic" if analytic else "tables"


@dataclass
class PixelRay:
    """The pixel's ray inside "OLS Light Shafts": what the air's light of either atmosphere
    model is computed from (sockets of ``g``)."""
    g: object
    gin: object
    pixel: object           # the pixel's integer coordinates (the jitter's noise)
    camera: object
    direction: object
    length: object
    end: object
    sun: object
    geometry: object        # 1 where the pixel shows a surface, 0 sky


def build_shaft_group(layout: ShaftLayout, params, shadow_test_tree, parameter_image, epipolar_images, air_light):
    """"OLS Light Shafts" around ``air_light(PixelRay) -> (light, unshadowed, base)``: the
    interface, the pixel's ray, the sky's share of the darkening, Show Cascades and Show
    Sampling, shared by the tables' group (build_light_shaft_groups) and the analytic model's
    (nodes/analytic_shafts.py); ``light`` is added to ``base`` times sun strength x scattering
    scale."""
    tree = new_group(names.LIGHT_SHAFTS_GROUP, "CompositorNodeTree")
    tree[names.LAYOUT_KEY] = layout.as_key()
    tree[names.SHAFT_MODEL_KEY] = shaft_model(layout.analytic)
    tree[names.READS_SHADOW_MAPS_KEY] = layout.reads_shadow_maps
    inputs = MAIN_INPUTS + test_inputs(layout) + (epipolar.INPUTS if layout.epipolar else MARCH_INPUTS)
    g, gin, gout = group_io(tree, inputs, [("Image", "NodeSocketColor", None)])
    camera, forward = gin.outputs["Camera Position"], gin.outputs["Camera Forward"]
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])

    # The pixel's ray: to the surface, or (sky) to view depth "Far Depth".
    # The epipolar pass must not read "Image": that would evaluate the aerial group's per-pixel
    # in-scattering, which its tables replace.
    source = gin.outputs["Surface"] if layout.epipolar else gin.outputs["Image"]
    coordinates = g.node("CompositorNodeImageCoordinates")
    g.links.new(source, coordinates.inputs["Image"])
    nx, ny, _ = g.separate(coordinates.outputs["Normalized"])
    tx, ty, _ = g.separate(gin.outputs["Tan Half FOV"])
    local = [g.mul(g.mul_add(nx, 2.0, -1.0), tx), g.mul(g.mul_add(ny, 2.0, -1.0), ty)]
    pixel_direction = g.vmath("NORMALIZE", g.vmath("ADD", g.vmath("ADD", g.vscale(gin.outputs["Camera Right"], local[0]),
                                                                   g.vscale(gin.outputs["Camera Up"], local[1])), forward))
    along = g.div(gin.outputs["Far Depth"], g.math("MAXIMUM", g.vmath("DOT_PRODUCT", pixel_direction, forward), MIN_FORWARD_COSINE))
    if layout.clouds:           # on to the cloud the sky shows (lut_gen.clouds.shafts)
        along = g.math("MAXIMUM", along, cloud_shafts.march_distance(g, camera, pixel_direction, gin.outputs["Cloud Layer"],
                                                                     params.earth_radius))
    geometry = g.math("LESS_THAN", gin.outputs["Depth"], gin.outputs["Sky Depth"])
    end = g.vlerp(g.vmath("MULTIPLY_ADD", pixel_direction, g.combine(along, along, along), camera),
                  gin.outputs["Position"], geometry)
    ray = g.vmath("SUBTRACT", end, camera)
    length = g.vmath("LENGTH", ray)
    direction = g.vscale(ray, g.div(1.0, g.math("MAXIMUM", length, 1e-9)))

    def shadow_test(point):
        node = g.node("CompositorNodeGroup")
        node.node_tree = shadow_test_tree
        g.links.new(point, node.inputs["Point"])
        for name, *_ in test_inputs(layout):
            g.links.new(gin.outputs[name], node.inputs[name])
        return node

    scale = g.mul(g.mul(gin.outputs["Sun Strength"], gin.outputs["Scattering Scale"]), gin.outputs["Enable"])
    light, unshadowed, base = air_light(PixelRay(g, gin, coordinates.outputs["Pixel"], camera, direction, length, end,
                                                 sun, geometry))
    if not layout.epipolar:     # brute force, either model: Jitter Steps' 3 x 3 mean of the darkening
        light = jitter.neighbourhood_mean(g, light, length, gin.outputs["Jitter Steps"])
    scale3 = g.combine(scale, scale, scale)
    # Sky pixels take the share of the darkening their own light allows (twin and why:
    # lut_gen.passes.scattering_pass.sky_shadow_share); no negative light in any case.
    share = g.vmath("MINIMUM", g.vmath("DIVIDE", base, g.vmath("MAXIMUM", g.vmath("MULTIPLY", unshadowed, scale3),
                                                                  (1e-20,) * 3)), (1.0, 1.0, 1.0))
    share = g.vmath("MAXIMUM", share, (0.0, 0.0, 0.0))
    share = g.vlerp(share, (1.0, 1.0, 1.0), geometry)
    light = g.vmath("MULTIPLY", light, share)
    result = g.vmath("MAXIMUM", g.vmath("MULTIPLY_ADD", light, scale3, base), (0.0, 0.0, 0.0))

    if layout.show_cascades:    # tint surfaces with the colour of the cascade they fall in
        end_cascade = shadow_test(end).outputs["Cascade"]
        colour_u = g.div(g.add(end_cascade, 0.5), layout.cascades + 1)
        colour_v = (shadow_map.PARAM_ROWS.index("color") + 0.5) / len(shadow_map.PARAM_ROWS)
        colour = g.image(parameter_image, g.combine(colour_u, colour_v, 1.0), interpolation="Closest")
        tint = g.vlerp((1.0, 1.0, 1.0), colour, g.mul(gin.outputs["Show Cascades"], geometry))
        result = g.vmath("MULTIPLY", result, tint)
    if layout.epipolar:
        result = epipolar.show_sampling(g, gin, result, g.combine(nx, ny, 1.0), epipolar_images[2])

    g.links.new(g.with_alpha_of(source, result), gout.inputs["Image"])
    return tree


def march_lit(ray: PixelRay, layout: ShaftLayout, shadow_test_tree, integration, chunk_names=None,
              integration_inputs=()):
    """Brute force: (lit length, first lit, integrated or None) of the pixel's ray, marched
    through the chunk groups (named ``chunk_names``: the full chunk's and the rest's) with
    ``integration`` as their step group, and the shaft edge refined. ``integration_inputs``:
    ((name, socket type, default), value) of the step group's inputs beyond the march's own."""
    specs = [spec for spec, _ in integration_inputs]
    chunk_trees = {name: build_march_chunk_group(name, count, layout, shadow_test_tree, integration, specs)
                   for name, count in dict(march_chunks(layout.steps, chunk_names)).items()}
    edge_tree = build_shaft_edge_group(layout, shadow_test_tree)
    offset = jitter.step_offset(ray.g, ray.pixel, ray.gin.outputs["Jitter Steps"])
    return _march(ray.g, ray.gin, ray.direction, ray.length, ray.sun, layout, chunk_trees, edge_tree, offset,
                  chunk_names, {spec[0]: value for spec, value in integration_inputs})


def _brute_force_difference(g, camera, end, direction, sun, layout: ShaftLayout, lit_length, first_lit, integrated):
    """(shadowed minus unshadowed, unshadowed) in-scattering per unit sun: the modes applied
    with eq. (8) per pixel (twin: lut_gen.passes.aerial.apply_modes minus segment_inscattering)."""
    def transmittance_to(point):
        return segment_transmittance_node(g, camera, point, direction)

    lit_start = g.vmath("MULTIPLY_ADD", direction, g.combine(first_lit, first_lit, first_lit), camera)
    lit_end = g.vmath("MULTIPLY_ADD", direction, g.combine(lit_length, lit_length, lit_length), lit_start)
    has_lit = g.math("GREATER_THAN", lit_length, 0.0)
    end_transmittance = transmittance_to(end)

    def lit_section(table):
        radiance = section_node(g, table, lit_start, lit_end, direction, sun, transmittance_to(lit_start),
                                transmittance_to(lit_end))
        return g.vscale(radiance, has_lit)

    terms = []
    if layout.single_mode == "INTEGRATION":
        terms.append(integrated)
    if layout.single_mode == "LUT":
        terms.append(lit_section("multiple" if layout.multiple_mode == "OCCLUDED" else "single"))
    if layout.multiple_mode == "OCCLUDED" and layout.single_mode != "LUT":
        terms.append(lit_section("higher"))
    if layout.multiple_mode == "UNOCCLUDED":
        terms.append(section_node(g, "higher", camera, end, direction, sun, None, end_transmittance))
    shadowed = (0.0, 0.0, 0.0)
    for term in terms:
        shadowed = g.vmath("ADD", shadowed, term)
    unshadowed = section_node(g, "multiple", camera, end, direction, sun, None, end_transmittance)
    return g.vmath("SUBTRACT", shadowed, unshadowed), unshadowed


# Steps per "OLS March Chunk" group. Blender's nodes.new and links.new cost grows with the
# tree's size, so unrolling 100 steps into one tree (about 3 500 links) took 15-37 s a rebuild;
# chunks of this many steps keep every tree to a few hundred links (about 2 s).
CHUNK_STEPS = 10
MARCH_STATE = [("Lit Length", "NodeSocketFloat", 0.0), ("First Lit", "NodeSocketFloat", NEVER),
               ("Optical Depth", "NodeSocketVector", (0.0, 0.0, 0.0)), ("Integrated", "NodeSocketVector", (0.0, 0.0, 0.0)),
               # The first shadow edge (lut_gen.passes.shaft_boundary.first_transition): the first
               # sample's state (-1 before it), the index of the first sample of the other state
               # (NEVER while none) and the lit fractions on both sides of it.
               ("First State", "NodeSocketFloat", -1.0), ("Transition", "NodeSocketFloat", NEVER),
               ("Lit Before", "NodeSocketFloat", 0.0), ("Lit After", "NodeSocketFloat", 0.0),
               ("Lit Previous", "NodeSocketFloat", 0.0)]


def march_chunks(steps: int, chunk_names=None):
    """(group name, step count) of the chunk groups a march of ``steps`` steps is made of, in
    order: full chunks, then the remainder's own group (``chunk_names``: the two names, the
    tables' by default)."""
    chunk, rest_name = chunk_names or (names.MARCH_CHUNK_GROUP, names.MARCH_REST_GROUP)
    full, rest = divmod(steps, CHUNK_STEPS)
    return [(chunk, CHUNK_STEPS)] * full + ([(rest_name, rest)] if rest else [])


def build_march_chunk_group(name: str, count: int, layout: ShaftLayout, shadow_test_tree, integration,
                            integration_inputs=()):
    """``count`` consecutive march steps from "First Step" on: each shadow test adds to the lit
    length (in steps) and lowers the first lit distance; with INTEGRATION each step's single
    scattering is added, the optical depth carried from step to step. ``integration_inputs``:
    (name, socket type, default) of the step group's inputs beyond the tables' own, taken as
    the chunk's inputs and handed on (the analytic model's extinction)."""
    tree = new_group(name, "CompositorNodeTree")
    inputs = (test_inputs(layout) + MARCH_STATE
              + [("Direction", "NodeSocketVector", (0.0, 1.0, 0.0)), ("Sun", "NodeSocketVector", (0.0, 0.0, 1.0)),
                 ("Step", "NodeSocketFloat", 1.0), ("First Step", "NodeSocketFloat", 0.0),
                 ("Offset", "NodeSocketFloat", jitter_offsets.CENTRE)] + list(integration_inputs))
    g, gin, gout = group_io(tree, inputs, MARCH_STATE)
    camera, direction, step = gin.outputs["Camera Position"], gin.outputs["Direction"], gin.outputs["Step"]
    state = {name: gin.outputs[name] for name, *_ in MARCH_STATE}
    # The samples sit at (first + j + offset) steps: the step centres at offset 0.5, the
    # pixel's jitter otherwise (lut_gen.passes.jitter).
    shifted = g.add(gin.outputs["First Step"], gin.outputs["Offset"])
    for j in range(count):
        t = g.mul(step, g.add(shifted, float(j)))
        point = g.vmath("MULTIPLY_ADD", direction, g.combine(t, t, t), camera)
        test = g.node("CompositorNodeGroup")
        test.node_tree = shadow_test_tree
        g.links.new(point, test.inputs["Point"])
        for socket, *_ in test_inputs(layout):
            g.links.new(gin.outputs[socket], test.inputs[socket])
        lit = test.outputs["Lit"]
        state["Lit Length"] = g.add(state["Lit Length"], lit)
        unlit = g.math("LESS_THAN", lit, shaft_boundary.LIT_FLOOR)
        index = g.add(gin.outputs["First Step"], float(j))
        start = g.mul(step, index)
        state["First Lit"] = g.math("MINIMUM", state["First Lit"], g.mul_add(unlit, NEVER, start))
        _track_transition(g, state, lit, index)
        if layout.single_mode == "INTEGRATION":
            node = g.node("CompositorNodeGroup")
            node.node_tree = integration
            for socket, value in (("Point", point), ("Direction", direction), ("Sun Direction", gin.outputs["Sun"]),
                                  ("Lit", lit), ("Step", step), ("Optical Depth Before", state["Optical Depth"]),
                                  *((socket, gin.outputs[socket]) for socket, *_ in integration_inputs)):
                g.feed(node.inputs[socket], value)
            state["Optical Depth"] = node.outputs["Optical Depth After"]
            state["Integrated"] = g.vmath("ADD", state["Integrated"], node.outputs["Radiance"])
    for name, value in state.items():
        g.links.new(value, gout.inputs[name])
    return tree


def _track_transition(g, state, lit, index):
    """One sample's part of shaft_boundary.first_transition, on the march state."""
    lit_state = g.math("GREATER_THAN", lit, shaft_boundary.HALF - 1e-7)
    unset = g.math("LESS_THAN", state["First State"], -0.5)
    state["First State"] = g.select(state["First State"], lit_state, unset)
    differs = g.math("ABSOLUTE", g.sub(lit_state, state["First State"]))
    fresh = g.mul(differs, g.math("GREATER_THAN", state["Transition"], 0.5 * NEVER))
    state["Transition"] = g.select(state["Transition"], index, fresh)
    state["Lit Before"] = g.select(state["Lit Before"], state["Lit Previous"], fresh)
    state["Lit After"] = g.select(state["Lit After"], lit, fresh)
    state["Lit Previous"] = lit


EDGE_INPUTS = [("Direction", "NodeSocketVector", (0.0, 1.0, 0.0)), ("Near", "NodeSocketFloat", 0.0),
               ("Far", "NodeSocketFloat", 1.0), ("Lit Near", "NodeSocketFloat", 0.0), ("Lit Far", "NodeSocketFloat", 1.0)]


def build_shaft_edge_group(layout: ShaftLayout, shadow_test_tree):
    """"OLS Shaft Edge": where between distances Near and Far along the pixel's ray its lit
    fraction crosses one half, by shaft_boundary.REFINE_ITERATIONS shadow tests of bisection
    and a linear crossing in the last bracket. Twin: lut_gen.passes.shaft_boundary.refine."""
    tree = new_group(names.SHAFT_EDGE_GROUP, "CompositorNodeTree")
    inputs = test_inputs(layout) + EDGE_INPUTS
    g, gin, gout = group_io(tree, inputs, [("Edge", "NodeSocketFloat", None)])
    camera, direction = gin.outputs["Camera Position"], gin.outputs["Direction"]
    near, far, lit_near, lit_far = (gin.outputs[name] for name in ("Near", "Far", "Lit Near", "Lit Far"))
    far_state = g.math("GREATER_THAN", lit_far, shaft_boundary.HALF - 1e-7)
    for _ in range(shaft_boundary.REFINE_ITERATIONS):
        middle = g.mul(g.add(near, far), 0.5)
        test = g.node("CompositorNodeGroup")
        test.node_tree = shadow_test_tree
        g.links.new(g.vmath("MULTIPLY_ADD", direction, g.combine(middle, middle, middle), camera), test.inputs["Point"])
        for socket, *_ in test_inputs(layout):
            g.links.new(gin.outputs[socket], test.inputs[socket])
        lit_middle = test.outputs["Lit"]
        middle_state = g.math("GREATER_THAN", lit_middle, shaft_boundary.HALF - 1e-7)
        like_far = g.sub(1.0, g.math("ABSOLUTE", g.sub(middle_state, far_state)))
        far, lit_far = g.lerp(far, middle, like_far), g.lerp(lit_far, lit_middle, like_far)
        near, lit_near = g.lerp(middle, near, like_far), g.lerp(lit_middle, lit_near, like_far)
    weight = g.clamp(g.div(g.sub(shaft_boundary.HALF, lit_near), g.sub(lit_far, lit_near)), 0.0, 1.0)
    g.links.new(g.mul_add(g.sub(far, near), weight, near), gout.inputs["Edge"])
    return tree


def _march(g, gin, direction, length, sun, layout: ShaftLayout, chunk_trees, edge_tree, offset, chunk_names=None,
           integration_inputs=None):
    """Brute force: (lit length, first lit, integrated or None) from ``layout.steps`` shadow
    tests along the pixel's ray, at ``offset`` (a socket: 0.5 the step centres, or the
    pixel's jitter) within each step, chained through the chunk groups."""
    step = g.div(length, float(layout.steps))
    state = {name: default for name, _, default in MARCH_STATE}
    first = 0
    for name, count in march_chunks(layout.steps, chunk_names):
        node = g.node("CompositorNodeGroup")
        node.node_tree = chunk_trees[name]
        for socket, *_ in test_inputs(layout):
            g.links.new(gin.outputs[socket], node.inputs[socket])
        for socket, value in (("Direction", direction), ("Sun", sun), ("Step", step), ("First Step", float(first)),
                              ("Offset", offset), *state.items(), *(integration_inputs or {}).items()):
            g.feed(node.inputs[socket], value)
        state = {name: node.outputs[name] for name, *_ in MARCH_STATE}
        first += count
    lit_length = g.mul(state["Lit Length"], step)
    first_lit = g.math("MINIMUM", state["First Lit"], length)
    # The first shadow edge between its samples, as lut_gen.passes.aerial.light_shafts places it.
    crossed = g.math("LESS_THAN", state["Transition"], 0.5 * NEVER)
    k = g.math("MINIMUM", state["Transition"], max(layout.steps - 1, 1))     # finite where none
    edge = g.group(edge_tree, **{name: gin.outputs[name] for name, *_ in test_inputs(layout)},
                   Direction=direction, Near=g.mul(g.add(k, g.sub(offset, 1.0)), step), Far=g.mul(g.add(k, offset), step),
                   **{"Lit Near": state["Lit Before"], "Lit Far": state["Lit After"]})["Edge"]
    shift = g.mul(g.sub(state["Lit Before"], state["Lit After"]), g.sub(edge, g.mul(k, step)))
    lit_length = g.mul_add(shift, crossed, lit_length)
    starts_shadowed = g.mul(crossed, g.math("LESS_THAN", state["First State"], 0.5))
    first_lit = g.select(first_lit, edge, starts_shadowed)
    return lit_length, first_lit, state["Integrated"] if layout.single_mode == "INTEGRATION" else None
