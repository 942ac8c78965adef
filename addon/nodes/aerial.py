""""OLS Aerial Perspective": the compositor group that puts the atmosphere between the camera
and every surface: L_surface T(C->P) + (L(C) - T(C->P) L(P)) x sun strength x scattering scale
(eq. 8 of seed 000), the two look-ups on the same side of the horizon seam and the extinction
from the optical-depth table. Twin: lut_gen.aerial.aerial_perspective.

Inputs come from render passes (Image, Position) and drivers (camera position, sun). Pixels
without geometry (the sky: depth beyond SKY_DEPTH) pass through unchanged.
"""
from __future__ import annotations

from .builder import group_io, new_group
from .lookup import COMPOSITOR_GROUP_NAME
from .optical import net_density_to_top, point_frame, transmittance_from_net_density

GROUP_NAME = "OLS Aerial Perspective"
SKY_DEPTH = 1e9
INPUTS = [
    ("Image", "NodeSocketColor", (0.0, 0.0, 0.0, 1.0)),
    ("Position", "NodeSocketVector", (0.0, 0.0, 0.0)),
    ("Depth", "NodeSocketFloat", 1e10),
    ("Camera Position", "NodeSocketVector", (0.0, 0.0, 2.0)),
    ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)),
    ("Sun Strength", "NodeSocketFloat", 10.0),
    ("Scattering Scale", "NodeSocketFloat", 0.5),
    ("Enable", "NodeSocketFloat", 1.0),
    ("Lighting Only", "NodeSocketFloat", 0.0),
]


def build_aerial_group(optical_depth_image, params):
    import bpy
    tree = new_group(GROUP_NAME, "CompositorNodeTree")
    g, gin, gout = group_io(tree, INPUTS, [("Image", "NodeSocketColor", None)])
    camera, point = gin.outputs["Camera Position"], gin.outputs["Position"]
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    view = g.vmath("NORMALIZE", g.vmath("SUBTRACT", point, camera))
    h_c, up_c = point_frame(g, camera, params)
    h_p, up_p = point_frame(g, point, params)
    cos_view_c = g.vmath("DOT_PRODUCT", view, up_c)
    cos_view_p = g.vmath("DOT_PRODUCT", view, up_p)
    cos_sun_view = g.vmath("DOT_PRODUCT", view, sun)

    def look_up(height, up, cos_view, forced=None):
        node = g.node("CompositorNodeGroup")
        node.node_tree = bpy.data.node_groups[COMPOSITOR_GROUP_NAME]
        for name, value in (("Height", height), ("Cos View Zenith", cos_view),
                            ("Cos Sun Zenith", g.vmath("DOT_PRODUCT", up, sun)), ("Cos Sun View", cos_sun_view)):
            g.feed(node.inputs[name], value)
        if forced is not None:
            g.feed(node.inputs["Force Horizon"], 1.0)
            g.feed(node.inputs["Above Horizon"], forced)
        return node.outputs["Radiance"], node.outputs["Above Horizon"]

    near, above = look_up(h_c, up_c, cos_view_c)
    far, _ = look_up(h_p, up_p, cos_view_p, forced=above)

    # Extinction camera -> point: net density to the top from the camera minus from the point;
    # along the reversed ray when the forward one runs into the ground (lut_gen.aerial).
    reverse = g.vscale(view, -1.0)
    forward_c = net_density_to_top(g, optical_depth_image, h_c, cos_view_c, params)
    forward_p = net_density_to_top(g, optical_depth_image, h_p, cos_view_p, params)
    backward_p = net_density_to_top(g, optical_depth_image, h_p, g.vmath("DOT_PRODUCT", reverse, up_p), params)
    backward_c = net_density_to_top(g, optical_depth_image, h_c, g.vmath("DOT_PRODUCT", reverse, up_c), params)
    def below_horizon(height, cos_view):
        c_h = g.mul(-1.0, g.div(g.math("SQRT", g.mul(height, g.add(height, 2 * params.earth_radius))),
                                g.add(height, params.earth_radius)))
        return g.math("LESS_THAN", cos_view, c_h)
    hits = g.math("MAXIMUM", below_horizon(h_c, cos_view_c), below_horizon(h_p, cos_view_p))
    net = [g.math("MAXIMUM", g.lerp(g.sub(fc, fp), g.sub(bp, bc), hits), 0.0)
           for fc, fp, bp, bc in zip(forward_c, forward_p, backward_p, backward_c)]
    transmittance = transmittance_from_net_density(g, *net, params)

    inscatter = g.vmath("MAXIMUM", g.vmath("SUBTRACT", near, g.vmath("MULTIPLY", transmittance, far)), (0.0, 0.0, 0.0))
    air_light = g.vscale(inscatter, g.mul(gin.outputs["Sun Strength"], gin.outputs["Scattering Scale"]))
    surface = g.vscale(g.vmath("MULTIPLY", gin.outputs["Image"], transmittance), g.sub(1.0, gin.outputs["Lighting Only"]))
    seen = g.vmath("ADD", surface, air_light)
    geometry = g.mul(g.math("LESS_THAN", gin.outputs["Depth"], SKY_DEPTH), gin.outputs["Enable"])
    result = g.vlerp(gin.outputs["Image"], seen, geometry)
    merge = g.node("CompositorNodeCombineColor")
    split = g.node("CompositorNodeSeparateColor")
    g.links.new(gin.outputs["Image"], split.inputs["Image"])
    for name, value in zip(("Red", "Green", "Blue"), g.separate(result)):
        g.feed(merge.inputs[name], value)
    g.links.new(split.outputs["Alpha"], merge.inputs["Alpha"])
    g.links.new(merge.outputs["Image"], gout.inputs["Image"])
    return tree
