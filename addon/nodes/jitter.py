"""The per-pixel offset of the brute-force march's steps in compositor nodes: interleaved
gradient noise of the pixel's coordinates, blended toward the step centre by the "Jitter
Steps" input (0 or 1). Twin: lut_gen.passes.jitter."""
from __future__ import annotations

from ...lut_gen.passes import jitter


def step_offset(g, pixel, enabled):
    """Offset in [0, 1) of the pixel's steps: ``pixel`` the Image Coordinates node's "Pixel"
    output, ``enabled`` a 0/1 float socket."""
    x, y, _ = g.separate(pixel)
    inner = g.math("FRACT", g.mul_add(x, jitter.MAGIC_X, g.mul(y, jitter.MAGIC_Y)))
    noise = g.math("FRACT", g.mul(inner, jitter.MAGIC_Z))
    return g.mul_add(g.sub(noise, jitter.CENTRE), enabled, jitter.CENTRE)


def _translated(g, image, dx: int, dy: int):
    """``image`` moved by whole pixels, zeros where nothing moved in (twin: jitter.shifted)."""
    if (dx, dy) == (0, 0):
        return image
    node = g.node("CompositorNodeTranslate")
    g.feed(node.inputs["Image"], image)
    g.feed(node.inputs["X"], float(dx))
    g.feed(node.inputs["Y"], float(dy))
    g.feed(node.inputs["Interpolation"], "Nearest")
    return node.outputs["Image"]


def neighbourhood_mean(g, values, length, enabled):
    """``values`` (a vector socket) averaged over the pixel's 3 x 3 block among the neighbours
    whose ray ``length`` is within the tolerance, when ``enabled`` is 1; ``values`` as they are
    when 0. Twin: lut_gen.passes.jitter.neighbourhood_mean (the sum is symmetric, so which way
    Translate counts a pixel does not matter).

    A translated image keeps its own, moved domain, and a node takes the domain of its first
    input: each neighbour's share is added to a sum that starts from the pixel itself, so the
    sum stays on the render's domain and the share is cut to it with zeros (Clip)."""
    packed = g.combine(length, 1.0, 0.0)                # (length, inside the image)
    tolerance = g.mul(length, jitter.LENGTH_TOLERANCE)
    weight = g.math("LESS_THAN", 0.0, tolerance)        # the pixel itself
    total = g.vmath("MULTIPLY", values, g.combine(weight, weight, weight))
    for dy, dx in jitter.neighbour_offsets():
        if (dy, dx) == (0, 0):
            continue
        near_length, inside, _ = g.separate(_translated(g, packed, dx, dy))
        near = g.mul(inside, g.math("LESS_THAN", g.math("ABSOLUTE", g.sub(near_length, length)), tolerance))
        total = g.vmath("ADD", total, g.vmath("MULTIPLY", _translated(g, values, dx, dy), g.combine(near, near, near)))
        weight = g.add(weight, near)
    mean = g.vscale(total, g.div(1.0, g.math("MAXIMUM", weight, 1.0)))
    return g.vlerp(values, mean, enabled)
