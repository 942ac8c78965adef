"""Look-ups into the optical-depth and ambient-skylight images shared by the sky and terrain
groups (the sample's texture coordinates: (h / H_atm, c * 0.5 + 0.5) and (c * 0.5 + 0.5, 0.5)). Texture
coordinates carry z = 1: the compositor's Map UV reads z as alpha."""
from __future__ import annotations

import math

import bpy

from ...lut_gen.passes import aerial as aerial_twin
from ...lut_gen.model import geometry
from ...lut_gen.model.profiles import OZONE_HALF_WIDTH_M, OZONE_PEAK_HEIGHT_M
from ...lut_gen.tables.optical_depth import EARTH_HIT_NET_DENSITY
from ..scene import names
from ..scene.tables.luts import fog_depth_image
from .builder import group_io, new_group


def point_frame(g, point, params):
    """(height above the ground, local up) of a world point; the Earth centre is at (0, 0, -R).
    Height as (|P|^2 + 2 z R) / (|P + R z^| + R): the plain |P + R z^| - R loses metres to
    float32 cancellation at R = 6.36e6 m."""
    from_centre = g.vmath("ADD", point, (0.0, 0.0, params.earth_radius))
    z = g.separate(point)[2]
    numerator = g.mul_add(z, 2.0 * params.earth_radius, g.vmath("DOT_PRODUCT", point, point))
    height = g.div(numerator, g.add(g.vmath("LENGTH", from_centre), params.earth_radius))
    return g.math("MAXIMUM", height, 0.0), g.vmath("NORMALIZE", from_centre)


def net_density_to_top(g, image, height, cos_zenith, params):
    """(Rayleigh, Mie, ozone) net densities to the top (1e20 where the ray hits the Earth), and
    the fog's fourth for params with fog; below the table's first row the Rayleigh and Mie
    columns are scaled by exp(dh / H), the fog's stored column by the fog density at the ray's
    lowest point, as in the twin, lut_gen.Luts.net_density_to_top."""
    safe_cos = horizon_safe_cos(g, height, cos_zenith, image.size[0], image.size[1], params)
    uv = g.combine(g.div(height, params.atmosphere_height), g.mul_add(safe_cos, 0.5, 0.5), 1.0)
    rayleigh, mie, ozone = g.separate(g.image(image, uv))
    first_row = params.atmosphere_height / (2 * image.size[0])
    below = g.math("MAXIMUM", g.sub(first_row, height), 0.0)
    rayleigh = g.mul(rayleigh, g.math("EXPONENT", g.div(below, params.rayleigh_scale_height)))
    mie = g.mul(mie, g.math("EXPONENT", g.div(below, params.mie_scale_height)))
    fog_image = fog_depth_image(image, params)
    if fog_image is None:
        return rayleigh, mie, ozone
    column = g.separate(g.image(fog_image, uv))[0]
    scale = g.math("EXPONENT", g.div(lowest_height(g, height, cos_zenith, params), -params.fog_height))
    return rayleigh, mie, ozone, g.math("MINIMUM", g.mul(column, scale), EARTH_HIT_NET_DENSITY)


def lowest_height(g, height, cos_zenith, params):
    """Height of the lowest point of the ray to the top: the start going up, the tangent point
    going down (0 for rays that reach the ground). Twin: lut_gen.tables.optical_depth.lowest_height."""
    h = g.math("MAXIMUM", height, 0.0)
    r = g.add(h, params.earth_radius)
    sin = g.math("SQRT", g.math("MAXIMUM", g.sub(1.0, g.mul(cos_zenith, cos_zenith)), 0.0))
    r_cos = g.mul(r, cos_zenith)
    # r sin - R as (r^2 sin^2 - R^2) / (r sin + R): float-safe near the ground
    tangent = g.div(g.sub(g.mul(h, g.add(h, 2.0 * params.earth_radius)), g.mul(r_cos, r_cos)),
                    g.mul_add(r, sin, params.earth_radius))
    going_down = g.math("LESS_THAN", cos_zenith, 0.0)
    return g.lerp(h, g.clamp(tangent, 0.0, h), going_down)


def horizon_cos(g, height, params):
    """c_h = -sqrt(h (2R + h)) / (R + h), the zenith cosine of the horizon from height h."""
    return g.mul(-1.0, g.div(g.math("SQRT", g.mul(height, g.add(height, 2 * params.earth_radius))),
                             g.add(height, params.earth_radius)))


def horizon_safe_cos(g, height, cos_zenith, n_heights, n_cos, params):
    """Rays above the horizon read the table at least at the first cos node above the horizon
    of the lower height row the filter blends, so no Earth-hit texel (1e20) leaks into them.
    Twin: lut_gen.tables.optical_depth.horizon_safe_cos."""
    row = g.math("MAXIMUM", g.math("FLOOR", g.mul_add(height, n_heights / params.atmosphere_height, -0.5)), 0.0)
    lower_row_height = g.mul(g.add(row, 0.5), params.atmosphere_height / n_heights)
    node = g.math("CEIL", g.mul_add(g.mul_add(horizon_cos(g, lower_row_height, params), 0.5, 0.5), n_cos, -0.5))
    first_node_above = g.mul_add(g.add(node, 0.5), 2.0 / n_cos, -1.0)
    above = g.math("GREATER_THAN", cos_zenith, horizon_cos(g, height, params))
    return g.lerp(cos_zenith, g.math("MAXIMUM", cos_zenith, first_node_above), above)


def optical_depth_of(g, net, params):
    """(R, G, B) optical depth beta_R D_R + beta_M^ext D_M + beta_O D_O [+ beta_F D_F] of the three
    or four net densities (or densities) ``net``."""
    extinction = params.extinction_matrix()      # RGB rows (spectral params: fitted, see lut_gen.model.spectrum)
    optical_depth = None
    for row, density in zip(extinction, net):
        term = g.vscale(tuple(row), density)
        optical_depth = term if optical_depth is None else g.vmath("ADD", optical_depth, term)
    return optical_depth


def transmittance_of_optical_depth(g, optical_depth):
    """exp(-tau) per channel (tau capped at 80: 1e20 net densities stay finite)."""
    channels = [g.math("EXPONENT", g.mul(g.math("MINIMUM", c, 80.0), -1.0)) for c in g.separate(optical_depth)]
    return g.combine(*channels)


def transmittance_from_net_density(g, *net, params):
    """exp(-optical depth) per channel for the three or four net densities of net_density_to_top."""
    return transmittance_of_optical_depth(g, optical_depth_of(g, net, params))


def transmittance_to_top(g, image, height, cos_zenith, params):
    """Transmittance from a point to the top; 0 where the ray hits the Earth (the table holds
    1e20 there). Twin: lut_gen.Luts.transmittance_to_top."""
    return transmittance_from_net_density(g, *net_density_to_top(g, image, height, cos_zenith, params), params=params)


def ambient_skylight(g, image, cos_sun_zenith):
    """E_sky per unit sun for the sun's zenith cosine. Twin: lut_gen.Luts.ambient_skylight."""
    return g.image(image, g.combine(g.mul_add(cos_sun_zenith, 0.5, 0.5), 0.5, 1.0))


def distance_to_ground(g, height, cos_view, earth_radius):
    """lut_gen.model.geometry.distance_to_ground, in its cancellation-free (float32-safe) form."""
    radius = g.add(height, earth_radius)
    rise = g.mul(height, g.add(height, 2.0 * earth_radius))
    r_cos = g.mul(radius, cos_view)
    root = g.math("SQRT", g.math("MAXIMUM", g.sub(g.mul(r_cos, r_cos), rise), 0.0))
    return g.div(rise, g.math("MAXIMUM", g.sub(root, r_cos), geometry.GROUND_DISTANCE_MIN_DENOMINATOR))


def ground_radiance(g, optical_image, ambient_image, height, cos_view, cos_sun, cos_sun_view, params):
    """Light the Lambertian ground reflects toward the viewer per unit sun, 0 for rays that miss
    it: T(view) * albedo / pi * (direct sun + ambient skylight) at the ground point. Twin:
    lut_gen.Luts.ground_radiance."""
    height = g.clamp(height, 0.0, params.atmosphere_height)       # as lut_gen.tables.ground.ground_point
    radius = g.add(height, params.earth_radius)
    distance = g.math("MINIMUM", distance_to_ground(g, height, cos_view, params.earth_radius),
                      2.0 * math.sqrt(params.top_radius ** 2 - params.earth_radius ** 2))
    cos_sun_at = g.clamp(g.div(g.mul_add(radius, cos_sun, g.mul(distance, cos_sun_view)), params.earth_radius), -1.0, 1.0)
    cos_back = g.clamp(g.div(g.mul_add(radius, cos_view, distance), -params.earth_radius), 0.0, 1.0)
    from_ground = net_density_to_top(g, optical_image, 0.0, cos_back, params)
    from_viewer = net_density_to_top(g, optical_image, height, g.mul(cos_view, -1.0), params)
    view = transmittance_from_net_density(
        g, *[g.math("MAXIMUM", g.sub(a, b), 0.0) for a, b in zip(from_ground, from_viewer)], params=params)
    lit_cos = g.math("MAXIMUM", cos_sun_at, 0.0)
    direct = g.vscale(transmittance_to_top(g, optical_image, 0.0, lit_cos, params), lit_cos)
    lit = g.vmath("ADD", direct, ambient_skylight(g, ambient_image, cos_sun_at))
    weight = g.mul(below_horizon(g, height, cos_view, params), params.ground_albedo / math.pi)
    return g.vscale(g.vmath("MULTIPLY", view, lit), weight)


def below_horizon(g, height, cos_view, params):
    """1 where a ray from ``height`` with zenith cosine ``cos_view`` runs into the Earth."""
    return g.math("LESS_THAN", cos_view, horizon_cos(g, height, params))




def build_segment_transmittance_group(image, params):
    """"OLS Segment Transmittance" (compositor): the transmittance between two world points,
    shared by the scattering groups (a big tree of its own; node trees grow slow to edit)."""
    tree = new_group(names.SEGMENT_GROUP, "CompositorNodeTree")
    inputs = [(name, "NodeSocketVector", (0.0, 0.0, 0.0)) for name in ("Start", "End", "Direction")]
    g, gin, gout = group_io(tree, inputs, [("Transmittance", "NodeSocketVector", None)])
    g.links.new(segment_transmittance(g, image, gin.outputs["Start"], gin.outputs["End"], gin.outputs["Direction"], params),
                gout.inputs["Transmittance"])
    return tree


def segment_transmittance_node(g, start, end, direction):
    """The transmittance start -> end through an "OLS Segment Transmittance" node."""
    return g.group(bpy.data.node_groups[names.SEGMENT_GROUP], start=start, end=end, direction=direction)["Transmittance"]


def segment_transmittance(g, image, start, end, direction, params):
    """Transmittance between world points ``start`` and ``end``, ``direction`` the unit vector
    from one to the other: net density to the top from the start minus from the end, along the
    reversed ray where the forward one from either end runs into the ground (the table holds
    1e20 there); for rays grazing the horizon, where that difference is ill-conditioned, an
    8-point Gauss-Legendre sum of the densities along the segment (blended over
    QUADRATURE_BAND). Twin: lut_gen.passes.aerial.segment_transmittance."""
    (h_s, up_s), (h_e, up_e) = point_frame(g, start, params), point_frame(g, end, params)
    reverse = g.vscale(direction, -1.0)
    cos_s, cos_e = g.vmath("DOT_PRODUCT", direction, up_s), g.vmath("DOT_PRODUCT", direction, up_e)
    cos_back_e = g.vmath("DOT_PRODUCT", reverse, up_e)
    forward_s = net_density_to_top(g, image, h_s, cos_s, params)
    forward_e = net_density_to_top(g, image, h_e, cos_e, params)
    backward_e = net_density_to_top(g, image, h_e, cos_back_e, params)
    backward_s = net_density_to_top(g, image, h_s, g.vmath("DOT_PRODUCT", reverse, up_s), params)
    hits = g.math("MAXIMUM", below_horizon(g, h_s, cos_s, params), below_horizon(g, h_e, cos_e, params))
    # A select, not a lerp: near the end's horizon its forward entry is a filtered blend of the
    # 1e20 marker (1e18-1e20), and fs - fe then swamps the reversed difference in float32.
    table = [g.select(g.sub(fs, fe), g.sub(be, bs), hits)
             for fs, fe, be, bs in zip(forward_s, forward_e, backward_e, backward_s)]
    horizon = g.lerp(g.sub(cos_s, horizon_cos(g, h_s, params)), g.sub(cos_back_e, horizon_cos(g, h_e, params)), hits)
    low, high = aerial_twin.QUADRATURE_BAND
    weight = g.node("ShaderNodeMapRange", interpolation_type="SMOOTHSTEP")
    for name, value in (("Value", horizon), ("From Min", low), ("From Max", high), ("To Min", 0.0), ("To Max", 1.0)):
        g.feed(weight.inputs[name], value)
    quadrature = quadrature_net_density(g, start, end, params)
    net = [g.math("MAXIMUM", g.lerp(q, t, weight.outputs["Result"]), 0.0) for q, t in zip(quadrature, table)]
    return transmittance_from_net_density(g, *net, params=params)


def quadrature_net_density(g, start, end, params):
    """(Rayleigh, Mie, ozone[, fog]) net densities along start -> end, 8-point Gauss-Legendre.
    Twin: lut_gen.passes.aerial.quadrature_net_density."""
    segment = g.vmath("SUBTRACT", end, start)
    half_length = g.mul(g.vmath("LENGTH", segment), 0.5)
    sums = [0.0] * (4 if params.has_fog else 3)
    for node, weight in zip(aerial_twin.GAUSS_NODES, aerial_twin.GAUSS_WEIGHTS):
        height, _ = point_frame(g, g.vmath("MULTIPLY_ADD", segment, (0.5 * (node + 1.0),) * 3, start), params)
        densities = [g.math("EXPONENT", g.div(height, -params.rayleigh_scale_height)),
                     g.math("EXPONENT", g.div(height, -params.mie_scale_height)), ozone_density(g, height)]
        if params.has_fog:
            densities.append(g.math("EXPONENT", g.div(height, -params.fog_height)))
        sums = [g.mul_add(d, float(weight), acc) for d, acc in zip(densities, sums)]
    return [g.mul(total, half_length) for total in sums]


def ozone_density(g, height):
    """Bruneton's tent profile (lut_gen.model.profiles.ozone_density)."""
    return g.clamp(g.sub(1.0, g.div(g.math("ABSOLUTE", g.sub(height, OZONE_PEAK_HEIGHT_M)), OZONE_HALF_WIDTH_M)), 0.0, 1.0)
