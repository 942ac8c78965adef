""""OLS Aerial Perspective": the compositor group that puts the atmosphere between the camera
and every surface: L_surface T(C->P) + (L(C) - T(C->P) L(P)) x sun strength x scattering scale
(eq. (8) of Yusov 2013), the two look-ups on the same side of the horizon seam and the extinction
from the optical-depth table. Twin: lut_gen.passes.aerial.aerial_perspective.

Inputs come from render passes (Image, Position, Depth) and "OLS Frame Values" (camera, sun). Pixels
without geometry (the sky: depth beyond "Sky Depth", see lut_gen.passes.scattering_pass.sky_depth)
pass through unchanged.
"""
from __future__ import annotations

from .builder import group_io, new_group
from .inscattering import section_node
from .optical import segment_transmittance_node
from ..scene import names

# The render passes both scattering groups read (light_shafts.py reuses them).
PASS_INPUTS = [
    ("Image", "NodeSocketColor", (0.0, 0.0, 0.0, 1.0)),
    ("Position", "NodeSocketVector", (0.0, 0.0, 0.0)),
    ("Depth", "NodeSocketFloat", 1e10),
    ("Sky Depth", "NodeSocketFloat", 1e9),
]
INPUTS = PASS_INPUTS + [
    ("Camera Position", "NodeSocketVector", (0.0, 0.0, 2.0)),
    ("Sun Direction", "NodeSocketVector", (0.0, 0.0, 1.0)),
    ("Sun Strength", "NodeSocketFloat", 10.0),
    ("Scattering Scale", "NodeSocketFloat", 0.5),
    ("Enable", "NodeSocketFloat", 1.0),
    ("Lighting Only", "NodeSocketFloat", 0.0),
]


def build_aerial_group(optical_depth_image, params):
    tree = new_group(names.AERIAL_GROUP, "CompositorNodeTree")
    g, gin, gout = group_io(tree, INPUTS, [("Image", "NodeSocketColor", None),
                                           ("Transmittance", "NodeSocketColor", None),
                                           ("Inscattering", "NodeSocketColor", None)])
    camera, point = gin.outputs["Camera Position"], gin.outputs["Position"]
    sun = g.vmath("NORMALIZE", gin.outputs["Sun Direction"])
    view = g.vmath("NORMALIZE", g.vmath("SUBTRACT", point, camera))
    transmittance = segment_transmittance_node(g, camera, point, view)
    inscatter = section_node(g, "multiple", camera, point, view, sun, None, transmittance)
    air_light = g.vscale(inscatter, g.mul(gin.outputs["Sun Strength"], gin.outputs["Scattering Scale"]))
    geometry = g.mul(g.math("LESS_THAN", gin.outputs["Depth"], gin.outputs["Sky Depth"]), gin.outputs["Enable"])
    # The layers of the multilayer EXR output, and the image made from them so that
    # Image = render x Transmittance + Inscattering holds to float precision. Sky pixels (and
    # Enable off) pass through: transmittance 1, nothing in-scattered.
    kept = g.vscale(transmittance, g.sub(1.0, gin.outputs["Lighting Only"]))
    layer_transmittance = g.vlerp((1.0, 1.0, 1.0), kept, geometry)
    layer_inscattering = g.vscale(air_light, geometry)
    result = g.vmath("ADD", g.vmath("MULTIPLY", gin.outputs["Image"], layer_transmittance), layer_inscattering)
    g.links.new(g.with_alpha_of(gin.outputs["Image"], result), gout.inputs["Image"])
    g.links.new(layer_transmittance, gout.inputs["Transmittance"])
    g.links.new(layer_inscattering, gout.inputs["Inscattering"])
    return tree
