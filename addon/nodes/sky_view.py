"""The camera's twilight correction in the "OLS Sky" group: lut_gen.passes.sky_view's image
read for the view and added, phases applied, to the 4D look-up. Twin:
lut_gen.passes.sky_view.correction_at (the sky group's test renders it at a low sun).

The image holds three tiles side by side (Rayleigh, Mie, fog; lut_gen.passes.sky_view.image_pixels),
azimuth from the sun along x, view zenith along y on Yusov 2013 eq. (5)'s horizon split for the
camera's height. Cycles filters both axes with the texture unit (each tile is continuous in both);
GPU engines fetch texel centres and blend them here, as the 4D look-up's "MANUAL" filtering does
(nodes/lookup.py: Yusov 2013 eq. (5) is steep at the horizon, and a mipmapped fetch there blurs it).
"""
from __future__ import annotations

import math

from ...lut_gen.passes import sky_view as twin
from .lookup import FILTERING, lower_node, mie_phase, rayleigh_phase, view_zenith_coordinate


def correction(g, image, height, cos_view, cos_sun, cos_sun_view, params, filtering="HARDWARE"):
    """(vector socket) radiance per unit sun the 4D look-up misses for this view; ``filtering``
    as the look-up group's (lookup.FILTERING)."""
    if filtering not in FILTERING:
        raise ValueError(f"filtering must be one of {FILTERING}, got {filtering!r}")
    n_t = image.size[0] // len(twin.MEDIA)
    n_a = image.size[1]
    x_a, _ = view_zenith_coordinate(g, cos_view, height, n_a, params.earth_radius)
    sin_view = g.math("SQRT", g.math("MAXIMUM", g.sub(1.0, g.mul(cos_view, cos_view)), 0.0))
    sin_sun = g.math("SQRT", g.math("MAXIMUM", g.sub(1.0, g.mul(cos_sun, cos_sun)), 0.0))
    cos_azimuth = g.div(g.sub(cos_sun_view, g.mul(cos_view, cos_sun)),
                        g.math("MAXIMUM", g.mul(sin_view, sin_sun), 1e-9))
    x_t = g.mul(g.math("ARCCOSINE", g.clamp(cos_azimuth, -1.0, 1.0)), (n_t - 1) / math.pi)
    width = n_t * len(twin.MEDIA)
    if filtering == "MANUAL":
        a0, w_a = lower_node(g, x_a, n_a)
        t0, w_t = lower_node(g, x_t, n_t)
        v_of = [g.div(g.add(a0, 0.5 + j), n_a) for j in (0, 1)]

        def tile(k):
            u_of = [g.div(g.add(t0, k * n_t + 0.5 + m), width) for m in (0, 1)]
            rows = [g.vlerp(*(g.image(image, g.combine(u, v, 0.0), interpolation="Closest") for u in u_of), w_t)
                    for v in v_of]
            return g.vlerp(rows[0], rows[1], w_a)
    else:
        v = g.div(g.add(x_a, 0.5), n_a)

        def tile(k):
            return g.image(image, g.combine(g.div(g.add(x_t, k * n_t + 0.5), width), v, 0.0), interpolation="Linear")
    tiles = [tile(k) for k in range(len(twin.MEDIA) if params.has_fog else 2)]
    total = g.vmath("ADD", g.vscale(tiles[0], rayleigh_phase(g, cos_sun_view)),
                    g.vscale(tiles[1], mie_phase(g, cos_sun_view, params.mie_g)))
    if params.has_fog:
        total = g.vmath("ADD", total, g.vscale(tiles[2], mie_phase(g, cos_sun_view, params.fog_g)))
    return total
