"""Eq. (8) of seed 000 in a compositor tree: light scattered toward the camera from a ray
section start -> end, T(C->start) L(start) - T(C->end) L(end), both look-ups on the side of the
horizon seam the first one chose (Listing 2). Twin: lut_gen.aerial._eq8."""
from __future__ import annotations

from .lookup import COMPOSITOR_GROUP_NAME
from .optical import point_frame


def lookup_group_name(table: str) -> str:
    """Compositor look-up group of a scattering table ("multiple" keeps the original name)."""
    return COMPOSITOR_GROUP_NAME if table == "multiple" else f"{COMPOSITOR_GROUP_NAME[:-1]}, {table})"


def look_up(g, table, point_frame_, direction, sun, forced=None):
    """(radiance per unit sun, above-horizon flag) of ``table`` at a point looking along
    ``direction``; ``forced`` takes the flag of an earlier look-up."""
    import bpy
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


def section_inscattering(g, table, start, end, direction, sun, start_transmittance, end_transmittance, params):
    """max(T_start L(start) - T_end L(end), 0) for world points ``start`` and ``end``."""
    near, above = look_up(g, table, point_frame(g, start, params), direction, sun)
    far, _ = look_up(g, table, point_frame(g, end, params), direction, sun, forced=above)
    if start_transmittance is not None:
        near = g.vmath("MULTIPLY", start_transmittance, near)
    difference = g.vmath("SUBTRACT", near, g.vmath("MULTIPLY", end_transmittance, far))
    return g.vmath("MAXIMUM", difference, (0.0, 0.0, 0.0))
