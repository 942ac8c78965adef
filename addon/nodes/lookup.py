"""The shared 4D look-up group: seed 000's Listing 1 over our 2D atlas (see lut_gen/atlas.py).

Inputs are world quantities; the group applies eqs. (4)-(7) (Listing 2's horizon split for the
view zenith), filters the view- and sun-zenith axes in hardware inside a tile and blends the
four tiles of the neighbouring height and sun-view nodes by hand, then restores the Rayleigh
phase the tables are divided by. Its numpy twin is lut_gen.Luts.sky_radiance.
"""
from __future__ import annotations

import math

from ...lut_gen import parameterization as par
from ...lut_gen.atmosphere import RAYLEIGH_PHASE_NORM
from .builder import group_io, new_group

GROUP_NAME = "OLS Scattering Lookup"
TAN_PHI = math.tan(1.26 * 1.1)       # eq. (6), Bruneton's form


def height_coordinate(g, height, dims, params):
    """x_h of eq. (4) and the clamped height."""
    h = g.clamp(height, 0.0, params.atmosphere_height)
    u = g.math("SQRT", g.div(h, params.atmosphere_height))
    return g.mul(u, dims[0] - 1), h


def view_zenith_coordinate(g, cos_view, h, n_a, earth_radius):
    """x_a of eq. (5) with Listing 2's halves; the horizon flag is decided per look-up."""
    half = n_a // 2
    # c_h = -sqrt(h (2R + h)) / (R + h)
    c_h = g.math("MULTIPLY", -1.0, g.div(g.math("SQRT", g.mul(h, g.add(h, 2 * earth_radius))),
                                          g.add(h, earth_radius)))
    above = g.math("GREATER_THAN", cos_view, c_h)
    t_up = g.math("POWER", g.clamp(g.div(g.sub(cos_view, c_h), g.sub(1.0, c_h)), 0.0, 1.0), par.ALPHA_POWER)
    t_down = g.math("POWER", g.clamp(g.div(g.sub(c_h, cos_view), g.add(c_h, 1.0)), 0.0, 1.0), par.ALPHA_POWER)
    x_up = g.mul_add(t_up, half - 1, half)
    x_down = g.mul(t_down, half - 1)
    return g.lerp(x_down, x_up, above)


def sun_zenith_coordinate(g, cos_sun, n_s):
    """x_s of eq. (6)."""
    c = g.math("MAXIMUM", cos_sun, par.SUN_ZENITH_MIN_COS)
    u = g.mul(g.add(g.div(g.math("ARCTANGENT", g.mul(c, TAN_PHI)), 1.1), 1.0 - 0.26), 0.5)
    return g.mul(g.clamp(u, 0.0, 1.0), n_s - 1)


def sun_view_coordinate(g, cos_sun_view, n_t):
    """x_t of eq. (7)."""
    gamma = g.div(g.math("ARCCOSINE", g.clamp(cos_sun_view, -1.0, 1.0)), math.pi)
    d = g.mul(g.sub(gamma, 0.5), 2.0)
    shaped = g.mul(g.math("SIGN", d), g.math("POWER", g.math("ABSOLUTE", d), par.THETA_POWER))
    return g.mul(g.mul_add(shaped, 0.5, 0.5), n_t - 1)


def lower_node(g, x, n):
    """(i0, weight of i0 + 1) for linear interpolation on an n-node axis, as axis_weights."""
    x = g.clamp(x, 0.0, n - 1)
    i0 = g.math("MINIMUM", g.math("FLOOR", x), max(n - 2, 0))
    return i0, g.sub(x, i0)


def build_lookup_group(image, dims, params):
    """(Re)build the group for the scattering atlas ``image`` with table sizes ``dims``."""
    n_h, n_a, n_s, n_t = dims
    width, height = n_t * n_a, n_h * n_s
    tree = new_group(GROUP_NAME)
    g, gin, gout = group_io(tree,
                            [("Height", "NodeSocketFloat", 0.0), ("Cos View Zenith", "NodeSocketFloat", 1.0),
                             ("Cos Sun Zenith", "NodeSocketFloat", 1.0), ("Cos Sun View", "NodeSocketFloat", 1.0)],
                            [("Radiance", "NodeSocketVector", None)])
    x_h, h = height_coordinate(g, gin.outputs["Height"], dims, params)
    x_a = view_zenith_coordinate(g, gin.outputs["Cos View Zenith"], h, n_a, params.earth_radius)
    x_s = sun_zenith_coordinate(g, gin.outputs["Cos Sun Zenith"], n_s)
    x_t = sun_view_coordinate(g, gin.outputs["Cos Sun View"], n_t)
    i_h, w_h = lower_node(g, x_h, n_h)
    i_t, w_t = lower_node(g, x_t, n_t)
    # In-tile texel centres: u = (i_t n_a + x_a + 0.5) / W, v = (i_h n_s + x_s + 0.5) / H.
    in_tile_u = g.add(x_a, 0.5)
    in_tile_v = g.add(x_s, 0.5)

    def tile(dh, dt):
        u = g.div(g.mul_add(g.add(i_t, dt), n_a, in_tile_u), width)
        v = g.div(g.mul_add(g.add(i_h, dh), n_s, in_tile_v), height)
        return g.image(image, g.combine(u, v, 0.0))

    low_h = g.vlerp(tile(0, 0), tile(0, 1), w_t)
    high_h = g.vlerp(tile(1, 0), tile(1, 1), w_t)
    stored = g.vlerp(low_h, high_h, w_h)
    c_t = gin.outputs["Cos Sun View"]
    phase = g.mul(g.mul_add(c_t, c_t, 1.0), RAYLEIGH_PHASE_NORM)
    g.links.new(g.vscale(stored, phase), gout.inputs["Radiance"])
    return tree
