"""The epipolar technique's part of "OLS Light Shafts": instead of marching each pixel's ray
through the shadow maps, read the lit length, the first lit distance and (INTEGRATION) the
shadowed single scattering at the pixel's own depth from the tables lut_gen.epipolar builds
before each frame. Twin: lut_gen.epipolar.look_up.

Table image "OLS Epipolar Lit" (RGBA: lit length, first lit): row i * K + k holds slice node
i at distance node k, column j sample node j; "OLS Epipolar Integral" (RGB) the same for the
INTEGRATION mode. Bilinear filtering interpolates samples and distances, the slices are blended
by hand (two fetches).
"""
from __future__ import annotations

import math

import numpy as np

from ...lut_gen import epipolar

LIT_IMAGE = "OLS Epipolar Lit"
INTEGRAL_IMAGE = "OLS Epipolar Integral"
SAMPLING_IMAGE = "OLS Epipolar Sampling"    # Show Sampling's dots at the render's size (1 x 1 when off)
INPUTS = [
    ("Epipolar Axis 1", "NodeSocketVector", (1.0, 0.0, 0.0)),
    ("Epipolar Axis 2", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Epipolar Phi", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Epipolar Theta", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Epipolar Depth", "NodeSocketVector", (1.0, 1.0, 0.0)),
    ("Show Sampling", "NodeSocketFloat", 0.0),
]


def show_sampling(g, gin, result, pixel_uv, sampling_image):
    """Red dots where Show Sampling's overlay is set (twin: scattering_pass.sampling_red)."""
    dots = g.separate(g.image(sampling_image, pixel_uv, interpolation="Closest"))[0]
    r, gr, b = g.separate(result)
    red = g.mul_add(g.math("MAXIMUM", r, g.math("MAXIMUM", gr, b)), 4.0, 1e-3)
    return g.vlerp(result, g.combine(red, 0.0, 0.0), g.mul(dots, gin.outputs["Show Sampling"]))


def pack(tables: epipolar.EpipolarTables):
    """(lit RGBA pixels ((S+1) K, N, 4), integral RGBA pixels or None), rows bottom to top."""
    n_slices, n_samples, K = tables.lit_length.shape
    lit = np.zeros((n_slices, K, n_samples, 4), dtype=np.float32)
    lit[..., 0] = tables.lit_length.transpose(0, 2, 1)
    lit[..., 1] = tables.first_lit.transpose(0, 2, 1)
    lit[..., 3] = 1.0
    integral = None
    if tables.integrated is not None:
        integral = np.ones((n_slices, K, n_samples, 4), dtype=np.float32)
        integral[..., :3] = tables.integrated.transpose(0, 2, 1, 3)
        integral = integral.reshape(n_slices * K, n_samples, 4)
    return lit.reshape(n_slices * K, n_samples, 4), integral


def image_size(slices: int, samples: int, steps: int):
    """(width, height) of the table images."""
    return samples, (slices + 1) * steps


def look_up(g, gin, direction, length, sun, layout, lit_image, integral_image):
    """(lit length, first lit, integrated or None) sockets for the pixel ray ``direction`` at
    distance ``length``."""
    S, N, K = layout.slices, layout.samples, layout.steps
    phi0, phi_span, full = g.separate(gin.outputs["Epipolar Phi"])
    theta0, theta_span, _ = g.separate(gin.outputs["Epipolar Theta"])
    t_max, growth, _ = g.separate(gin.outputs["Epipolar Depth"])
    phi = g.math("ARCTAN2", g.vmath("DOT_PRODUCT", direction, gin.outputs["Epipolar Axis 2"]),
                 g.vmath("DOT_PRODUCT", direction, gin.outputs["Epipolar Axis 1"]))
    turn = g.sub(phi, phi0)
    turn = g.lerp(turn, g.math("FLOORED_MODULO", turn, 2.0 * math.pi), full)
    x = g.mul(g.math("DIVIDE", turn, phi_span, clamp=False), float(S))
    x = g.clamp(x, 0.0, float(S))
    theta = g.math("ARCCOSINE", g.clamp(g.vmath("DOT_PRODUCT", direction, sun), -1.0, 1.0))
    y = g.mul(g.clamp(g.div(g.sub(theta, theta0), theta_span), 0.0, 1.0), float(N - 1))
    t = g.clamp(g.div(length, t_max), 0.0, 1.0)
    z = g.mul(g.div(g.math("LOGARITHM", g.mul_add(growth, t, 1.0), math.e),
                    g.math("LOGARITHM", g.add(growth, 1.0), math.e)), float(K - 1))
    i0 = g.math("MINIMUM", g.math("FLOOR", x), float(S - 1))
    w = g.sub(x, i0)
    width, height = image_size(S, N, K)
    u = g.div(g.add(y, 0.5), float(width))

    def fetch(image):
        rows = []
        for di in (0.0, 1.0):
            v = g.div(g.add(g.mul_add(g.add(i0, di), float(K), z), 0.5), float(height))
            rows.append(g.image(image, g.combine(u, v, 1.0), interpolation="Linear"))
        return g.vlerp(rows[0], rows[1], w)

    lit_length, first_lit, _ = g.separate(fetch(lit_image))
    # Beyond the grid (past the farthest shadow caster) the air is lit, as outside every cascade.
    beyond = g.math("MAXIMUM", g.sub(length, t_max), 0.0)
    lit_length = g.add(g.math("MINIMUM", lit_length, length), beyond)
    first_lit = g.math("MINIMUM", first_lit, length)
    integrated = fetch(integral_image) if integral_image is not None else None
    return lit_length, first_lit, integrated
