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
