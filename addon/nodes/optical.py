"""Look-ups into the optical-depth and ambient-skylight images shared by the sky and terrain
groups (the sample's texture coordinates: (h / H_atm, c * 0.5 + 0.5) and (c * 0.5 + 0.5, 0.5))."""
from __future__ import annotations


def transmittance_to_top(g, image, height, cos_zenith, params):
    """exp(-(beta_R D_R + beta_M^ext D_M + beta_O D_O)) per channel; 0 where the ray hits the
    Earth (the table holds 1e20 there). Below the table's first row the Rayleigh and Mie columns
    are scaled by exp(dh / H) as in the twin, lut_gen.Luts.transmittance_to_top."""
    uv = g.combine(g.div(height, params.atmosphere_height), g.mul_add(cos_zenith, 0.5, 0.5), 0.0)
    rayleigh, mie, ozone = g.separate(g.image(image, uv))
    first_row = params.atmosphere_height / (2 * image.size[0])
    below = g.math("MAXIMUM", g.sub(first_row, height), 0.0)
    rayleigh = g.mul(rayleigh, g.math("EXPONENT", g.div(below, params.rayleigh_scale_height)))
    mie = g.mul(mie, g.math("EXPONENT", g.div(below, params.mie_scale_height)))
    optical_depth = g.vmath("ADD", g.vscale(tuple(params.rayleigh), rayleigh),
                            g.vmath("ADD", g.vscale(tuple(params.mie_extinction), mie),
                                    g.vscale(tuple(params.ozone_extinction), ozone)))
    channels = [g.math("EXPONENT", g.mul(c, -1.0)) for c in g.separate(optical_depth)]
    return g.combine(*channels)


def ambient_skylight(g, image, cos_sun_zenith):
    """E_sky per unit sun for the sun's zenith cosine. Twin: lut_gen.Luts.ambient_skylight."""
    return g.image(image, g.combine(g.mul_add(cos_sun_zenith, 0.5, 0.5), 0.5, 0.0))
