"""The epipolar technique's part of "OLS Light Shafts": instead of marching each pixel's ray
through the shadow maps, read the lit length, the first lit distance and (INTEGRATION) the shadowed
single scattering at the pixel's own depth from the tables lut_gen.passes.epipolar builds before
each frame, then apply the scattering modes from the in-scattering tables of
lut_gen.passes.epipolar_air (no per-pixel Yusov 2013 eq. 8). Twin:
lut_gen.passes.epipolar_air.light_shaft_difference.

Table image "OLS Epipolar Lit" (RGBA: lit length, first lit): row i * K + k holds slice node
i at distance node k, column j sample node j; "OLS Epipolar Integral" (RGB) the same for the
INTEGRATION mode; "OLS Epipolar Air ..." (RGB) the in-scattering tables on their coarser grid,
whose reach is the z of the "Epipolar Depth" input. Bilinear filtering interpolates samples and
distances, the slices are blended by hand (two fetches).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...lut_gen.passes import epipolar, epipolar_air
from .lookup import mie_phase, rayleigh_phase
from ..scene import names

INPUTS = [
    ("Epipolar Axis 1", "NodeSocketVector", (1.0, 0.0, 0.0)),
    ("Epipolar Axis 2", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Epipolar Phi", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Epipolar Theta", "NodeSocketVector", (0.0, 1.0, 0.0)),
    ("Epipolar Depth", "NodeSocketVector", (1.0, 1.0, 1.0)),     # z: the in-scattering grid's reach
    # (slices, samples, distances) of the tables and of the in-scattering grid: values of the
    # frame, not of the graph, so changing them rebuilds no group (only the images' sizes change).
    ("Epipolar Grid", "NodeSocketVector", (1.0, 2.0, 2.0)),
    ("Epipolar Air Grid", "NodeSocketVector", (1.0, 2.0, 2.0)),
    ("Show Sampling", "NodeSocketFloat", 0.0),
    # The raw render and the aerial group's transmittance: the epipolar pass makes the whole
    # image (its "Image" input, the aerial group's, is read only when the node is muted).
    ("Surface", "NodeSocketColor", (0.0, 0.0, 0.0, 1.0)),
    ("Transmittance", "NodeSocketColor", (1.0, 1.0, 1.0, 1.0)),
]


def show_sampling(g, gin, result, pixel_uv, sampling_image):
    """Red dots where Show Sampling's overlay is set (twin: scattering_pass.sampling_red)."""
    dots = g.separate(g.image(sampling_image, pixel_uv, interpolation="Closest"))[0]
    r, gr, b = g.separate(result)
    red = g.mul_add(g.math("MAXIMUM", r, g.math("MAXIMUM", gr, b)), 4.0, 1e-3)
    return g.vlerp(result, g.combine(red, 0.0, 0.0), g.mul(dots, gin.outputs["Show Sampling"]))


def _rows(channels, out=None) -> np.ndarray:
    """Up to three (slices + 1, samples, steps) arrays, one per colour channel -> RGBA pixels
    ((slices + 1) steps, samples, 4): row i * steps + k holds slice node i at distance node k;
    the channels not given 0, alpha 1. Each channel goes straight into the pixels: stacking
    the channels first and zeroing the pixels copied the lit tables twice more (0.03 s).
    ``out``: an array of the pixels' shape to fill (the last frame's)."""
    n_slices, n_samples, steps = np.shape(channels[0])
    shape = (n_slices * steps, n_samples, 4)
    fits = out is not None and out.shape == shape and out.dtype == np.float32 and out.flags.c_contiguous
    pixels = (out if fits else np.empty(shape, dtype=np.float32)).reshape(n_slices, steps, n_samples, 4)
    for channel, table in enumerate(channels):
        pixels[..., channel] = np.swapaxes(table, 1, 2)
    pixels[..., len(channels):3] = 0.0
    pixels[..., 3] = 1.0
    return pixels.reshape(n_slices * steps, n_samples, 4)


def _channels(table) -> list:
    """The channels of a (..., channels) table as a list of views."""
    return [table[..., c] for c in range(table.shape[-1])]


def pack(tables: epipolar.EpipolarTables, out=(None, None)):
    """(lit RGBA pixels ((S+1) K, N, 4), integral RGBA pixels or None), rows bottom to top;
    ``out``: arrays to pack into where they fit (the last frame's pair)."""
    lit = _rows([tables.lit_length, tables.first_lit], out[0])
    return lit, None if tables.integrated is None else _rows(_channels(tables.integrated), out[1])


def pack_air(tables: epipolar_air.AirTables) -> dict:
    """{image name: RGBA pixels} of the in-scattering tables (the fog's 0 without fog: its image
    is read only by groups built for fog)."""
    arrays = {"single": tables.rayleigh, "single_mie": tables.mie, "higher": tables.higher,
              "single_fog": np.zeros_like(tables.mie) if tables.fog is None else tables.fog}
    return {names.EPIPOLAR_AIR_IMAGES[name]: _rows(_channels(table)) for name, table in arrays.items()}


def image_size(slices: int, samples: int, steps: int):
    """(width, height) of the table images."""
    return samples, (slices + 1) * steps


def _grid_coordinates(g, gin, direction, sun):
    """(slice fraction, sample fraction), each in [0, 1], of the pixel ray ``direction``."""
    phi0, phi_span, full = g.separate(gin.outputs["Epipolar Phi"])
    theta0, theta_span, _ = g.separate(gin.outputs["Epipolar Theta"])
    phi = g.math("ARCTAN2", g.vmath("DOT_PRODUCT", direction, gin.outputs["Epipolar Axis 2"]),
                 g.vmath("DOT_PRODUCT", direction, gin.outputs["Epipolar Axis 1"]))
    turn = g.sub(phi, phi0)
    turn = g.lerp(turn, g.math("FLOORED_MODULO", turn, 2.0 * math.pi), full)
    across = g.clamp(g.math("DIVIDE", turn, phi_span, clamp=False), 0.0, 1.0)
    theta = g.math("ARCCOSINE", g.clamp(g.vmath("DOT_PRODUCT", direction, sun), -1.0, 1.0))
    along = g.clamp(g.div(g.sub(theta, theta0), theta_span), 0.0, 1.0)
    return across, along


def _distance_node(g, distance, t_max, growth, steps):
    """Fractional node index of ``distance`` on the geometric grid t_max ((1 + a)^(k / (K - 1)) - 1) / a
    (``steps``: K, a socket)."""
    t = g.clamp(g.div(distance, t_max), 0.0, 1.0)
    return g.mul(g.div(g.math("LOGARITHM", g.mul_add(growth, t, 1.0), math.e),
                       g.math("LOGARITHM", g.add(growth, 1.0), math.e)), g.sub(steps, 1.0))


class _Grid:
    """A table grid at the pixel's grid fractions: the slice pair and the column are found once
    for every fetch of its images. ``dims``: the (slices, samples, steps) socket; the image is
    samples wide and (slices + 1) steps high (image_size)."""

    def __init__(self, g, dims, across, along):
        self.g = g
        S, N, self.K = g.separate(dims)
        x = g.mul(across, S)
        self.slice = g.math("MINIMUM", g.math("FLOOR", x), g.sub(S, 1.0))
        self.weight = g.sub(x, self.slice)
        self.height = g.mul(g.add(S, 1.0), self.K)
        self.u = g.div(g.mul_add(along, g.sub(N, 1.0), 0.5), N)
        self.first_row = g.mul(self.slice, self.K)

    def coordinates(self, z):
        """The texture coordinates of distance node ``z`` in the two slices around the pixel:
        the same for every image of this grid, so images read at one distance share them."""
        g = self.g
        row = g.add(self.first_row, g.add(z, 0.5))
        return [g.combine(self.u, g.div(g.add(row, offset), self.height), 1.0) for offset in (0.0, self.K)]

    def fetch(self, image, z, coordinates=None):
        """``image`` at distance node ``z`` (or at its ``coordinates``): bilinear in hardware
        along samples and distances, the two slices blended by hand."""
        rows = [self.g.image(image, uv, interpolation="Linear") for uv in coordinates or self.coordinates(z)]
        return self.g.vlerp(rows[0], rows[1], self.weight)


@dataclass
class LitTables:
    """The lit-length tables read at a pixel's own depth (sockets): its lit length and first
    lit distance, the integral table's value (None when not read), its grid fractions
    (slice, sample) and the tables' reach."""
    lit_length: object
    first_lit: object
    integral: object
    across: object
    along: object
    t_max: object


def read_lit_tables(g, gin, direction, length, sun, lit_image, integral_image=None) -> LitTables:
    """What the epipolar march found along the pixel ray ``direction`` out to its ``length``,
    from the tables lut_gen.passes.epipolar builds (twin: epipolar.look_up): whatever the air's
    model, the tables' in-scattering (in_scattering) or the analytic one's
    (nodes/analytic_shafts.py) applies the modes to it."""
    across, along = _grid_coordinates(g, gin, direction, sun)
    t_max, growth, _ = g.separate(gin.outputs["Epipolar Depth"])
    grid = _Grid(g, gin.outputs["Epipolar Grid"], across, along)
    z = _distance_node(g, length, t_max, growth, grid.K)
    at_z = grid.coordinates(z)                  # the lit and the integral tables share them
    lit_length, first_lit, _ = g.separate(grid.fetch(lit_image, z, at_z))
    # Beyond the grid (past the farthest shadow caster) the air is lit, as outside every cascade.
    beyond = g.math("MAXIMUM", g.sub(length, t_max), 0.0)
    lit_length = g.add(g.math("MINIMUM", lit_length, length), beyond)
    first_lit = g.math("MINIMUM", first_lit, length)
    integral = None if integral_image is None else grid.fetch(integral_image, z, at_z)
    return LitTables(lit_length, first_lit, integral, across, along, t_max)


def in_scattering(g, gin, direction, length, sun, geometry, layout, images, params):
    """The air's light per unit sun of the pixel ray ``direction`` of ``length``: the
    aerial perspective's in-scattering where ``geometry`` is 1, plus the shadowed minus the
    unshadowed in-scattering (the light shafts), all from the tables: the lit length and first
    lit distance at the pixel's own depth, then the modes from the in-scattering images.
    Twin: lut_gen.passes.epipolar_air.light_shaft_difference (unshadowed x geometry + difference).
    Returns that and the unshadowed in-scattering alone."""
    lit_image, integral_image, _, air_images = images
    lit = read_lit_tables(g, gin, direction, length, sun, lit_image,
                          integral_image if layout.single_mode == "INTEGRATION" else None)
    lit_length, first_lit, across, along = lit.lit_length, lit.first_lit, lit.across, lit.along
    reach = g.separate(gin.outputs["Epipolar Depth"])[2]
    distances = {"end": length, "first": first_lit, "lit_end": g.add(first_lit, lit_length)}

    air_grid = _Grid(g, gin.outputs["Epipolar Air Grid"], across, along)
    air_growth = g.div(reach, epipolar.MIN_NEAR)
    coordinates_at, fetched = {}, {}

    def fetch(table, name):
        if name not in coordinates_at:
            coordinates_at[name] = air_grid.coordinates(_distance_node(g, distances[name], reach, air_growth,
                                                                       air_grid.K))
        if (table, name) not in fetched:
            fetched[table, name] = air_grid.fetch(air_images[names.EPIPOLAR_AIR_IMAGES[table]], None, coordinates_at[name])
        return fetched[table, name]

    def weights(uses, end=geometry):
        """{distance: weight} of the difference's terms plus the unshadowed I(end) x ``end``."""
        merged = {"end": end}
        for name, sign in uses:
            merged[name] = g.add(merged[name], sign) if name in merged else sign
        return merged

    def combination(table, merged):
        total = None
        for name, weight in merged.items():
            value = fetch(table, name)
            if total is None:
                total = value if weight == 1.0 else g.vscale(value, weight)
            elif isinstance(weight, float) and abs(weight) == 1.0:
                total = g.vmath("ADD" if weight > 0 else "SUBTRACT", total, value)
            else:
                total = g.vmath("ADD", total, g.vscale(value, weight))
        return total

    cos_theta = g.vmath("DOT_PRODUCT", direction, sun)
    phases = rayleigh_phase(g, cos_theta), mie_phase(g, cos_theta, params.mie_g)

    def phased(single, higher):
        rayleigh = g.vmath("ADD", combination("single", single), combination("higher", higher))
        light = g.vmath("ADD", g.vscale(rayleigh, phases[0]), g.vscale(combination("single_mie", single), phases[1]))
        if params.has_fog:
            light = g.vmath("ADD", light, g.vscale(combination("single_fog", single), mie_phase(g, cos_theta, params.fog_g)))
        return light

    uses = epipolar_air.table_uses(layout.single_mode, layout.multiple_mode)
    light = phased(weights(uses["single"]), weights(uses["higher"]))
    if layout.single_mode == "INTEGRATION":
        light = g.vmath("ADD", light, lit.integral)
    # The same fetches of I(end): the unshadowed light, for the share sky pixels take.
    return light, phased({"end": 1.0}, {"end": 1.0})
