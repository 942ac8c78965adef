"""The shared 4D look-up group: Listing 1 of Yusov 2013 over our 2D atlas (see lut_gen/tables/atlas.py).

Inputs are world quantities; the group applies Yusov 2013 eqs. (4)-(7) (Listing 2's horizon split
for the view zenith), filters the view-zenith axis in hardware inside a tile, blends the
neighbouring sun-view nodes linearly and the neighbouring sun-zenith and height nodes geometrically
(lut_gen.tables.lookup.GEOMETRIC_AXES) by hand, then restores the Rayleigh
phase the tables are divided by, adds the single Mie table times the exact Mie phase, and
multiplies ground-hitting rays by their ground-ray scale. Its numpy twin is
lut_gen.Luts.sky_radiance.
"""
from __future__ import annotations

import math

from ...lut_gen.model import geometry
from ...lut_gen.tables import parameterization as par
from ...lut_gen.model.atmosphere import RAYLEIGH_PHASE_NORM
from .builder import group_io, new_group
from .optical import distance_to_ground
from ..scene import names

TAN_PHI = math.tan(1.26 * 1.1)       # Yusov 2013 eq. (6), Bruneton's form


def height_coordinate(g, height, dims, params):
    """x_h and the clamped height: Yusov 2013 eq. (4), or with fog the logarithmic axis that
    resolves the layer (lut_gen.tables.parameterization.height_to_x)."""
    h = g.clamp(height, 0.0, params.atmosphere_height)
    knee = par.fog_knee(params)
    if knee is None:
        u = g.math("SQRT", g.div(h, params.atmosphere_height))
    else:
        u = g.div(g.math("LOGARITHM", g.add(g.div(h, knee), 1.0), math.e),
                  math.log1p(params.atmosphere_height / knee))
    return g.mul(u, dims[0] - 1), h


def view_zenith_coordinate(g, cos_view, h, n_a, earth_radius, forced_flag=None):
    """x_a of Yusov 2013 eq. (5) with Listing 2's halves and the horizon flag used. The flag is
    decided per look-up unless ``forced_flag`` = (force 0/1, above 0/1) sockets pass an earlier
    one."""
    half = n_a // 2
    # c_h = -sqrt(h (2R + h)) / (R + h)
    c_h = g.math("MULTIPLY", -1.0, g.div(g.math("SQRT", g.mul(h, g.add(h, 2 * earth_radius))),
                                          g.add(h, earth_radius)))
    above = g.math("GREATER_THAN", cos_view, c_h)
    if forced_flag is not None:
        force, given = forced_flag
        above = g.lerp(above, given, force)
    t_up = g.math("POWER", g.clamp(g.div(g.sub(cos_view, c_h), g.sub(1.0, c_h)), 0.0, 1.0), par.ALPHA_POWER)
    t_down = g.math("POWER", g.clamp(g.div(g.sub(c_h, cos_view), g.add(c_h, 1.0)), 0.0, 1.0), par.ALPHA_POWER)
    x_up = g.mul_add(t_up, half - 1, half)
    x_down = g.mul(t_down, half - 1)
    return g.lerp(x_down, x_up, above), above


def sun_zenith_coordinate(g, cos_sun, n_s):
    """x_s of Yusov 2013 eq. (6)."""
    c = g.math("MAXIMUM", cos_sun, par.SUN_ZENITH_MIN_COS)
    u = g.mul(g.add(g.div(g.math("ARCTANGENT", g.mul(c, TAN_PHI)), 1.1), 1.0 - 0.26), 0.5)
    return g.mul(g.clamp(u, 0.0, 1.0), n_s - 1)


def sun_view_coordinate(g, cos_sun_view, n_t):
    """x_t of Yusov 2013 eq. (7)."""
    gamma = g.div(g.math("ARCCOSINE", g.clamp(cos_sun_view, -1.0, 1.0)), math.pi)
    d = g.mul(g.sub(gamma, 0.5), 2.0)
    shaped = g.mul(g.math("SIGN", d), g.math("POWER", g.math("ABSOLUTE", d), par.THETA_POWER))
    return g.mul(g.mul_add(shaped, 0.5, 0.5), n_t - 1)


def rayleigh_phase(g, cos_theta):
    """Rayleigh phase function (lut_gen.model.atmosphere.rayleigh_phase)."""
    return g.mul(g.mul_add(cos_theta, cos_theta, 1.0), RAYLEIGH_PHASE_NORM)


def mie_phase(g, cos_theta, mie_g):
    """Cornette-Shanks phase function (lut_gen.model.atmosphere.mie_phase)."""
    g2 = mie_g * mie_g
    norm = 3.0 / (8.0 * math.pi) * (1.0 - g2) / (2.0 + g2)
    peak = g.math("POWER", g.mul_add(cos_theta, -2.0 * mie_g, 1.0 + g2), 1.5)
    return g.div(g.mul(g.mul_add(cos_theta, cos_theta, 1.0), norm), peak)


def ground_ray_length(g, h, params):
    """lut_gen.tables.parameterization.ground_ray_length."""
    if not params.has_fog:
        return geometry.GROUND_RAY_SCALE_M
    return g.math("MINIMUM", g.div(g.math("EXPONENT", g.math("MINIMUM", g.div(h, params.fog_height), 50.0)), params.fog),
                  geometry.GROUND_RAY_SCALE_M)


def ground_ray_scale(g, h, cos_view, above, params):
    """lut_gen.model.geometry.ground_ray_scale for the half of the view axis the look-up used."""
    earth_radius = params.earth_radius
    distance = g.math("MAXIMUM", distance_to_ground(g, h, cos_view, earth_radius), geometry.MIN_GROUND_RAY_M)
    length = ground_ray_length(g, h, params)
    # l (1 - exp(-x)) as 2 l exp(-x/2) sinh(x/2): float32 keeps its precision for short rays.
    # Clamped: sinh overflows for the huge distances of rays that miss the ground (0 x inf).
    twice = 2.0 * length if isinstance(length, float) else g.mul(length, 2.0)
    half = g.math("MINIMUM", g.div(distance, twice), 20.0)
    scale = g.mul(g.mul(g.math("EXPONENT", g.mul(half, -1.0)), g.math("SINH", half)), twice)
    return g.lerp(scale, 1.0, above)


def even_odd_nodes(g, x, n):
    """The even and the odd node next to x with their linear-interpolation weights.

    Same result as blending floor(x) and floor(x) + 1, but each node index only jumps where
    its own weight is zero (the even one at odd x, the odd one at even x). A GPU picks mip
    levels from texture-coordinate derivatives, so a tile index that jumps where it still
    matters (floor) draws seam lines in EEVEE; a jump under zero weight cannot show."""
    x = g.clamp(x, 0.0, n - 1)
    even = g.math("MINIMUM", g.mul(g.math("FLOOR", g.mul(g.add(x, 1.0), 0.5)), 2.0), n - 1 - (n - 1) % 2)
    odd = g.math("MINIMUM", g.add(g.mul(g.math("FLOOR", g.mul(x, 0.5)), 2.0), 1.0), max(n - 1 - n % 2, 0))
    weight = lambda node: g.math("MAXIMUM", g.sub(1.0, g.math("ABSOLUTE", g.sub(x, node))), 0.0)
    return (even, weight(even)), (odd, weight(odd))


FILTERING = ("HARDWARE", "MANUAL")


def lower_node(g, x, n):
    """(floor node, weight of the next node) on an n-node axis, as lut_gen's axis_weights."""
    x = g.clamp(x, 0.0, n - 1)
    low = g.math("MINIMUM", g.math("FLOOR", x), max(n - 2, 0))
    return low, g.sub(x, low)




def build_lookup_group(image, dims, params, filtering="HARDWARE", compositor=False, name=None, *, mie_image,
                       fog_image=None):
    """(Re)build the group ``name`` (default: names.LOOKUP_GROUP or names.COMPOSITOR_LOOKUP_GROUP) for the
    scattering atlas ``image`` with table sizes ``dims``; ``mie_image``: the single Mie atlas
    for the tables that include single scattering, None only for "higher" (required: leaving it
    out would silently drop the aureole); ``fog_image``: the single fog atlas, required with it
    for params with fog.

    ``filtering``: "HARDWARE" blends the view-zenith axis with the texture unit (8 fetches; Cycles,
    which has no mipmaps). "MANUAL" fetches texel centres with Closest interpolation and blends them
    in the node tree (16 fetches): GPU engines (EEVEE) pick mip levels from texture-coordinate
    derivatives, which are large where Yusov 2013 eq. (5) is steep (just below the horizon), and a
    mipmapped fetch there mixes neighbouring tiles."""
    if filtering not in FILTERING:
        raise ValueError(f"filtering must be one of {FILTERING}, got {filtering!r}")
    if mie_image is not None and params.has_fog and fog_image is None:
        raise ValueError("these tables have fog: pass the single fog atlas (fog_image)")
    n_h, n_a, n_s, n_t = dims
    width, height = n_t * n_a, n_h * n_s
    inputs = [("Height", "NodeSocketFloat", 0.0), ("Cos View Zenith", "NodeSocketFloat", 1.0),
              ("Cos Sun Zenith", "NodeSocketFloat", 1.0), ("Cos Sun View", "NodeSocketFloat", 1.0)]
    outputs = [("Radiance", "NodeSocketVector", None)]
    # Yusov 2013 eq. (8) needs its second look-up on the first one's side of the seam.
    if compositor:
        inputs += [("Force Horizon", "NodeSocketFloat", 0.0), ("Above Horizon", "NodeSocketFloat", 1.0)]
        outputs += [("Above Horizon", "NodeSocketFloat", None)]
    tree = new_group(name or (names.COMPOSITOR_LOOKUP_GROUP if compositor else names.LOOKUP_GROUP),
                     "CompositorNodeTree" if compositor else "ShaderNodeTree")
    tree[names.FILTERING_KEY] = filtering
    g, gin, gout = group_io(tree, inputs, outputs)
    x_h, h = height_coordinate(g, gin.outputs["Height"], dims, params)
    forced = (gin.outputs["Force Horizon"], gin.outputs["Above Horizon"]) if compositor else None
    x_a, above = view_zenith_coordinate(g, gin.outputs["Cos View Zenith"], h, n_a, params.earth_radius, forced)
    if compositor:
        g.links.new(above, gout.inputs["Above Horizon"])
    x_s = sun_zenith_coordinate(g, gin.outputs["Cos Sun Zenith"], n_s)
    x_t = sun_view_coordinate(g, gin.outputs["Cos Sun View"], n_t)

    # Node indices, weights and texture coordinates are shared by both atlases: made once.
    h_nodes = even_odd_nodes(g, x_h, n_h)
    t_nodes = even_odd_nodes(g, x_t, n_t)
    s0, w_s = lower_node(g, x_s, n_s)
    # v of sun-zenith row s0 + j in the tile row of height node k (texel centres at +0.5)
    v_of = {(k, j): g.div(g.mul_add(i_h, n_s, g.add(s0, 0.5 + j)), height)
            for k, (i_h, _) in enumerate(h_nodes) for j in (0, 1)}
    if filtering == "HARDWARE":
        x_a_centre = g.add(x_a, 0.5)
        u_of = {k: g.div(g.mul_add(i_t, n_a, x_a_centre), width) for k, (i_t, _) in enumerate(t_nodes)}
        uv_of = {(kh, kt, j): g.combine(u_of[kt], v_of[kh, j], 1.0)         # z: Map UV's alpha
                 for kh in (0, 1) for kt in (0, 1) for j in (0, 1)}

        def row(atlas, kh, kt, j):
            """Sun-zenith node s0 + j of a tile, interpolated along the view zenith."""
            return g.image(atlas, uv_of[kh, kt, j], interpolation="Linear")
    else:
        a0, w_a = lower_node(g, x_a, n_a)
        a_centre = g.add(a0, 0.5)
        u_of = {(k, m): g.div(g.mul_add(i_t, n_a, g.add(a_centre, float(m))), width)
                for k, (i_t, _) in enumerate(t_nodes) for m in (0, 1)}
        uv_of = {(kh, kt, j, m): g.combine(u_of[kt, m], v_of[kh, j], 1.0)
                 for kh in (0, 1) for kt in (0, 1) for j in (0, 1) for m in (0, 1)}

        def row(atlas, kh, kt, j):
            return g.vlerp(g.image(atlas, uv_of[kh, kt, j, 0], interpolation="Closest"),
                           g.image(atlas, uv_of[kh, kt, j, 1], interpolation="Closest"), w_a)

    def interpolated(atlas):
        """Linear along the view zenith and the sun-view angle, geometric along the sun zenith
        and the height (lut_gen.tables.lookup.GEOMETRIC_AXES)."""
        at_height = []
        for kh in (0, 1):
            sun_rows = []
            for j in (0, 1):
                total = None
                for kt, (_, w_t) in enumerate(t_nodes):
                    term = g.vscale(row(atlas, kh, kt, j), w_t)
                    total = term if total is None else g.vmath("ADD", total, term)
                sun_rows.append(total)
            at_height.append(g.vgeometric_lerp(sun_rows[0], sun_rows[1], w_s))
        # even and odd height node; their weights sum to 1
        return g.vgeometric_lerp(at_height[0], at_height[1], h_nodes[1][1])

    c_t = gin.outputs["Cos Sun View"]
    radiance = g.vscale(interpolated(image), rayleigh_phase(g, c_t))
    if mie_image is not None:
        radiance = g.vmath("ADD", radiance, g.vscale(interpolated(mie_image), mie_phase(g, c_t, params.mie_g)))
        if params.has_fog:
            radiance = g.vmath("ADD", radiance, g.vscale(interpolated(fog_image), mie_phase(g, c_t, params.fog_g)))
    scale = ground_ray_scale(g, h, gin.outputs["Cos View Zenith"], above, params)
    g.links.new(g.vscale(radiance, scale), gout.inputs["Radiance"])
    return tree


def filtering_for_engine(engine: str) -> str:
    return "HARDWARE" if engine == "CYCLES" else "MANUAL"
