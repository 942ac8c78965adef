""""OLS Tone Mapping": the sample's seven tone-mapping operators as a compositor group.

Twin: lut_gen/passes/tone_mapping.py (same names, same constants). The operator is an input (its
index in OPERATORS) so a driver from scene.ols switches it; all seven are evaluated and the
chosen one is kept. Auto exposure takes the log-average luminance of the frame from the Levels
node's mean over log luminance; otherwise "Average Luminance" is used (the sample's 0.1).

"Linear Output" 1 passes the image through unchanged: renders saved as OpenEXR hold scene-linear
radiance (addon/scene/setup/compositor.py sets it from the output format).

Light adaptation: the operators use Previous + (measured - Previous) * Adaptation Weight (weight 1,
the default, is no adaptation). A compositor has no memory across frames, so Python carries it
(addon/scene/frame/adaptation.py): the output "Adapted Luminance" is a 1 x 1 image of the luminance this
frame used, which a File Output node writes for the render handlers to read back.
"""
from __future__ import annotations

import math

from ...lut_gen.passes import tone_mapping as twin
from .builder import group_io, new_group
from ..scene import names

INPUTS = [
    ("Image", "NodeSocketColor", (0.0, 0.0, 0.0, 1.0)),
    ("Operator", "NodeSocketFloat", float(twin.OPERATORS.index("UNCHARTED2"))),
    ("Middle Gray", "NodeSocketFloat", 0.18),
    ("White Point", "NodeSocketFloat", 3.0),
    ("Luminance Saturation", "NodeSocketFloat", 1.0),
    ("Auto Exposure", "NodeSocketFloat", 1.0),
    ("Average Luminance", "NodeSocketFloat", twin.FIXED_AVERAGE_LUMINANCE),
    ("Previous Luminance", "NodeSocketFloat", twin.FIXED_AVERAGE_LUMINANCE),
    ("Adaptation Weight", "NodeSocketFloat", 1.0),
    ("Linear Output", "NodeSocketFloat", 0.0),     # 1: pass the image through (scene-linear EXR)
]
OUTPUTS = [("Image", "NodeSocketColor", None), ("Adapted Luminance", "NodeSocketColor", None)]


def _uncharted2(g, x):
    a, b, c, d, e, f = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30
    numerator = g.add(g.mul(x, g.mul_add(x, a, c * b)), d * e)
    denominator = g.add(g.mul(x, g.mul_add(x, a, b)), d * f)
    return g.sub(g.div(numerator, denominator), e / f)


def _one_pixel_image(g, image, value):
    """A 1 x 1 image holding ``value``: a File Output node skips single values, and one pixel
    keeps the file tiny. The crop of the frame only supplies the image's size; min(max(x, 0), 0)
    zeroes its pixel even when it is inf or NaN."""
    crop = g.node("CompositorNodeCrop")
    g.links.new(image, crop.inputs["Image"])
    for name, size in (("X", 0), ("Y", 0), ("Width", 1), ("Height", 1)):
        crop.inputs[name].default_value = size
    red = g.node("CompositorNodeSeparateColor")
    g.links.new(crop.outputs["Image"], red.inputs["Image"])
    zero = g.math("MINIMUM", g.math("MAXIMUM", red.outputs["Red"], 0.0), 0.0)
    return g.add(zero, value)


def build_tone_mapping_group():
    tree = new_group(names.TONE_MAPPING_GROUP, "CompositorNodeTree")
    g, gin, gout = group_io(tree, INPUTS, OUTPUTS)
    split = g.node("CompositorNodeSeparateColor")
    g.links.new(gin.outputs["Image"], split.inputs["Image"])
    colour = [g.math("MAXIMUM", split.outputs[name], 0.0) for name in ("Red", "Green", "Blue")]
    weights = twin.RGB_TO_LUMINANCE
    lum = g.math("MAXIMUM", g.mul_add(colour[2], weights[2], g.mul_add(colour[1], weights[1], g.mul(colour[0], weights[0]))),
                 twin.MIN_LUMINANCE)

    # Average luminance: exp(mean(log L)) from the Levels node, or the given value.
    log_lum = g.math("LOGARITHM", lum, math.e)
    log_image = g.node("CompositorNodeCombineColor")
    for name in ("Red", "Green", "Blue"):
        g.feed(log_image.inputs[name], log_lum)
    levels = g.node("CompositorNodeLevels")
    g.links.new(log_image.outputs["Image"], levels.inputs["Image"])
    frame_average = g.math("EXPONENT", levels.outputs["Mean"])
    measured = g.lerp(gin.outputs["Average Luminance"], frame_average, gin.outputs["Auto Exposure"])
    average = g.lerp(gin.outputs["Previous Luminance"], measured, gin.outputs["Adaptation Weight"])
    g.links.new(_one_pixel_image(g, gin.outputs["Image"], average), gout.inputs["Adapted Luminance"])

    scale = g.div(gin.outputs["Middle Gray"], average)
    scaled_lum = g.mul(lum, scale)
    white = gin.outputs["White Point"]
    saturation = gin.outputs["Luminance Saturation"]
    chroma = [g.math("POWER", g.div(c, lum), saturation) for c in colour]

    # Luminance operators (mapped luminance times chroma).
    mapped = {
        "EXP": g.sub(1.0, g.math("EXPONENT", g.mul(scaled_lum, -1.0))),
        "REINHARD": g.div(scaled_lum, g.add(scaled_lum, 1.0)),
        "REINHARD_MOD": g.div(g.mul(scaled_lum, g.add(g.div(scaled_lum, g.mul(white, white)), 1.0)),
                              g.add(scaled_lum, 1.0)),
        "LOGARITHMIC": g.div(g.math("LOGARITHM", g.add(scaled_lum, 1.0), 10.0),
                             g.math("LOGARITHM", g.add(white, 1.0), 10.0)),
    }
    exponent = math.log(twin.ADAPTIVE_LOG_BIAS) / math.log(0.5)
    mapped["ADAPTIVE_LOG"] = g.div(
        g.div(g.math("LOGARITHM", g.add(scaled_lum, 1.0), math.e), g.math("LOGARITHM", g.add(white, 1.0), 10.0)),
        g.math("LOGARITHM", g.mul_add(g.math("POWER", g.div(scaled_lum, white), exponent), 8.0, 2.0), math.e))

    operator = gin.outputs["Operator"]
    channels = []
    for c, ch in zip(colour, chroma):
        scaled = g.mul(c, scale)
        results = {name: g.mul(value, ch) for name, value in mapped.items()}
        results["UNCHARTED2"] = g.div(_uncharted2(g, g.mul(scaled, twin.UNCHARTED2_EXPOSURE_BIAS)), _uncharted2(g, white))
        x = g.math("MAXIMUM", g.sub(scaled, 0.004), 0.0)
        filmic = g.div(g.mul(x, g.mul_add(x, 6.2, 0.5)), g.add(g.mul(x, g.mul_add(x, 6.2, 1.7)), 0.06))
        results["FILMIC_ALU"] = g.math("POWER", filmic, 2.2)
        results["BLENDER_VIEW"] = g.mul(c, g.lerp(1.0, scale, gin.outputs["Auto Exposure"]))
        chosen = None
        for index, name in enumerate(twin.OPERATORS):
            term = g.mul(results[name], g.math("COMPARE", operator, float(index), 0.5))
            chosen = term if chosen is None else g.add(chosen, term)
        channels.append(chosen)
    linear = gin.outputs["Linear Output"]
    channels = [g.lerp(chosen, split.outputs[name], linear) for chosen, name in zip(channels, ("Red", "Green", "Blue"))]
    merge = g.node("CompositorNodeCombineColor")
    for name, value in zip(("Red", "Green", "Blue"), channels):
        g.feed(merge.inputs[name], value)
    g.feed(merge.inputs["Alpha"], split.outputs["Alpha"])
    g.links.new(merge.outputs["Image"], gout.inputs["Image"])
    return tree
