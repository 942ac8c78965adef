"""The sun's net densities at the nodes of view rays, for single scattering: the optical-depth
table as packed bilinear cells, read at each node toward the sun, and mended where the sun is
near or under a node's horizon (the horizon band; the Earth's shadow under the table's first
row)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from . import parameterization as par
from ..model.atmosphere import AtmosphereParams
from .bake_parallel import parallel_rows
from .interpolation import interpolate
from .optical_depth import fog_column_scale, horizon_floor
from .optical_depth_bake import OPTICAL_DEPTH_STEPS, net_densities
from .view_rays import RayNodes

# -- the horizon band --------------------------------------------------------------------
#
# The optical-depth table's cells next to the horizon blend Earth-hit texels (1e20): a sun ray
# within a texel (0.002 in cosine, 0.11 deg) of grazing the ground read dark, though lit. Single
# scattering toward a sun just under the camera's horizon comes from exactly such points (a
# ground ray toward a sun 0.25 deg down, 172 m up: 36-48% dark; read at the first node above
# the horizon instead, as table_net_density does, 29-53% bright). The band table holds those
# rays' net densities on their own axis, the cosine above each height's horizon.

HORIZON_BAND_NODES = 32
HORIZON_BAND_ROWS = 256         # heights h = H_atm (k / (n - 1))^2: 1.2 m apart at the ground
HORIZON_BAND_TEXELS = 3         # the band's width in the optical-depth table's cosine texels
HORIZON_BAND_STEPS = 4 * OPTICAL_DEPTH_STEPS    # grazing rays cross the densest air: more nodes


@dataclass(frozen=True)
class SunDepths:
    """What bake_single reads the sun's net densities from: the optical-depth table's packed
    bilinear cells and the horizon band (HORIZON_BAND_ROWS heights from the ground up; nodes
    evenly spaced in cosine above each row's horizon over ``band_width``)."""

    cells_low: np.ndarray
    cells_high: np.ndarray
    band: Optional[np.ndarray]  # (HORIZON_BAND_ROWS, HORIZON_BAND_NODES, 4); None: without it
    band_width: float


def sun_depths(params: AtmosphereParams, optical_depth: np.ndarray, media_used: int, band: bool = False) -> SunDepths:
    """The optical-depth table as packed bilinear cells (bilinear_cells) for bake_single's sun
    look-ups, and with ``band`` its horizon band; a caller integrating often
    (lut_gen.passes.sky_view) keeps them. Net densities are interpolated and then exponentiated
    per channel; the 1e20 of Earth-hit texels makes a cell that touches the Earth's shadow
    dark, so rays within the band read the band instead.

    The bake itself goes without the band: finding the band's rays among all the table's cost
    the default bake 5-7% (0.3-0.45 s of 6.5 s), and its look-ups between nodes are far coarser
    than the band's gain (their low-sun p99 12.6% either way). The camera's sky, integrated at
    its own views, uses it."""
    net = np.minimum(optical_depth, np.float32(1e6))
    low, high = (_packed_cells(c) for c in bilinear_cells(net[..., :media_used]))
    n_height, n_cos = optical_depth.shape[:2]
    width = HORIZON_BAND_TEXELS * 2.0 / n_cos
    if not band:
        return SunDepths(low, high, None, width)
    heights = np.linspace(0.0, 1.0, HORIZON_BAND_ROWS)[:, None] ** 2 * params.atmosphere_height
    cosines = par.cos_horizon(heights, params.earth_radius) + np.linspace(0.0, width, HORIZON_BAND_NODES)[None, :]
    table = np.empty((HORIZON_BAND_ROWS, HORIZON_BAND_NODES, 4), np.float32)
    rows = HORIZON_BAND_ROWS // 8

    def fill(chunk):
        sl = slice(chunk * rows, (chunk + 1) * rows)
        table[sl] = net_densities(params, heights[sl], cosines[sl], HORIZON_BAND_STEPS)
    parallel_rows(fill, 8, lambda stage, fraction: None, "horizon band")
    return SunDepths(low, high, table, width)


def sun_near_horizon(params, depths: SunDepths, sun_net, node_h, cos_node, cos_sun, s, n_odh: int, n_odc: int,
                      opaque_medium: int):
    """Mend bake_single's sun net densities ``sun_net`` (media, a, K, s, t) where the sun is near
    or under the horizon of a node (heights ``node_h`` (a, K), cos sun zenith ``cos_node``
    (a, K, s, t)).

    - The Earth's shadow where the table misses it: a node under its first row (39 m up) reads
      that row, whose horizon is lower, so a sun between the two horizons lit it (a ground ray
      from 33 m toward a sun 0.15 deg down read 2.7x too bright). Above the first row a cell
      blends its own row's Earth-hit texels there, which is dark.
    - With a horizon band: where the table's cell touches Earth-hit texels (above the node's
      horizon, under the first cos node above the horizon of the lower height row the cell
      blends), the band's net density. Along a ray the sun's zenith angle changes by at most
      the angle between the verticals at the camera and at the node, so only the sun nodes with
      cos under band_width + that angle are looked at."""
    low = np.nonzero(node_h < 0.5 * params.atmosphere_height / n_odh)
    if low[0].size:
        # A huge column of a medium that absorbs in every channel darkens the node.
        horizon = par.cos_horizon(node_h[low], params.earth_radius).astype(np.float32)[:, None, None]
        low_net = sun_net[opaque_medium][low]
        np.copyto(low_net, np.float32(1e30), where=cos_node[low] < horizon)
        sun_net[opaque_medium][low] = low_net
    if depths.band is None:
        return
    # The angle between the verticals at the camera (radius r) and at each node: cos =
    # (r + s c_v) / |P|, with s c_v from |P|^2 = r^2 + s^2 + 2 r s c_v.
    radius = node_h + params.earth_radius
    r = radius[:, :1]
    cos_turn = (r + (radius * radius - r * r - s * s) / (2.0 * r)) / radius
    reach = float(np.arccos(np.clip(cos_turn.min(), -1.0, 1.0))) + depths.band_width
    j_max = int(np.searchsorted(np.asarray(cos_sun), reach, side="right"))
    if j_max == 0:
        return
    horizon, clean = horizon_floor(params, node_h, n_odh, n_odc)
    above = cos_node[:, :, :j_max] - horizon.astype(np.float32)[:, :, None, None]
    # 0 <= above < limit in one pass: non-negative float32 compare as their bits do, and a
    # negative one's sign bit puts it above any limit. (Under the first row the limit is 0:
    # the first row's horizon is lower, and a lit node's cell is clean.)
    limit = np.clip(clean - horizon, 0.0, depths.band_width).astype(np.float32)[:, :, None, None]
    in_band = np.nonzero(above.view(np.uint32) < limit.view(np.uint32))
    if in_band[0].size:
        near = sun_net[:, :, :, :j_max]
        near[(slice(None),) + in_band] = _band_net_density(params, depths, node_h[in_band[:2]],
                                                           cos_node[:, :, :j_max][in_band], sun_net.shape[0])


def _band_net_density(params, depths: SunDepths, node_h, cos_node, media_used: int):
    """(media, n) net densities of n sun rays inside the horizon band, as the main look-up gives
    them (the fog's factor included)."""
    h = np.clip(np.asarray(node_h, np.float64), 0.0, params.atmosphere_height)
    x_h = np.sqrt(h / params.atmosphere_height) * (HORIZON_BAND_ROWS - 1)
    x_d = ((np.asarray(cos_node, np.float64) - par.cos_horizon(h, params.earth_radius))
           * ((HORIZON_BAND_NODES - 1) / depths.band_width))
    net = interpolate(depths.band[..., :media_used], (x_h, x_d))
    if media_used > 3:
        net[:, 3] *= fog_column_scale(params, node_h, cos_node).astype(np.float32)
    return net.T


def node_cos_sun(r, nodes: RayNodes, cos_sun, cos_sun_view):
    """(rays, K, n_s, n_t) cos sun zenith at every node: (r c_s + s c_t) / |P|."""
    s = nodes.s[:, :, None, None].astype(np.float32)
    inv_radius = (1.0 / nodes.radius)[:, :, None, None].astype(np.float32)
    return (np.float32(r) * cos_sun[None, None, :, None].astype(np.float32)
            + s * cos_sun_view[:, None].astype(np.float32)) * inv_radius


def bilinear_cells(table: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """The coefficients of every cell of a 2D table (n0, n1, M), M <= 4, so that its bilinear
    value is (a + b*w1) + w0*(c + d*w1): two (n0-1, n1-1, 8) tables, [a, b] and [c, d], each
    coefficient padded to 4 media. A look-up then gathers two 32-byte records, which numpy's
    take copies with a fixed-size move where one 64-byte record took a memmove call each
    (3.8 s of the default bake's single scattering, against 0.6 s)."""
    n0, n1, media = table.shape
    if media > 4:
        raise ValueError(f"bilinear_cells takes at most 4 media, not {media}")
    v00, v01, v10, v11 = table[:-1, :-1], table[:-1, 1:], table[1:, :-1], table[1:, 1:]
    low = np.zeros((n0 - 1, n1 - 1, 8), np.float32)
    high = np.zeros((n0 - 1, n1 - 1, 8), np.float32)
    low[..., :media] = v00
    np.subtract(v01, v00, out=low[..., 4:4 + media])
    np.subtract(v10, v00, out=high[..., :media])
    d = high[..., 4:4 + media]
    np.subtract(v11, v10, out=d)
    d -= v01
    d += v00
    return low, high


def _packed_cells(cells: np.ndarray) -> np.ndarray:
    record = np.dtype([("v", np.float32, (8,))])
    return np.ascontiguousarray(cells).reshape(-1, 8).view(record).reshape(-1)
