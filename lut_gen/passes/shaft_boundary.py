"""Where a view ray crosses a shadow's edge, found between two march samples.

A march with a shadow test at each step's centre knows a ray's lit length and first lit
distance only to a whole step: as the view rises over a wall against a low sun, the place where
its ray leaves the wall's shadow slides smoothly along it, but the march answered in whole
steps, and the darkened sky above the wall came out in bands a step tall (blocks of 5% of the
sky's light, where the physics has a smooth gradient).

Both techniques (the brute-force march, lut_gen.passes.aerial.light_shafts and its node
groups, and the epipolar tables, lut_gen.passes.epipolar) therefore take the ray's first change
of state (lit at or above half the sun, or below) between two neighbouring samples, and halve
that gap REFINE_ITERATIONS times with further shadow tests. The edge is where the lit fraction
crosses one half, interpolated linearly in the last gap: with bilinear PCF the lit fraction is
continuous across the edge, so the crossing moves continuously with the ray.

The march counted each sample's lit fraction over its own step, so the gap between samples
k - 1 and k held sample k - 1's fraction up to the step boundary b and sample k's after it.
With the edge at c instead, the lit length gains (lit[k - 1] - lit[k]) x (c - b) for every
distance past both, and a ray that starts in shadow is first lit at c.
"""
from __future__ import annotations

import numpy as np

REFINE_ITERATIONS = 4       # shadow tests per ray: the edge to 1/16 of a step before interpolating
HALF = 0.5                  # the lit fraction that separates the two states
# A sample lit less than this counts as unlit for the first lit distance: the compositor's
# float32 test, and the cloud's transmittance under a thick cloud (exp(-20) = 2e-9) is no light.
LIT_FLOOR = 1e-6


def first_transition(lit):
    """For march samples ``lit`` (..., n): (index k of the first sample whose state differs
    from sample 0's, n where none does; lit fraction of sample k - 1; lit fraction of sample k)."""
    lit = np.asarray(lit, dtype=np.float64)
    n = lit.shape[-1]
    state = lit >= HALF
    differs = state != state[..., :1]
    index = np.where(differs.any(axis=-1), np.argmax(differs, axis=-1), n)
    safe = np.clip(index, 1, max(n - 1, 1))[..., None]
    before = np.take_along_axis(lit, safe - 1, axis=-1)[..., 0]
    after = np.take_along_axis(lit, safe, axis=-1)[..., 0]
    return index, before, after


def refine(is_lit, origin, direction, near, far, lit_near, lit_far, iterations: int = REFINE_ITERATIONS):
    """(...) distance in [near, far] along ``origin + t direction`` where the lit fraction
    crosses HALF, given its values at both ends (on either side of HALF): bisection, then the
    linear crossing in the last bracket. ``is_lit(points (..., 3)) -> (...)``."""
    near, far = np.asarray(near, dtype=np.float64), np.asarray(far, dtype=np.float64)
    lit_near, lit_far = np.asarray(lit_near, dtype=np.float64), np.asarray(lit_far, dtype=np.float64)
    for _ in range(iterations):
        middle = 0.5 * (near + far)
        lit_middle = np.asarray(is_lit(origin + direction * middle[..., None]), dtype=np.float64)
        like_far = (lit_middle >= HALF) == (lit_far >= HALF)
        far, lit_far = np.where(like_far, middle, far), np.where(like_far, lit_middle, lit_far)
        near, lit_near = np.where(like_far, near, middle), np.where(like_far, lit_near, lit_middle)
    return near + (far - near) * crossing_weight(lit_near, lit_far)


def crossing_weight(lit_near, lit_far):
    """Where between two samples a straight line through their lit fractions meets HALF (0 at
    the near one, 1 at the far one)."""
    span = lit_far - lit_near
    safe = np.where(np.abs(span) > 1e-9, span, 1.0)
    return np.clip((HALF - lit_near) / safe, 0.0, 1.0)
