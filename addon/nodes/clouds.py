""""OLS Clouds": what a view ray of the world sees of the cloud layer. Twin:
lut_gen.clouds.sky.view with air=lut_gen.clouds.air_map.lookup (the formulas and their reasons
are there); the sky group composites it (addon/nodes/sky.py). It reads the same cloud map,
higher-orders table and air map images the numpy code reads, so the twin is exact up to float32.
The air map (the terms that depend on the ray's direction alone, recomputed per frame by
scene/frame/skylight.py) replaced a 4D sky look-up and four optical-depth look-ups per ray.

Outputs, as the camera sees them (times the air's transmittance T camera -> cloud): Alpha (the
share of the light behind the cloud it hides), Light (T x the cloud's own light per unit sun),
Sky Behind (T x the sky's radiance from the cloud on, per unit sun, from the 4D table); Air
Shade and Air Shade Single (what the clouds take off the clear sky's air in front of them, per
unit sun: lut_gen.clouds.air_shade.Shade's rest and single).
"""
from __future__ import annotations

import math

from ...lut_gen.clouds import air_map, field, slab
from ..scene import names
from .builder import group_io, new_group
from .optical import below_horizon

INPUTS = [
    ("View", "NodeSocketVector", (0.0, 0.0, 1.0)),            # unit direction of the ray
    ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)),
    ("Camera Height", "NodeSocketFloat", 2.0),
    ("Camera XY", "NodeSocketVector", (0.0, 0.0, 0.0)),       # the camera's world x, y: where the map is read
    ("Coverage", "NodeSocketFloat", 0.4),
    ("Base", "NodeSocketFloat", 1500.0),
    ("Thickness", "NodeSocketFloat", 600.0),
    ("Density", "NodeSocketFloat", 20.0 / 600.0),
    ("Scale", "NodeSocketFloat", 2000.0),
    ("Offset", "NodeSocketVector", (0.0, 0.0, 0.0)),
]
OUTPUTS = [("Alpha", "NodeSocketFloat", None), ("Light", "NodeSocketVector", None),
           ("Sky Behind", "NodeSocketVector", None),
           # lut_gen.clouds.air_shade.Shade: what the clouds take off the air in front of them
           ("Air Shade", "NodeSocketVector", None), ("Air Shade Single", "NodeSocketVector", None)]


def phase(g, cos_theta):
    """lut_gen.clouds.slab.phase."""
    total = 0.0
    for weight, asym in slab.PHASE_LOBES:
        base = g.mul_add(cos_theta, -2.0 * asym, 1.0 + asym * asym)
        lobe = g.div(weight * (1.0 - asym * asym) / (4.0 * math.pi), g.math("POWER", g.math("MAXIMUM", base, 1e-9), 1.5))
        total = lobe if isinstance(total, float) else g.add(total, lobe)
    return total


def _exp_ratio(g, a, b):
    """slab._exp_ratio: exp(-min(a, b)) (1 - exp(-d)) / d, d = |b - a|, its series for small d."""
    d = g.math("ABSOLUTE", g.sub(b, a))
    small = g.math("LESS_THAN", d, slab.SERIES_BELOW)
    series = g.mul_add(d, g.mul_add(d, 1.0 / 6.0, -0.5), 1.0)
    safe = g.select(d, 1.0, small)
    exact = g.div(g.sub(1.0, g.math("EXPONENT", g.mul(safe, -1.0))), safe)
    return g.mul(g.math("EXPONENT", g.mul(g.math("MINIMUM", a, b), -1.0)), g.select(exact, series, small))


def _single_scattering(g, tau, mu_s, mu_v, cos_sun_view, reflected):
    """slab.single_scattering, the transmitted or the reflected form by ``reflected``."""
    p = phase(g, cos_sun_view)
    through = g.mul(g.div(g.mul(p, tau), mu_v), _exp_ratio(g, g.div(tau, mu_v), g.div(tau, mu_s)))
    inverse_sum = g.add(g.div(1.0, mu_s), g.div(1.0, mu_v))
    back = g.mul(g.div(g.mul(p, mu_s), g.add(mu_s, mu_v)),
                 g.sub(1.0, g.math("EXPONENT", g.mul(g.mul(tau, inverse_sum), -1.0))))
    return g.select(through, back, reflected)


def two_stream(g, tau, mu_s):
    """slab.two_stream: (reflected, diffusely transmitted) flux fractions."""
    f, asym = slab.DELTA_FRACTION, slab.SCALED_ASYMMETRY
    gamma1 = 0.75 * (1.0 - asym)
    scaled = g.mul(tau, 1.0 - f)
    gamma3 = g.mul_add(mu_s, -3.0 * asym / 4.0, 0.5)
    direct_scaled = g.math("EXPONENT", g.div(g.mul(scaled, -1.0), mu_s))
    numerator = g.add(g.mul(scaled, gamma1), g.mul(g.sub(gamma3, g.mul(mu_s, gamma1)), g.sub(1.0, direct_scaled)))
    reflected = g.div(numerator, g.mul_add(scaled, gamma1, 1.0))
    direct = g.math("EXPONENT", g.div(g.mul(tau, -1.0), mu_s))
    return reflected, g.math("MAXIMUM", g.sub(g.sub(1.0, reflected), direct), 0.0)


def diffuse_two_stream(g, tau):
    """slab.diffuse_two_stream."""
    f, asym = slab.DELTA_FRACTION, slab.SCALED_ASYMMETRY
    x = g.mul(tau, 0.75 * (1.0 - asym) * (1.0 - f))
    back = g.div(x, g.add(x, 1.0))
    through = g.math("MAXIMUM", g.sub(g.sub(1.0, back), g.math("EXPONENT", g.mul(tau, -2.0))), 0.0)
    return back, through


def _table_texel(g, cosine):
    n = len(slab.TABLE_COS)
    scaled = g.mul(g.sub(cosine, slab.TABLE_COS[0]), (n - 1) / (slab.TABLE_COS[-1] - slab.TABLE_COS[0]))
    return g.add(g.clamp(scaled, 0.0, n - 1.0), 0.5)


def _log2_tau(g, tau):
    """log2(tau), floored: both tables' tau axes are log2-spaced (one node a ray)."""
    return g.math("LOGARITHM", g.math("MAXIMUM", tau, 1e-12), 2.0)


def _higher_orders(g, table_image, tau, log_tau, abs_sun, mu_s, abs_view, cos_az, reflected):
    """slab.higher_orders: two fetches (the tau nodes around tau) of the table image."""
    n_cos, n_tau = len(slab.TABLE_COS), len(slab.TABLE_TAUS)
    x_tau = g.clamp(g.sub(log_tau, math.log2(slab.TABLE_TAUS[0])), 0.0, n_tau - 1.0)
    low = g.math("MINIMUM", g.math("FLOOR", x_tau), n_tau - 2.0)
    weight = g.sub(x_tau, low)
    ts, tv = _table_texel(g, abs_sun), _table_texel(g, abs_view)
    v = g.div(g.mul_add(reflected, n_cos, ts), float(slab.TABLE_ROWS))
    fetches = []
    for node in (low, g.add(low, 1.0)):
        u = g.div(g.mul_add(node, n_cos, tv), n_tau * n_cos)
        fetches.append(g.image_rgba(table_image, g.combine(u, v, 1.0)))
    terms = g.separate(g.vlerp(fetches[0][0], fetches[1][0], weight))
    fourth = g.lerp(fetches[0][1], fetches[1][1], weight)
    cos2 = g.mul_add(g.mul(cos_az, cos_az), 2.0, -1.0)
    cos3 = g.sub(g.mul(g.mul(cos_az, cos2), 2.0), cos_az)
    shape = g.math("EXPONENT", g.add(g.add(g.mul_add(terms[1], cos_az, terms[0]), g.mul(terms[2], cos2)),
                                     g.mul(fourth, cos3)))
    back, through = two_stream(g, tau, mu_s)
    return g.mul(g.mul(shape, g.mul(mu_s, 1.0 / math.pi)), g.select(through, back, reflected))


def diffuse_shares(g, table_image, tau, log_tau, abs_view):
    """slab.diffuse_shares: (reflected, let through), one fetch of the table image's diffuse
    block (columns the tau nodes, rows the view nodes, R let through, G reflected)."""
    n_cos, n_tau = len(slab.TABLE_COS), len(slab.DIFFUSE_TAUS)
    x_tau = g.clamp(g.mul(g.sub(log_tau, math.log2(slab.DIFFUSE_TAUS[0])), float(slab.DIFFUSE_TAUS_PER_OCTAVE)),
                    0.0, n_tau - 1.0)
    u = g.div(g.add(x_tau, 0.5), float(len(slab.TABLE_TAUS) * n_cos))
    v = g.div(g.add(_table_texel(g, abs_view), 2.0 * n_cos), float(slab.TABLE_ROWS))
    through_shape, back_shape, _ = g.separate(g.image(table_image, g.combine(u, v, 1.0)))
    back, through = diffuse_two_stream(g, tau)
    return g.mul(back, back_shape), g.mul(through, through_shape)


def _cos_azimuth(g, cos_view, cos_sun, cos_sun_view):
    """slab.cos_azimuth."""
    across = g.math("SQRT", g.mul(g.math("MAXIMUM", g.sub(1.0, g.mul(cos_view, cos_view)), 0.0),
                                  g.math("MAXIMUM", g.sub(1.0, g.mul(cos_sun, cos_sun)), 0.0)))
    ratio = g.clamp(g.div(g.sub(cos_sun_view, g.mul(cos_view, cos_sun)), g.math("MAXIMUM", across, 1e-6)), -1.0, 1.0)
    return g.select(1.0, ratio, g.math("GREATER_THAN", across, 1e-6))


def column_fraction(g, map_image, x, y, scale, offset, coverage):
    """lut_gen.clouds.sky.column_fraction: the map sampled with wrapping, then thresholded."""
    off_x, off_y, _ = g.separate(offset)
    tile = g.mul(scale, float(field.TILE_FEATURES))
    uv = g.combine(g.div(g.add(x, off_x), tile), g.div(g.add(y, off_y), tile), 0.0)
    threshold = g.mul_add(g.sub(1.0, coverage), 1.0 + field.SOFTNESS, -field.SOFTNESS)
    return thickness_fraction(g, map_image, uv, threshold)


def thickness_fraction(g, map_image, uv, threshold):
    """field.thickness_fraction of the map's rank at map coordinates ``uv`` (wrapping), for
    shader and compositor trees alike."""
    rank = g.separate(g.image(map_image, uv, repeat=True))[0]
    # clamp((rank - threshold) / SOFTNESS, 0, 1) as one clamped node per pixel: the light
    # shafts run this in every march step, where the compositor pays per image-wide node (the
    # threshold's term is a single value).
    return g.math("MULTIPLY_ADD", rank, 1.0 / field.SOFTNESS, g.div(threshold, -field.SOFTNESS), clamp=True)


def air_terms(g, air_image, view):
    """lut_gen.clouds.air_map.lookup: the tiles' colours (air_map.TILES, in order) at the ray's
    direction ``view``."""
    view_x, view_y, view_z = g.separate(view)
    width, height = air_map.SIZE
    u = g.add(g.div(g.math("ARCTAN2", view_x, view_y), 2 * math.pi), 0.5)
    elevation = g.math("ARCSINE", g.clamp(view_z, -1.0, 1.0))
    v = g.mul_add(g.mul(g.math("SIGN", elevation), g.math("SQRT", g.div(g.math("ABSOLUTE", elevation), 0.5 * math.pi))),
                  0.5, 0.5)
    rows = len(air_map.TILES) * (height + 2)
    in_tile = g.mul(v, height / rows)
    return [g.image(air_image, g.combine(u, g.add(in_tile, (tile * (height + 2) + 1) / rows), 1.0), repeat=True)
            for tile in range(len(air_map.TILES))]


def middle_hit(g, height, middle, view_z, earth_radius):
    """lut_gen.clouds.layer.middle_hit, cancellation-free: (distance, meets 0/1, the ray's
    (R + h) cos term, which the caller reuses)."""
    b = g.mul(g.add(height, earth_radius), view_z)
    q = g.mul(g.sub(middle, height), g.add(g.add(height, middle), 2.0 * earth_radius))
    disc = g.mul_add(b, b, q)
    root = g.math("SQRT", g.math("MAXIMUM", disc, 0.0))
    upward = g.div(q, g.math("MAXIMUM", g.add(b, root), 1e-9))
    downward = g.div(g.mul(q, -1.0), g.math("MAXIMUM", g.sub(root, b), 1e-9))
    below = g.math("GREATER_THAN", q, 0.0)
    distance = g.select(downward, upward, below)
    goes_down = g.mul(g.math("GREATER_THAN", disc, -1e-30), g.math("LESS_THAN", view_z, 0.0))
    return distance, g.select(goes_down, 1.0, below), b


def build_cloud_group(map_image, table_image, air_image, params):
    tree = new_group(names.CLOUDS_GROUP)
    g, gin, gout = group_io(tree, INPUTS, OUTPUTS)
    view = g.vmath("NORMALIZE", gin.outputs["View"])
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    view_x, view_y, view_z = g.separate(view)
    height = g.math("MAXIMUM", gin.outputs["Camera Height"], 0.0)
    earth = params.earth_radius
    middle = g.mul_add(gin.outputs["Thickness"], 0.5, gin.outputs["Base"])

    distance, meets, b = middle_hit(g, height, middle, view_z, earth)
    hits_ground = g.mul(below_horizon(g, g.math("MINIMUM", height, params.atmosphere_height), view_z, params),
                        g.math("LESS_THAN", height, middle))
    hit = g.mul(meets, g.sub(1.0, hits_ground))
    distance = g.mul(distance, hit)

    radius = g.add(middle, earth)
    cos_view = g.div(g.add(distance, b), radius)
    cos_sun_view = g.vmath("DOT_PRODUCT", view, sun)
    sun_z = g.separate(sun)[2]
    cos_sun = g.div(g.mul_add(distance, cos_sun_view, g.mul(g.add(height, earth), sun_z)), radius)

    camera_x, camera_y, _ = g.separate(gin.outputs["Camera XY"])
    fraction = column_fraction(g, map_image, g.mul_add(distance, view_x, camera_x), g.mul_add(distance, view_y, camera_y),
                                gin.outputs["Scale"], gin.outputs["Offset"], gin.outputs["Coverage"])
    tau = g.mul(g.mul(g.mul(gin.outputs["Density"], gin.outputs["Thickness"]), fraction), hit)
    abs_view = g.math("MAXIMUM", g.math("ABSOLUTE", cos_view), slab.MIN_COS)
    abs_sun = g.math("ABSOLUTE", cos_sun)
    mu_s = g.math("MAXIMUM", abs_sun, slab.MIN_COS)
    alpha = g.sub(1.0, g.math("EXPONENT", g.div(g.mul(tau, -1.0), abs_view)))
    reflected = g.math("LESS_THAN", g.mul(cos_view, cos_sun), 0.0)
    cos_az = _cos_azimuth(g, cos_view, cos_sun, cos_sun_view)
    log_tau = _log2_tau(g, tau)
    sun_share = g.add(_single_scattering(g, tau, mu_s, abs_view, cos_sun_view, reflected),
                      _higher_orders(g, table_image, tau, log_tau, abs_sun, mu_s, abs_view, cos_az, reflected))
    back, through = diffuse_shares(g, table_image, tau, log_tau, abs_view)
    looking_up = g.math("GREATER_THAN", cos_view, 0.0)
    ambient_share = g.select(back, through, looking_up)
    bounce_share = g.select(through, back, looking_up)
    terms = dict(zip(air_map.TILES, air_terms(g, air_image, view)))
    light = g.vmath("ADD", g.vmath("ADD", g.vscale(terms["sun"], sun_share), g.vscale(terms["ambient"], ambient_share)),
                    g.vscale(terms["bounce"], bounce_share))

    for name, socket in (("Alpha", g.mul(alpha, hit)), ("Light", g.vscale(light, hit)),
                         ("Sky Behind", g.vscale(terms["behind"], hit)), ("Air Shade", g.vscale(terms["shade_rest"], hit)),
                         ("Air Shade Single", g.vscale(terms["shade_single"], hit))):
        g.links.new(socket, gout.inputs[name])
    return tree
