"""Eq. (8) of Yusov 2013 in a compositor tree: light scattered toward the camera from a ray section
start -> end, T(C->start) L(start) - T(C->end) L(end), both look-ups on the side of the horizon seam
the first one chose (Yusov 2013 Listing 2). Twin: lut_gen.passes.aerial.section_inscattering."""
from __future__ import annotations

import bpy

from ...lut_gen.passes.aerial import HORIZON_BLEND, HORIZON_BLEND_HEIGHT, uses_horizon_blend
from .builder import group_io, new_group
from .optical import horizon_cos, point_frame
from ..scene import names


def lookup_group_name(table: str) -> str:
    """Compositor look-up group of a scattering table ("multiple" keeps the original name)."""
    return names.COMPOSITOR_LOOKUP_GROUP if table == "multiple" else f"{names.COMPOSITOR_LOOKUP_GROUP[:-1]}, {table})"


def look_up(g, table, point_frame_, direction, sun, forced=None):
    """(radiance per unit sun, above-horizon flag) of ``table`` at a point looking along
    ``direction``; ``forced`` takes the flag of an earlier look-up."""
    height, up = point_frame_
    node = g.node("CompositorNodeGroup")
    node.node_tree = bpy.data.node_groups[lookup_group_name(table)]
    for name, value in (("Height", height), ("Cos View Zenith", g.vmath("DOT_PRODUCT", direction, up)),
                        ("Cos Sun Zenith", g.vmath("DOT_PRODUCT", up, sun)),
                        ("Cos Sun View", g.vmath("DOT_PRODUCT", direction, sun))):
        g.feed(node.inputs[name], value)
    if forced is not None:
        g.feed(node.inputs["Force Horizon"], 1.0)
        g.feed(node.inputs["Above Horizon"], forced)
    return node.outputs["Radiance"], node.outputs["Above Horizon"]


def section_group_name(table: str) -> str:
    return names.SECTION_GROUP.format(table=table)


def build_section_group(table, params):
    """"OLS Section Scattering (<table>)": Yusov 2013 eq. (8) over a ray section as a shared
    group."""
    tree = new_group(section_group_name(table), "CompositorNodeTree")
    inputs = ([(name, "NodeSocketVector", (0.0, 0.0, 0.0)) for name in ("Start", "End", "Direction", "Sun Direction")]
              + [(name, "NodeSocketVector", (1.0, 1.0, 1.0)) for name in ("Start Transmittance", "End Transmittance")])
    g, gin, gout = group_io(tree, inputs, [("Radiance", "NodeSocketVector", None)])
    o = gin.outputs
    g.links.new(section_inscattering(g, table, o["Start"], o["End"], o["Direction"], o["Sun Direction"],
                                     o["Start Transmittance"], o["End Transmittance"], params), gout.inputs["Radiance"])
    return tree


def section_node(g, table, start, end, direction, sun, start_transmittance, end_transmittance):
    """Yusov 2013 eq. (8) start -> end through an "OLS Section Scattering (<table>)" node."""
    return g.group(bpy.data.node_groups[section_group_name(table)], start=start, end=end, direction=direction,
                   sun_direction=sun, start_transmittance=start_transmittance,
                   end_transmittance=end_transmittance)["Radiance"]


def section_inscattering(g, table, start, end, direction, sun, start_transmittance, end_transmittance, params):
    """max(T_start L(start) - T_end L(end), 0) for world points ``start`` and ``end``; within
    HORIZON_BLEND of the start's horizon (narrowed for long sections), the blend of
    Yusov 2013 eq. (8) along the rays just below and just above the horizon (Bruneton's fix for the
    step the seam draws; not in fog: uses_horizon_blend; twin:
    lut_gen.passes.aerial.section_inscattering)."""
    start_frame = point_frame(g, start, params)
    height, up = start_frame

    def eq8(view, end_point, forced=None):
        near, above = look_up(g, table, start_frame, view, sun, forced)
        far, _ = look_up(g, table, point_frame(g, end_point, params), view, sun, above if forced is None else forced)
        if start_transmittance is not None:
            near = g.vmath("MULTIPLY", start_transmittance, near)
        return g.vmath("MAXIMUM", g.vmath("SUBTRACT", near, g.vmath("MULTIPLY", end_transmittance, far)), (0.0, 0.0, 0.0))

    plain = eq8(direction, end)
    if not uses_horizon_blend(params):
        return plain
    c_h = horizon_cos(g, height, params)
    offset = g.sub(g.vmath("DOT_PRODUCT", direction, up), c_h)
    length = g.vmath("LENGTH", g.vmath("SUBTRACT", end, start))
    half_width = g.math("MINIMUM", g.div(HORIZON_BLEND_HEIGHT, g.math("MAXIMUM", length, 1e-9)), HORIZON_BLEND)
    sides = []
    for side in (-1.0, 1.0):
        tilted = tilted_direction(g, up, direction, g.mul_add(half_width, side, c_h))
        tilted_end = g.vmath("MULTIPLY_ADD", tilted, g.combine(length, length, length), start)
        sides.append(eq8(tilted, tilted_end, forced=1.0 if side > 0 else 0.0))
    weight = g.clamp(g.div(g.add(offset, half_width), g.mul(half_width, 2.0)), 0.0, 1.0)
    in_band = g.math("LESS_THAN", g.math("ABSOLUTE", offset), half_width)
    return g.vlerp(plain, g.vlerp(sides[0], sides[1], weight), in_band)


def tilted_direction(g, up, direction, cos_zenith):
    """``direction`` turned in its vertical plane to the zenith cosine ``cos_zenith``."""
    level = g.vmath("NORMALIZE", g.vmath("SUBTRACT", direction, g.vscale(up, g.vmath("DOT_PRODUCT", up, direction))))
    sine = g.math("SQRT", g.math("MAXIMUM", g.sub(1.0, g.mul(cos_zenith, cos_zenith)), 0.0))
    return g.vmath("ADD", g.vscale(up, cos_zenith), g.vscale(level, sine))
