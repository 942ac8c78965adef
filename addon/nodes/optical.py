"""Look-ups into the optical-depth and ambient-skylight images shared by the sky and terrain
groups (the sample's texture coordinates: (h / H_atm, c * 0.5 + 0.5) and (c * 0.5 + 0.5, 0.5)). Texture
coordinates carry z = 1: the compositor's Map UV reads z as alpha."""
from __future__ import annotations


def point_frame(g, point, params):
    """(height above the ground, local up) of a world point; the Earth centre is at (0, 0, -R).
    Height as (|P|^2 + 2 z R) / (|P + R z^| + R): the plain |P + R z^| - R loses metres to
    float32 cancellation at R = 6.36e6 m."""
    from_centre = g.vmath("ADD", point, (0.0, 0.0, params.earth_radius))
    z = g.separate(point)[2]
    numerator = g.mul_add(z, 2.0 * params.earth_radius, g.vmath("DOT_PRODUCT", point, point))
    height = g.div(numerator, g.add(g.vmath("LENGTH", from_centre), params.earth_radius))
    return g.math("MAXIMUM", height, 0.0), g.vmath("NORMALIZE", from_centre)


def net_density_to_top(g, image, height, cos_zenith, params):
    """(Rayleigh, Mie, ozone) net densities to the top (1e20 where the ray hits the Earth);
    below the table's first row the Rayleigh and Mie columns are scaled by exp(dh / H), as in
    the twin, lut_gen.Luts.net_density_to_top."""
    uv = g.combine(g.div(height, params.atmosphere_height), g.mul_add(cos_zenith, 0.5, 0.5), 1.0)
    rayleigh, mie, ozone = g.separate(g.image(image, uv))
    first_row = params.atmosphere_height / (2 * image.size[0])
    below = g.math("MAXIMUM", g.sub(first_row, height), 0.0)
    rayleigh = g.mul(rayleigh, g.math("EXPONENT", g.div(below, params.rayleigh_scale_height)))
    mie = g.mul(mie, g.math("EXPONENT", g.div(below, params.mie_scale_height)))
    return rayleigh, mie, ozone


def transmittance_from_net_density(g, rayleigh, mie, ozone, params):
    """exp(-(beta_R D_R + beta_M^ext D_M + beta_O D_O)) per channel."""
    optical_depth = g.vmath("ADD", g.vscale(tuple(params.rayleigh), rayleigh),
                            g.vmath("ADD", g.vscale(tuple(params.mie_extinction), mie),
                                    g.vscale(tuple(params.ozone_extinction), ozone)))
    channels = [g.math("EXPONENT", g.mul(g.math("MINIMUM", c, 80.0), -1.0)) for c in g.separate(optical_depth)]
    return g.combine(*channels)


def transmittance_to_top(g, image, height, cos_zenith, params):
    """Transmittance from a point to the top; 0 where the ray hits the Earth (the table holds
    1e20 there). Twin: lut_gen.Luts.transmittance_to_top."""
    return transmittance_from_net_density(g, *net_density_to_top(g, image, height, cos_zenith, params), params)


def ambient_skylight(g, image, cos_sun_zenith):
    """E_sky per unit sun for the sun's zenith cosine. Twin: lut_gen.Luts.ambient_skylight."""
    return g.image(image, g.combine(g.mul_add(cos_sun_zenith, 0.5, 0.5), 0.5, 1.0))


def below_horizon(g, height, cos_view, params):
    """1 where a ray from ``height`` with zenith cosine ``cos_view`` runs into the Earth."""
    c_h = g.mul(-1.0, g.div(g.math("SQRT", g.mul(height, g.add(height, 2 * params.earth_radius))),
                            g.add(height, params.earth_radius)))
    return g.math("LESS_THAN", cos_view, c_h)


def segment_transmittance(g, image, start_frame, end_frame, direction, params):
    """Transmittance between two points given as (height, up) frames, ``direction`` the unit
    vector from start to end: net density to the top from the start minus from the end, along
    the reversed ray where the forward one from either end runs into the ground (the table
    holds 1e20 there). Twin: lut_gen.aerial.segment_transmittance."""
    (h_s, up_s), (h_e, up_e) = start_frame, end_frame
    reverse = g.vscale(direction, -1.0)
    cos_s, cos_e = g.vmath("DOT_PRODUCT", direction, up_s), g.vmath("DOT_PRODUCT", direction, up_e)
    forward_s = net_density_to_top(g, image, h_s, cos_s, params)
    forward_e = net_density_to_top(g, image, h_e, cos_e, params)
    backward_e = net_density_to_top(g, image, h_e, g.vmath("DOT_PRODUCT", reverse, up_e), params)
    backward_s = net_density_to_top(g, image, h_s, g.vmath("DOT_PRODUCT", reverse, up_s), params)
    hits = g.math("MAXIMUM", below_horizon(g, h_s, cos_s, params), below_horizon(g, h_e, cos_e, params))
    net = [g.math("MAXIMUM", g.lerp(g.sub(fs, fe), g.sub(be, bs), hits), 0.0)
           for fs, fe, be, bs in zip(forward_s, forward_e, backward_e, backward_s)]
    return transmittance_from_net_density(g, *net, params)
