"""Precomputation of the scattering tables (Yusov 2013, "Multiple Scattering").

Stages, each a pure function of AtmosphereParams:
  optical depth   net Rayleigh/Mie/ozone density from (height, cos zenith) to the top
  single          L1, eq. (2) with the sun term, parabolas between view-ray nodes, Rayleigh and
                  Mie kept apart without their phase functions (applied exactly at look-up)
  orders 2..N     J(n) = sphere integral of L(n-1) against the phase functions (eq. 1),
                  L(n) = its integral along the view ray (eq. 2); summed into "higher"
  ambient         E_sky, eq. (3), over the upper hemisphere at 20 m

Spectral params are integrated at the wavelengths of lut_gen.model.spectrum (every stage works on C
channels at once: the optical-depth table holds net densities, which do not depend on
wavelength) and converted to linear Rec.709 at the end.

Two ideas keep this fast in numpy without giving up accuracy:

* Product integration along view rays. The integrand of eqs. (1)-(2) is (density x view
  transmittance), which varies fast and does not depend on the sun, times a slowly varying sun
  factor (sun transmittance for L1, J / density for higher orders). The first is integrated
  per ray on a fine grid into node weights A_k (lut_gen.tables.view_rays); the second is evaluated only at a few
  nodes k per ray and per sun configuration: L = sum_k A_k * f(node k).
* The sphere integral of eq. (1) for fixed height and sun zenith is a convolution in azimuth
  with the phase function, done with real FFTs over a fixed direction grid; the discrete
  kernel is normalised so that a constant radiance integrates exactly.

Higher orders are smooth, so they are computed on a grid with half the nodes along height,
view and sun zenith and resampled onto the full grid at the end.
"""
from __future__ import annotations

import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Callable, Optional, Sequence, Tuple, Union

import numpy as np

from .process_tuning import blas_on_one_thread, tuned_for_bake
from . import parameterization as par
from ..model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase
from ..model.spectrum import Media, bake_media, spectra_to_rgb, spectral_resample_matrix
from .ground import GroundSource
from ..model.geometry import clustered_nodes, distance_to_sphere_exit, radius_along
from .interpolation import (ABSOLUTE_FLOOR, axis_weights, gather, geometric_lerp_of_logs, interpolate, packed_rows,
                            resample_matrix, resample_separable, resample_sun_geometric)
from .optical_depth import (EARTH_HIT_NET_DENSITY, below_first_row_factors, fog_column_scale, horizon_floor,
                            lowest_height)
from .lookup import Luts
from .view_rays import RayNodes, density_profiles, view_ray_nodes

Progress = Callable[[str, float], None]


@dataclass(frozen=True)
class Resolution:
    scattering: Tuple[int, int, int, int]   # (height, view zenith, sun zenith, sun-view)
    optical_depth: Tuple[int, int]          # (height, cos zenith)
    ambient: int


RESOLUTIONS = {
    "default": Resolution((32, 128, 64, 16), (1024, 1024), 1024),
    # The preview while a default bake runs (addon/baking.py), so its time is the wait: 256 x 256
    # optical depth and 128 ambient nodes bake in 1.7 s against 2.5 s at 512 and 512, with the
    # same sky (median 1.9%, p90 5.5% against the default tables over 4000 random rays).
    "draft": Resolution((16, 64, 32, 8), (256, 256), 128),
}

# Quadrature settings (named so that their effect on accuracy can be measured in one place).
OPTICAL_DEPTH_STEPS = 48        # nodes per optical-depth ray (clustered toward low heights)
SINGLE_NODES = 32               # sun-transmittance nodes per view ray
SINGLE_SUBSTEPS = 8             # fine steps per node interval for density x transmittance
NODE_UNIFORM_SHARE = 0.6        # keeps far, sunlit stretches of twilight rays sampled
HIGHER_NODES = 24               # J nodes per view ray for orders >= 2
HIGHER_SUBSTEPS = 4
HIGHER_UNIFORM_SHARE = 0.2      # J / density falls fastest near the ground: cluster there
SPHERE_BELOW_NODES = 17         # sphere-integral zeniths below the horizon band (angle-spaced)
SPHERE_BAND_NODES = 49          # ... inside the band of horizons (cos-spaced)
SPHERE_ABOVE_NODES = 25         # ... above it (angle-spaced, up to the zenith)
SPHERE_AZIMUTHS = 64            # azimuth samples of the sphere integral (full circle)
AMBIENT_HEIGHT_M = 20.0         # the sample's camera height for eq. (3)
MAX_ORDERS = 30


def _workers() -> int:
    return max(1, min(os.cpu_count() or 1, 8))


def _parallel_rows(function, count: int, progress: Progress, stage: str):
    """Run function(i) for i in range(count) on all cores (numpy releases the GIL in its
    loops), reporting progress in completion order."""
    with blas_on_one_thread(), ThreadPoolExecutor(_workers()) as pool:
        try:
            for done, _ in enumerate(pool.map(function, range(count)), 1):
                progress(stage, done / count)
        except BaseException:
            # A progress callback may stop the bake (a newer bake superseded it): drop the
            # rows not started rather than finishing the stage.
            pool.shutdown(wait=True, cancel_futures=True)
            raise


# Work items stay below ~32 MB per temporary array: larger ones are mmapped afresh by malloc
# on every allocation and page faults then cost more than the arithmetic.
LOOKUPS_PER_BATCH = 1 << 18


def _ray_batches(n_h: int, n_a: int, lookups_per_ray: int):
    """(height index, slice of view rays) work items of about LOOKUPS_PER_BATCH look-ups."""
    rays = max(1, min(n_a, LOOKUPS_PER_BATCH // max(1, lookups_per_ray)))
    return [(i, slice(a, min(a + rays, n_a))) for i in range(n_h) for a in range(0, n_a, rays)]


def resolve_resolution(resolution: Union[str, Sequence[int], Resolution]) -> Resolution:
    if isinstance(resolution, Resolution):
        return resolution
    if isinstance(resolution, str):
        try:
            return RESOLUTIONS[resolution]
        except KeyError:
            raise ValueError(f"resolution must be one of {', '.join(RESOLUTIONS)} or 4 table sizes, "
                             f"got {resolution!r}") from None
    dims = tuple(resolution)
    if len(dims) != 4 or not all(isinstance(n, (int, np.integer)) for n in dims):
        raise ValueError(f"resolution tuple must be 4 integers (height, view, sun, sun-view), got {resolution!r}")
    n_h, n_a, n_s, n_t = dims
    if n_h < 2 or n_s < 2 or n_t < 2 or n_a < 4 or n_a % 2:
        raise ValueError("resolution needs >= 2 nodes per axis and an even view axis >= 4, "
                         f"got {resolution!r}")
    _check_memory(dims)
    return Resolution(tuple(int(n) for n in dims), RESOLUTIONS["default"].optical_depth,
                      RESOLUTIONS["default"].ambient)


# Bytes per texel of the 4D tables at the bake's peak: Rayleigh and Mie single scattering at
# every wavelength of the bake (2 x 12 float32) plus the four RGB tables kept (4 x 3 float32).
BYTES_PER_TEXEL = 4 * (2 * 12 + 4 * 3)


def _check_memory(dims):
    """Refuse, before any work, a resolution whose tables cannot fit in this machine's memory
    (a MemoryError came after a whole stage otherwise)."""
    need = int(np.prod([int(n) for n in dims], dtype=np.float64)) * BYTES_PER_TEXEL
    try:
        have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return
    if need > 0.8 * have:
        size = "x".join(str(int(n)) for n in dims)
        raise ValueError(f"resolution {size} needs about {need / 2**30:.1f} GiB for its tables; this machine has "
                         f"{have / 2**30:.1f} GiB: choose smaller tables (the default is 32x128x64x16)")


def higher_order_dims(dims):
    """Grid for orders >= 2: half the height, view and sun-zenith nodes (they are smooth)."""
    n_h, n_a, n_s, n_t = dims
    half_a = max(4, (n_a // 2) // 2 * 2)
    return (max(2, (n_h + 1) // 2), half_a, max(2, (n_s + 1) // 2), n_t)


# Orders from this one on (only fog bakes get there: the clear sky stops at CLEAR_SKY_ORDERS)
# are computed on late_order_dims, the order grid with half its view nodes. By then the light
# has scattered four times and is smoother, and the fog's ten to twenty orders after it took
# three quarters of a morning-fog bake.
LATE_ORDERS_FROM = 5


def late_order_dims(dims_j):
    """Grid for orders >= LATE_ORDERS_FROM from the grid of the orders before: half its view
    nodes. (Halving the height nodes as well moved the morning fog's tables by 2.5x at worst,
    a fog 50 m deep needs them; halving the sun-zenith nodes instead of the view's moved them
    by 4.6% at p99 against 3.1%.)"""
    n_h, n_a, n_s, n_t = dims_j
    return (n_h, max(4, (n_a // 2) // 2 * 2), n_s, n_t)


# -- optical depth --------------------------------------------------------------

def bake_optical_depth(params: AtmosphereParams, n_height: int, n_cos: int,
                       steps: int = OPTICAL_DEPTH_STEPS, progress: Optional[Progress] = None) -> np.ndarray:
    """(n_height, n_cos, 4) net densities to the top, the fog's divided by fog_column_scale;
    EARTH_HIT_NET_DENSITY where blocked. Nodes at texel centres: h = (i + 0.5) / n * H_atm,
    c = 2 (j + 0.5) / n - 1."""
    heights = par.centre_nodes(n_height) * params.atmosphere_height
    cosines = par.centre_nodes(n_cos) * 2.0 - 1.0
    out = np.zeros((n_height, n_cos, 4), dtype=np.float32)
    rows = max(1, (1 << 19) // (n_cos * steps))
    starts = list(range(0, n_height, rows))

    def fill(chunk):
        sl = slice(starts[chunk], starts[chunk] + rows)
        h = heights[sl, None]
        out[sl] = _net_densities(params, h, cosines[None, :], steps)
        hits = cosines[None, :] < par.cos_horizon(h, params.earth_radius)
        out[sl, :, :4 if params.has_fog else 3][hits] = EARTH_HIT_NET_DENSITY

    _parallel_rows(fill, len(starts), progress or (lambda *a: None), "optical depth")
    return out


def _net_densities(params: AtmosphereParams, h, cos_zenith, steps: int) -> np.ndarray:
    """(..., 4) float32 net densities to the top of rays from heights ``h`` (..., 1) at zenith
    cosines (..., n), the fog's divided by fog_column_scale; rays into the Earth not marked."""
    r = params.earth_radius + h
    length = distance_to_sphere_exit(r, cos_zenith, params.top_radius)
    s = clustered_nodes(r, cos_zenith, length, steps).astype(np.float32)
    node_heights = _height_along(params, h, r, cos_zenith, s)
    weights = _trapezoid_weights(s)
    rayleigh, mie, ozone, fog = density_profiles(params, node_heights)
    heights_clamped = np.maximum(node_heights, np.float32(0.0))
    out = np.zeros(np.broadcast(h, cos_zenith).shape + (4,), np.float32)
    out[..., 0] = _exponential_segments_integral(rayleigh, heights_clamped, params.rayleigh_scale_height, s)
    out[..., 1] = _exponential_segments_integral(mie, heights_clamped, params.mie_scale_height, s)
    out[..., 2] = np.einsum("...k,...k->...", ozone, weights) if ozone is not None else 0.0
    if fog is not None:
        # Divided by the lowest point's density in the integral itself: the column of a fog
        # 20 m thick seen from 5 km up underflows float32, its ratio does not.
        lowest = lowest_height(params, h, cos_zenith)
        relative = np.exp((lowest[..., None].astype(np.float32) - heights_clamped) * np.float32(1.0 / params.fog_height))
        out[..., 3] = _exponential_segments_integral(relative, heights_clamped, params.fog_height, s)
    return out


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
        table[sl] = _net_densities(params, heights[sl], cosines[sl], HORIZON_BAND_STEPS)
    _parallel_rows(fill, 8, lambda stage, fraction: None, "horizon band")
    return SunDepths(low, high, table, width)


def _sun_near_horizon(params, depths: SunDepths, sun_net, node_h, cos_node, cos_sun, s, n_odh: int, n_odc: int,
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


def _height_along(params, h, r, cos_zenith, s):
    """Height at distance s along rays from (h, r = R + h); float32-safe form of |P| - R."""
    h, r, c = (np.asarray(v, dtype=np.float64)[..., None] for v in (h, r, cos_zenith))
    s = s.astype(np.float32)
    rise = s * (s + (2.0 * r * c).astype(np.float32))
    return h.astype(np.float32) + rise / (radius_along(r, c, s).astype(np.float32) + r.astype(np.float32))


def _exponential_segments_integral(density, heights, scale_height: float, s):
    """Integral along the last axis of density = exp(-height / scale_height), taken as
    exponential in s between its samples (exact on a straight vertical ray). The trapezoid
    rule on the same 48 nodes overestimated the Mie column by 1% (Rayleigh 0.15%), which a low
    sun's transmittance turns into several percent."""
    a, b = density[..., :-1], density[..., 1:]
    # log(b / a) without a log: the densities are exponentials of the heights.
    log_ratio = (heights[..., :-1] - heights[..., 1:]) * np.float32(1.0 / scale_height)
    small = np.abs(log_ratio) < np.float32(1e-3)
    # (b - a) / log(b / a), with its series where the segment barely changes height.
    mean = np.where(small, 0.5 * (a + b), (b - a) / np.where(small, np.float32(1.0), log_ratio))
    return np.einsum("...k,...k->...", mean, np.diff(s, axis=-1).astype(np.float32))


def _trapezoid_weights(s):
    """Trapezoid-rule weights of the samples s (..., n) along the last axis."""
    ds = np.diff(s, axis=-1)
    weights = np.zeros_like(s)
    weights[..., :-1] += 0.5 * ds
    weights[..., 1:] += 0.5 * ds
    return weights


def _node_cos_sun(r, nodes: RayNodes, cos_sun, cos_sun_view):
    """(rays, K, n_s, n_t) cos sun zenith at every node: (r c_s + s c_t) / |P|."""
    s = nodes.s[:, :, None, None].astype(np.float32)
    inv_radius = (1.0 / nodes.radius)[:, :, None, None].astype(np.float32)
    return (np.float32(r) * cos_sun[None, None, :, None].astype(np.float32)
            + s * cos_sun_view[:, None].astype(np.float32)) * inv_radius


# -- single scattering -----------------------------------------------------------------

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


def bake_single(params: AtmosphereParams, media: Media, dims, optical_depth: np.ndarray,
                progress: Progress, axes=None, depths=None, nodes: int = None) -> Tuple[np.ndarray, np.ndarray, Optional[np.ndarray]]:
    """Single scattering without phase functions, (n_h, n_a, n_s, n_t, C) for Rayleigh, for
    Mie and for the fog (None without fog): radiance = rayleigh * P_R(nu) + mie * P_M(nu)
    + fog * P_F(nu).

    ``axes``: the rays to integrate instead of the 4D table's nodes, (heights (n_h,), cos view
    zenith (n_h, n_a), above-horizon flags (n_a,), cos sun zenith (n_s,), sun_view) with
    sun_view(i, rays) the (rays, n_s, n_t) cos sun-view angles of height i's view rays ``rays``
    (lut_gen.passes.sky_view integrates a camera's sky with it); ``depths``:
    sun_depths(params, optical_depth, media used), when the caller keeps them; ``nodes``: per
    view ray (SINGLE_NODES)."""
    n_h, n_a, n_s, n_t = dims
    if axes is None:
        heights, cos_view, above, cos_sun, cos_sun_view = par.grid_axes(params, dims)

        def sun_view(i, rays):
            return par.clamp_sun_view(cos_view[i][rays, None, None], cos_sun[None, :, None], cos_sun_view[None, None, :])
    else:
        heights, cos_view, above, cos_sun, sun_view = axes
    n_odh, n_odc = optical_depth.shape[:2]
    fog = media.has_fog
    media_used = 4 if fog else 3
    depths = sun_depths(params, optical_depth, media_used) if depths is None else depths
    cells_low, cells_high = depths.cells_low, depths.cells_high
    extinction = media.extinction_matrix()[:media_used].astype(np.float32)
    # The medium whose extinction is positive in every channel: a huge column of it darkens a
    # node in the Earth's shadow (_sun_near_horizon). Without one (no air) nothing scatters.
    opaque_medium = int(np.argmax(extinction.min(axis=1)))
    media_scatter = np.stack([media.rayleigh, media.mie] + ([media.fog] if fog else []), axis=-1).astype(np.float32)
    k_nodes = nodes or SINGLE_NODES
    channels = media.channels
    out_r = np.empty((n_h, n_a, n_s, n_t, channels), dtype=np.float32)
    out_m = np.empty((n_h, n_a, n_s, n_t, channels), dtype=np.float32)
    out_f = np.empty((n_h, n_a, n_s, n_t, channels), dtype=np.float32) if fog else None
    tasks = _ray_batches(n_h, n_a, k_nodes * n_s * n_t * max(1, channels // 3))
    # The view rays' nodes, a height's rays at a time (2 rays a call spent 1.4 s of one core
    # in numpy's per-call overhead).
    nodes_at = [None] * n_h

    def find_nodes(i):
        nodes_at[i] = view_ray_nodes(params, media, heights[i], cos_view[i], above, k_nodes, SINGLE_SUBSTEPS,
                                     NODE_UNIFORM_SHARE, quadratic=True)
    _parallel_rows(find_nodes, n_h, lambda stage, fraction: progress(stage, 0.0), "single scattering")

    def fill(task):
        i, rays = tasks[task]
        nodes = nodes_at[i].rays(rays)
        n_rays = len(nodes.s)
        ct = sun_view(i, rays)
        node_h = nodes.radius - params.earth_radius
        ih, wh = axis_weights(par.unit_to_centre_x(node_h / params.atmosphere_height, n_odh), n_odh)
        # The table's first row sits 39 m up and the look-up clamps there: nodes lower down
        # (every ground ray ends at 0 m) need the columns' growth below it, or a low sun's
        # path misses the aerosol below 39 m (3% of its column) and ground rays at sunset read
        # 5-13% too bright.
        below = below_first_row_factors(params, node_h, n_odh).astype(np.float32)[..., :media_used]   # (a, K, m)
        cos_node = _node_cos_sun(params.earth_radius + heights[i], nodes, cos_sun, ct)       # (a, K, s, t)
        ic, wc = axis_weights(par.unit_to_centre_x(cos_node * np.float32(0.5) + np.float32(0.5), n_odc), n_odc)
        ic += ih[:, :, None, None] * (n_odc - 1)
        # Node-major order keeps each node's gathers inside one table row (cache friendly).
        low, high = gather(cells_low, 8, ic), gather(cells_high, 8, ic)                   # (a, K, s, t, 8)
        # Net densities medium-major (numpy's loops then run over a node's look-ups, not over 4
        # media), then one matmul gives every channel's optical depth.
        scale_low = below.transpose(2, 0, 1)[:, :, :, None, None]                        # (media, a, K, 1, 1)
        scale_high = scale_low * wh[None, :, :, None, None]
        sun_net = np.empty((media_used,) + cos_node.shape, np.float32)                     # (media, a, K, s, t)
        upper = np.empty(cos_node.shape, np.float32)
        for m in range(media_used):
            np.multiply(low[..., 4 + m], wc, out=sun_net[m])
            sun_net[m] += low[..., m]
            if np.any(scale_low[m] != 1.0):          # only rays with nodes below the first row
                sun_net[m] *= scale_low[m]
            np.multiply(high[..., 4 + m], wc, out=upper)
            upper += high[..., m]
            upper *= scale_high[m]
            sun_net[m] += upper
        if fog:
            sun_net[3] *= fog_column_scale(params, node_h[:, :, None, None], cos_node)
        _sun_near_horizon(params, depths, sun_net, node_h, cos_node, cos_sun, nodes.s, n_odh, n_odc, opaque_medium)
        depth = (-extinction.T) @ sun_net.reshape(media_used, -1)                          # (C, a*K*s*t)
        sun_trans = np.exp(depth, out=depth).reshape(channels, n_rays, k_nodes, n_s * n_t)
        # Sum over nodes for all media at once, as matmuls per ray and channel (BLAS).
        ray_weights = [nodes.weight_rayleigh, nodes.weight_mie] + ([nodes.weight_fog] if fog else [])
        weights = np.stack(ray_weights, axis=-1).transpose(0, 2, 3, 1)                     # (a, C, media, K)
        integrals = np.matmul(weights, sun_trans.transpose(1, 0, 2, 3))                    # (a, C, media, s*t)
        integrals *= media_scatter[:, :len(ray_weights), None]
        integrals = integrals.reshape(n_rays, channels, len(ray_weights), n_s, n_t)
        out_r[i, rays] = integrals[:, :, 0].transpose(0, 2, 3, 1)
        out_m[i, rays] = integrals[:, :, 1].transpose(0, 2, 3, 1)
        if fog:
            out_f[i, rays] = integrals[:, :, 2].transpose(0, 2, 3, 1)

    _parallel_rows(fill, len(tasks), progress, "single scattering")
    return out_r, out_m, out_f


# -- higher orders -----------------------------------------------------------------------

def sphere_zenith_grid(atmosphere_height: float, earth_radius: float):
    """Nodes (ascending, poles included) and trapezoid weights in cos zenith over [-1, 1]:
    evenly spaced in angle toward the poles (the Mie kernel is ~10 deg wide everywhere) and
    dense in cos zenith in the band where the horizon of every height inside the atmosphere
    lies, so the radiance jump there costs little."""
    c_low = float(par.cos_horizon(atmosphere_height, earth_radius)) - 0.05
    c_high = 0.05
    below = np.cos(np.linspace(math.pi, math.acos(c_low), SPHERE_BELOW_NODES))
    band = np.linspace(c_low, c_high, SPHERE_BAND_NODES)
    above = np.cos(np.linspace(math.acos(c_high), 0.0, SPHERE_ABOVE_NODES))
    mu = np.concatenate([below[:-1], band[:-1], above])
    mu[0], mu[-1] = -1.0, 1.0
    gaps = np.diff(mu)
    weights = np.zeros_like(mu)
    weights[:-1] += 0.5 * gaps
    weights[1:] += 0.5 * gaps
    return mu, weights


def _cosine_transforms(n_az: int):
    """Forward (m, j) and inverse (j, m) real DFTs of sequences on a circle of n_az samples
    that are symmetric about az = 0, using only the samples j = 0 .. n_az/2 (az in [0, pi])."""
    half = n_az // 2 + 1
    angle = 2 * math.pi * np.outer(np.arange(half), np.arange(half)) / n_az
    doubled = np.full(half, 2.0)
    doubled[[0, -1]] = 1.0           # az = 0 and az = pi appear once on the full circle
    forward = np.cos(angle) * doubled[None, :]
    inverse = np.cos(angle).T * doubled[None, :] / n_az
    return forward.astype(np.float32), inverse.astype(np.float32)


def phase_kernels(params: AtmosphereParams, mu, mu_weights, n_az: int):
    """Spectra over the azimuth difference of the discretised phase functions,
    (n_az//2+1, n_mu_out, n_mu_in) for Rayleigh, Mie and (with fog) the fog, rows normalised to
    integrate to 1."""
    sin = np.sqrt(np.clip(1 - mu * mu, 0, 1))
    d_az = 2 * math.pi / n_az
    cos_az = np.cos(np.arange(n_az // 2 + 1) * d_az)
    cosang = mu[:, None, None] * mu[None, :, None] + sin[:, None, None] * sin[None, :, None] * cos_az
    forward, _ = _cosine_transforms(n_az)
    kernels = []
    phases = [rayleigh_phase(cosang), mie_phase(cosang, params.mie_g)]
    if params.has_fog:
        phases.append(mie_phase(cosang, params.fog_g))
    for phase in phases:
        k = phase * mu_weights[None, :, None] * d_az
        spectrum = np.einsum("vwj,mj->mvw", k, forward.astype(np.float64))
        spectrum /= spectrum[0].sum(axis=1)[None, :, None]      # m = 0 holds the full integral
        kernels.append(spectrum.astype(np.float32))
    return kernels


# Azimuthal frequencies of the sphere integral: a kernel's frequencies from the first one
# under KERNEL_FREQUENCY_FLOOR of its m = 0 term on are left out of the convolution. The
# Rayleigh kernel holds m <= 2 only (its phase is quadratic in the cosine of the scattering
# angle), so its convolution takes 3 of the 33 frequencies; the Mie and fog kernels keep all.
# (The radiance of the orders after the second is not smooth enough in azimuth to truncate it
# as well: its spectrum levels off at a few 1e-3 of the m = 0 term from m ~ 12 on, the kinks of
# the tables' linear interpolation along the sun-view cosine.)
KERNEL_FREQUENCY_FLOOR = 1e-6


def frequencies_needed(kernel: np.ndarray) -> int:
    """M: how many leading frequencies (axis 0) of a kernel's cosine spectrum (m, mu, mu) are
    not negligible (KERNEL_FREQUENCY_FLOOR of the m = 0 term)."""
    size = np.abs(kernel).max(axis=(1, 2))
    above = np.nonzero(size > KERNEL_FREQUENCY_FLOOR * size[0])[0]
    return int(above[-1]) + 1


def _scattered_radiance(params, dims_j, prev_n, mu, kernels, n_az, prev_mie=None, ground=None, prev_fog=None):
    """J~ for Rayleigh, Mie and the fog (phase-convolved radiance, per unit density and
    scattering coefficient; one per kernel) on the order grid: (n_h, n_a, n_s, n_t, media x C).
    ``prev_n`` is the previous order divided by the Rayleigh phase, like the stored tables;
    ``prev_mie`` and ``prev_fog`` (order 2) the single Mie and fog scattering without their
    phases, which are applied here per sphere direction. ``ground``: (GroundSource, irradiance
    of the ground by the order before) adds the lit ground.

    Each height's J~ needs the previous order at that height alone: the heights are shared
    between the cores (on one, this took 0.8 s of each order of the default bake)."""
    n_h, n_a, n_s, n_t = dims_j
    channels = prev_n.shape[-1]
    source = np.concatenate([t for t in (prev_n, prev_mie, prev_fog) if t is not None], axis=-1)
    packed, width = packed_rows(source.reshape(-1, source.shape[-1]))
    directions = _SphereDirections(params, dims_j, mu, n_az)
    if ground is not None:
        ground[0].radiance(ground[1], directions.cos_sun_view, slice(0, 0))     # its sun weights, once
    out = np.empty((n_h, n_a, n_s, n_t, len(kernels) * channels), dtype=np.float32)
    parts = np.array_split(np.arange(n_h), min(n_h, 2 * _workers()))

    def fill(part):
        rows = slice(int(parts[part][0]), int(parts[part][-1]) + 1)
        out[rows] = _scattered_radiance_rows(params, dims_j, directions, packed, width, channels, kernels, rows,
                                             prev_mie is not None, prev_fog is not None, ground)
    _parallel_rows(fill, len(parts), lambda stage, fraction: None, "scattered radiance")
    return out


class _SphereDirections:
    """The sphere directions J~ integrates over (zenith cosines ``mu``, ``n_az`` azimuths, of
    which the half circle is kept: the sky is symmetric about the sun's plane) against the
    order grid's sun nodes, and where each falls on the grid's view-zenith and sun-view axes."""

    def __init__(self, params, dims_j, mu, n_az):
        n_h, n_a, n_s, n_t = dims_j
        self.heights, self.cos_view, _, self.cos_sun, self.cos_sun_view_nodes = par.grid_axes(params, dims_j)
        self.mu, self.n_az = mu, n_az
        self.half = n_az // 2 + 1
        self.d_az = 2 * math.pi / n_az
        az = np.arange(self.half) * self.d_az
        sin_mu = np.sqrt(np.clip(1 - mu * mu, 0, 1))
        sin_sun = np.sqrt(np.clip(1 - self.cos_sun * self.cos_sun, 0, 1))
        xa, _ = par.view_zenith_to_x(mu[None, :], self.heights[:, None], n_a, params.earth_radius)  # (h, mu)
        self.cos_sun_view = (mu[None, :, None] * self.cos_sun[:, None, None]
                             + sin_mu[None, :, None] * sin_sun[:, None, None] * np.cos(az))        # (s, mu, az)
        xt = par.sun_view_to_x(self.cos_sun_view, n_t)
        self.ia, self.wa = axis_weights(xa, n_a)
        self.it, self.wt = axis_weights(xt, n_t)
        self.rayleigh = rayleigh_phase(self.cos_sun_view).astype(np.float32)[None, ..., None]
        self.mie = mie_phase(self.cos_sun_view, params.mie_g).astype(np.float32)[None, ..., None]
        self.fog = mie_phase(self.cos_sun_view, params.fog_g).astype(np.float32)[None, ..., None]
        self.transforms = _cosine_transforms(n_az)


def _scattered_radiance_rows(params, dims_j, directions: _SphereDirections, packed, width, channels, kernels,
                             rows: slice, mie: bool, fog: bool, ground):
    """_scattered_radiance at the heights ``rows`` of the order grid, from the previous order
    packed (packed_rows) with its channels Rayleigh, then Mie and the fog when ``mie`` and
    ``fog``."""
    n_h, n_a, n_s, n_t = dims_j
    n_media = len(kernels)
    mu, half, d_az = directions.mu, directions.half, directions.d_az
    n_mu = len(mu)
    heights = np.arange(n_h)[rows]
    n_rows = len(heights)
    ia, wa = directions.ia[rows], directions.wa[rows]
    it, wt = directions.it, directions.wt
    # Previous-order radiance on the direction grid (exact height and sun nodes): (h, s, mu, az, 3).
    base_h = heights[:, None, None, None] * (n_a * n_s * n_t)
    base_s = np.arange(n_s)[None, :, None, None] * n_t
    radiance = np.zeros((n_rows, n_s, n_mu, half, width), dtype=np.float32)
    for da, w_a in ((0, 1 - wa), (1, wa)):
        for dt, w_t in ((0, 1 - wt), (1, wt)):
            idx = base_h + (ia + da)[:, None, :, None] * (n_s * n_t) + base_s + (it + dt)[None]
            radiance += (w_a[:, None, :, None] * w_t[None])[..., None] * gather(packed, width, idx)
    scattered = radiance[..., :channels] * directions.rayleigh
    if mie:
        scattered += radiance[..., channels:2 * channels] * directions.mie
    if fog:
        scattered += radiance[..., 2 * channels:3 * channels] * directions.fog
    if ground is not None:
        ground_source, irradiance = ground
        scattered += ground_source.radiance(irradiance, directions.cos_sun_view, rows)
    radiance = scattered
    # Convolution in azimuth = product of cosine spectra; a matmul over mu per frequency.
    forward, inverse = directions.transforms
    by_az = np.ascontiguousarray(radiance.transpose(3, 2, 0, 1, 4)).reshape(half, -1)           # (j, mu*h*s*C)
    spectrum = (forward @ by_az).reshape(half, n_mu, -1)                                       # (m, mu, h*s*C)
    table = np.zeros((n_rows, n_s, n_mu, half, n_media * channels), dtype=np.float32)
    for medium, kernel in enumerate(kernels):
        m = frequencies_needed(kernel)
        conv = np.matmul(kernel[:m], spectrum[:m]).reshape(m, -1)                              # (m, mu_v*h*s*C)
        back = (inverse[:, :m] @ conv).reshape(half, n_mu, n_rows, n_s, channels)             # (j, mu_v, h, s, C)
        table[..., channels * medium:channels * (medium + 1)] = back.transpose(2, 3, 1, 0, 4)
    # Resample from (mu, az) to the table's (cos view zenith, cos sun-view) nodes.
    cos_view = directions.cos_view[rows]
    ca = cos_view[:, :, None, None]                                                         # (h, a, 1, 1)
    cs = directions.cos_sun[None, None, :, None]
    ctn = par.clamp_sun_view(ca, cs, directions.cos_sun_view_nodes[None, None, None, :])    # (h, a, s, t)
    denom = np.sqrt(np.clip(1 - ca * ca, 0, 1) * np.clip(1 - cs * cs, 0, 1))
    cos_daz = np.where(denom > 1e-9, (ctn - ca * cs) / np.maximum(denom, 1e-9), 1.0)
    i_az, w_az = axis_weights(np.arccos(np.clip(cos_daz, -1, 1)) / d_az, half)               # (h, a, s, t)
    i_mu, w_mu = axis_weights(np.interp(cos_view, mu, np.arange(n_mu)), n_mu)                 # (h, a)
    packed, width = packed_rows(table.reshape(-1, n_media * channels))
    base = (np.arange(n_rows)[:, None, None, None] * n_s + np.arange(n_s)[None, None, :, None]) * n_mu
    out = np.zeros((n_rows, n_a, n_s, n_t, width), dtype=np.float32)
    for dm, w_m in ((0, 1 - w_mu), (1, w_mu)):
        for dz, w_z in ((0, 1 - w_az), (1, w_az)):
            idx = (base + (i_mu + dm)[:, :, None, None]) * half + i_az + dz
            out += (w_m[:, :, None, None] * w_z)[..., None] * gather(packed, width, idx)
    # The cosine-series convolution rings slightly (a few 1e-3 of the peak) next to the sun's
    # Mie peak; scattered radiance is never negative.
    return np.maximum(out[..., :n_media * channels], 0.0)


class OrderGeometry:
    """What the view-ray integral of every order (eq. 2) needs that does not change from one
    order to the next, per work item of one grid, found by the first order and kept: the nodes
    along each view ray with their weights (media's scattering coefficients included) and where
    each node falls on the grid's height and view-zenith axes (``item``). Where its sun falls on
    the sun-zenith axis is found again each order (``sun_rows``)."""

    def __init__(self, params: AtmosphereParams, media: Media, dims_j):
        self.params, self.media, self.dims = params, media, dims_j
        n_h, n_a, n_s, n_t = dims_j
        self.axes = par.grid_axes(params, dims_j)
        channels = media.channels
        self.tasks = _ray_batches(n_h, n_a, HIGHER_NODES * n_s * n_t * 2 * max(1, channels // 3))
        self._items = {}

    def item(self, task: int):
        item = self._items.get(task)
        if item is None:
            item = self._items[task] = self._find(task)
        return item

    def _find(self, task: int):
        params, media = self.params, self.media
        n_h, n_a, n_s, n_t = self.dims
        heights, cos_view, above, cos_sun, cos_sun_view = self.axes
        i, rays = self.tasks[task]
        cos_view_i, above_i = cos_view[i][rays], above[rays]
        n_rays = len(cos_view_i)
        nodes = view_ray_nodes(params, media, heights[i], cos_view_i, above_i, HIGHER_NODES, HIGHER_SUBSTEPS,
                               HIGHER_UNIFORM_SHARE)
        r = params.earth_radius + heights[i]
        node_h = nodes.radius - params.earth_radius
        node_cos_view = (r * cos_view_i[:, None] + nodes.s) / nodes.radius
        xh = par.height_to_x(node_h, n_h, params.atmosphere_height, par.fog_knee(params))
        xa, _ = par.view_zenith_to_x(node_cos_view, node_h, n_a, params.earth_radius,
                                     above_horizon=np.broadcast_to(above_i[:, None], node_h.shape))
        ih, wh = axis_weights(xh, n_h)
        ia, wa = axis_weights(xa, n_a)
        corners = [(ih + dh, ia + da, (w_h * w_a)[..., None, None, None].astype(np.float32))
                   for dh, w_h in ((0, 1 - wh), (1, wh)) for da, w_a in ((0, 1 - wa), (1, wa))]
        ct = par.clamp_sun_view(cos_view_i[:, None, None], cos_sun[None, :, None], cos_sun_view[None, None, :])
        base = ((np.arange(n_rays)[:, None, None, None] * HIGHER_NODES + np.arange(HIGHER_NODES)[None, :, None, None]) * n_t
                + np.arange(n_t)[None, None, None, :]) * n_s                                  # (a, K, 1, t)
        # Ray weights times the media's scattering coefficients, media-major like J~: (a, K, media x C).
        weights = [media.rayleigh * nodes.weight_rayleigh, media.mie * nodes.weight_mie]
        if nodes.weight_fog is not None:
            weights.append(media.fog * nodes.weight_fog)
        ray_weights = np.concatenate(weights, axis=-1).astype(np.float32)
        return i, rays, corners, (r, nodes, ct, base), ray_weights, (1.0 / rayleigh_phase(ct))[..., None].astype(np.float32)

    def sun_rows(self, sun):
        """(slab rows below each node's sun, weight of the row above): (a, K, s, t) each. Found
        again by every order: kept, they were 12 bytes per node, sun and sun-view angle (150 MB
        at the default resolution), for 4% of an order's time."""
        r, nodes, ct, base = sun
        n_s = self.dims[2]
        cos_node = _node_cos_sun(r, nodes, self.axes[3], ct)                                   # (a, K, s, t)
        i_s, w_s = axis_weights(par.sun_zenith_to_x(cos_node, n_s), n_s)
        return base + i_s, w_s[..., None]


def _integrate_order(params, media: Media, dims_j, j_table, progress: Progress, stage: str,
                     geometry: Optional[OrderGeometry] = None):
    """L(n) on the order grid from J~ (eq. 2), product-integrated along each view ray.
    ``geometry``: the grid's OrderGeometry, kept from order to order (made here if None)."""
    geometry = geometry or OrderGeometry(params, media, dims_j)
    n_h, n_a, n_s, n_t = dims_j
    channels = media.channels
    n_media = j_table.shape[-1] // channels
    out = np.empty((n_h, n_a, n_s, n_t, channels), dtype=np.float32)
    # J~ sun-view major and padded to whole gather records once per order, so each node's slab
    # is copied out contiguous and its logs are taken in place.
    n_j = j_table.shape[-1]
    width = next(w for w in (4, 8, 16, n_j) if w >= n_j)
    j_rows = np.zeros((n_h, n_a, n_t, n_s, width), np.float32)
    j_rows[..., :n_j] = j_table.transpose(0, 1, 3, 2, 4)
    record = np.dtype([("v", np.float32, (width,))])

    def fill(task):
        i, rays, corners, sun, ray_weights, inverse_phase = geometry.item(task)
        below, w_s = geometry.sun_rows(sun)
        # Slab of J~ at each node's (height, view zenith), sun-view major: (a, K, t, s, width).
        slab = None
        for ih, ia, w in corners:
            corner = j_rows[ih, ia]
            corner *= w
            slab = corner if slab is None else slab.__iadd__(corner)
        # Blended geometrically along the sun zenith, from the slab's logs (one per entry, not
        # two per look-up: a third of the orders' time went to those logs).
        np.maximum(slab, ABSOLUTE_FLOOR, out=slab)
        packed = np.log(slab, out=slab).reshape(-1, width).view(record).reshape(-1)
        j_nodes = geometric_lerp_of_logs(gather(packed, width, below), gather(packed, width, below + 1), w_s)
        # One sum per medium: a single einsum over (a, K, s, t, media, C) took 2.5x as long.
        scattered = np.einsum("akstc,akc->astc", j_nodes[..., :channels], ray_weights[..., :channels])
        for medium in range(1, n_media):
            media_slice = slice(medium * channels, (medium + 1) * channels)
            scattered += np.einsum("akstc,akc->astc", j_nodes[..., media_slice], ray_weights[..., media_slice])
        out[i, rays] = scattered * inverse_phase

    _parallel_rows(fill, len(geometry.tasks), progress, stage)
    return out


TAIL_MAX_RATIO = 0.8        # an order at most this share of the one before in the tail's series
TAIL_FLOOR = 1e-30


def geometric_tail(before: np.ndarray, last: np.ndarray) -> np.ndarray:
    """The orders after ``last`` as a geometric series of its ratio to ``before`` (the order
    before it), per element: last r / (1 - r), r = last / before clamped to [0, TAIL_MAX_RATIO]."""
    ratio = np.clip(last / np.maximum(before, TAIL_FLOOR), 0.0, TAIL_MAX_RATIO)
    ratio = np.where(before > TAIL_FLOOR, ratio, 0.0)
    return (np.maximum(last, 0.0) * ratio / (1.0 - ratio)).astype(np.float32)


def grid_to_grid_matrices(params, src_dims, dst_dims):
    """Separable linear resampling matrices from one table grid to another (same
    parameterisation, so each destination node has a fixed coordinate on each source axis)."""
    mats = []
    for axis, (n_src, n_dst) in enumerate(zip(src_dims, dst_dims)):
        if axis == 1:
            half_src, half_dst = n_src // 2, n_dst // 2
            j = np.arange(n_dst)
            t = np.where(j >= half_dst, (j - half_dst) / (half_dst - 1), j / (half_dst - 1))
            x = np.where(j >= half_dst, half_src + t * (half_src - 1), t * (half_src - 1))
        else:
            x = np.arange(n_dst) / (n_dst - 1) * (n_src - 1)
        mats.append(None if n_src == n_dst else resample_matrix(x, n_src))
    return mats


# Orders until converged (orders="converged"): the bake stops after the first order that adds
# less than CONVERGENCE of the radiance so far at every texel that is at least
# CONVERGENCE_FLOOR of the brightest texel at the same height and sun (darker texels are out of
# sight next to it, 13 stops down, and at twilight they converge slowest), or at MAX_ORDERS.
CONVERGED = "converged"
CONVERGENCE = 0.005
CONVERGENCE_FLOOR = 1e-4


def _whole_single(params, dims_j, single, single_mie, single_fog):
    """Single scattering with every phase applied, divided by the Rayleigh phase (the unit of
    the orders), on the order grid: what each order is measured against."""
    _, cos_view, _, cos_sun, cos_sun_view = par.grid_axes(params, dims_j)
    ct = par.clamp_sun_view(cos_view[:, :, None, None], cos_sun[None, None, :, None], cos_sun_view[None, None, None, :])
    whole = single + single_mie * (mie_phase(ct, params.mie_g) / rayleigh_phase(ct))[..., None].astype(np.float32)
    if single_fog is not None:
        whole += single_fog * (mie_phase(ct, params.fog_g) / rayleigh_phase(ct))[..., None].astype(np.float32)
    return whole


def order_share(order: np.ndarray, whole: np.ndarray) -> float:
    """The largest share of ``whole`` that ``order`` adds, over the texels that count
    (CONVERGENCE_FLOOR)."""
    brightest = whole.max(axis=(1, 3, 4), keepdims=True)                # per height and sun
    counted = whole >= CONVERGENCE_FLOOR * brightest
    share = np.where(counted, order / np.maximum(whole, TAIL_FLOOR), 0.0)
    return float(share.max())


def _resample_on_cores(table: np.ndarray, matrices, channels: np.ndarray, floor: Optional[float] = None,
                       scale: Optional[np.ndarray] = None) -> np.ndarray:
    """resample_sun_geometric of ``table @ channels`` (then at least ``floor``, times ``scale``,
    (n_h, n_a, 1, 1, 1)) on every core: split along the sun-view axis, which no grid change
    resamples (it took a second on one core, between every bake's orders)."""
    if matrices[3] is not None:
        raise ValueError("the sun-view axis is split between the cores, so it cannot be resampled")
    n_t = table.shape[3]
    parts = [part for part in np.array_split(np.arange(n_t), min(n_t, _workers())) if len(part)]

    linear_axes = [m if axis < 2 else None for axis, m in enumerate(matrices)]
    sun_axis = [m if axis == 2 else None for axis, m in enumerate(matrices)]

    def mix(chunk):
        chunk = np.ascontiguousarray(chunk)
        return (chunk.reshape(-1, chunk.shape[-1]) @ channels).reshape(chunk.shape[:-1] + (channels.shape[1],))

    def one(part):
        chunk = table[:, :, :, part[0]:part[-1] + 1]
        if floor is None and scale is None:
            # The channel mix commutes with the linear height and view axes: after them, on a
            # quarter of the entries.
            return resample_sun_geometric(mix(resample_separable(chunk, linear_axes)), sun_axis)
        chunk = mix(chunk)
        if floor is not None:
            np.maximum(chunk, np.float32(floor), out=chunk)
        if scale is not None:
            chunk *= scale.astype(np.float32)
        return resample_sun_geometric(chunk, matrices)

    with blas_on_one_thread(), ThreadPoolExecutor(len(parts)) as pool:
        return np.concatenate(list(pool.map(one, parts)), axis=3)


def bake_higher_orders(params: AtmosphereParams, media: Media, dims, single_rayleigh: np.ndarray,
                       single_mie: np.ndarray, orders, progress: Progress,
                       optical_depth: np.ndarray, single_media: Optional[Media] = None, tail: bool = True,
                       single_fog: Optional[np.ndarray] = None) -> Tuple[np.ndarray, list, int]:
    """Sum of orders 2..N divided by the Rayleigh phase and the ground-ray scale, in RGB, from
    single scattering without phases at the wavelengths of ``single_media`` (default: ``media``);
    the orders themselves are integrated at the (fewer) wavelengths of ``media``: they are smooth
    in wavelength. Per-order timings, and N.

    ``orders``: N, or CONVERGED: until an order adds less than CONVERGENCE (see there), at
    most MAX_ORDERS (a line is printed when the cap stops it).

    ``tail`` (N >= 3): the orders after N as a geometric series, order N x r / (1 - r) with r the
    ratio of order N to order N - 1 per texel and wavelength (at most TAIL_MAX_RATIO). Each order
    of the clear sky is about half the one before wherever multiple scattering matters (the
    ground's light feeds every order), so four orders alone left up to 25% of the sky out (the
    horizon from the ground, the air 1-3 km up: a median 11% there); with the tail the four
    orders are within 3% (p99 over the draft table) of fifteen orders, five within 2% (max)."""
    dims_j = higher_order_dims(dims)
    to_order_grid = grid_to_grid_matrices(params, dims, dims_j) + [None]
    spectral = spectral_resample_matrix(single_media or media, media).T.astype(np.float32)
    prev, prev_mie, prev_fog = (None if table is None else _resample_on_cores(table, to_order_grid, spectral)
                                for table in (single_rayleigh, single_mie, single_fog))
    converge = orders == CONVERGED
    cap = MAX_ORDERS if converge else orders
    whole = _whole_single(params, dims_j, prev, prev_mie, prev_fog) if converge else None
    mu, mu_w = sphere_zenith_grid(params.atmosphere_height, params.earth_radius)
    kernels = phase_kernels(params, mu, mu_w, SPHERE_AZIMUTHS)
    total = np.zeros_like(prev)
    parts = []                 # (sum of orders, its grid) of the grids left behind
    timings = []
    ground, irradiance = None, None
    if params.ground_albedo > 0.0:
        ground = _ground_source(params, media, optical_depth, mu, dims_j)
        irradiance = ground.direct
    late_dims = late_order_dims(dims_j)
    geometry = OrderGeometry(params, media, dims_j)
    before, order = None, 1
    for order in range(2, cap + 1):
        t0 = time.perf_counter()
        if order == LATE_ORDERS_FROM and late_dims != dims_j:
            # From here on the orders are smooth enough for a coarser grid (see LATE_ORDERS_FROM).
            # Resampled, like the sum at the end, with the ground-ray scale divided out: ground
            # rays in fog change fastest next to the horizon, their scaled radiance does not.
            down = grid_to_grid_matrices(params, dims_j, late_dims) + [None]
            scale_j, scale_late = par.grid_scale(params, dims_j), par.grid_scale(params, late_dims)
            prev = resample_sun_geometric(prev / scale_j, down) * scale_late
            if converge:
                whole = resample_sun_geometric(whole / scale_j, down) * scale_late
            if ground is not None:
                irradiance = (down[2] @ irradiance).astype(np.float32) if down[2] is not None else irradiance
                ground = _ground_source(params, media, optical_depth, mu, late_dims)
            parts.append((total, dims_j))
            total, dims_j = np.zeros_like(prev), late_dims
            geometry = OrderGeometry(params, media, dims_j)
        # Order n scatters order n - 1 and the ground lit by order n - 2 (the sun for n = 2).
        j_table = _scattered_radiance(params, dims_j, prev, mu, kernels, SPHERE_AZIMUTHS, prev_mie,
                                      None if ground is None else (ground, irradiance), prev_fog)
        if ground is not None and order < cap:
            irradiance = ground.sky_irradiance(prev, prev_mie, prev_fog)
        before = prev if prev_mie is None else None
        prev, prev_mie, prev_fog = _integrate_order(params, media, dims_j, j_table, progress,
                                                    f"scattering order {order}", geometry), None, None
        total += prev
        timings.append((f"order {order}", time.perf_counter() - t0))
        if converge:
            whole += prev
            if order_share(prev, whole) < CONVERGENCE:
                break
    else:
        if converge:
            print(f"lut_gen: scattering orders stopped at the cap of {MAX_ORDERS}: the last one still added "
                  f"{order_share(prev, whole):.1%} somewhere (the geometric tail adds the rest)", flush=True)
    if tail and order >= 3:
        total += geometric_tail(before, prev)
    parts.append((total, dims_j))
    # Colour conversion first: it commutes with the resampling and leaves 3 channels, not C.
    # The ground-ray scale is divided out before resampling across heights (see geometry).
    to_rgb = media.to_rgb.T.astype(np.float32)
    higher = sum(_resample_on_cores(part, grid_to_grid_matrices(params, part_dims, dims) + [None], to_rgb,
                                    floor=0.0, scale=1.0 / par.grid_scale(params, part_dims))
                 for part, part_dims in parts)
    return higher, timings, order


def _ground_source(params, media, optical_depth, mu, dims_j):
    heights, _, _, cos_sun, _ = par.grid_axes(params, dims_j)
    return GroundSource(params, media, optical_depth, heights, mu, cos_sun, dims_j)


# -- ambient skylight ----------------------------------------------------------------------

def bake_ambient(luts: Luts, n: int, progress: Progress = lambda stage, fraction: None) -> np.ndarray:
    """E_sky(c_s) = integral over the upper hemisphere of L_M(20 m, w, l) (w . N) dw, the sun
    nodes shared between the cores (one took 1 s of the default bake)."""
    cos_sun = par.centre_nodes(n) * 2 - 1
    parts = np.array_split(np.arange(n), min(n, 2 * _workers()))
    out = np.empty((n, 3), dtype=np.float32)

    def fill(part):
        rows = parts[part]
        out[rows] = luts.sky_irradiance(AMBIENT_HEIGHT_M, cos_sun[rows])
    # The tables packed for look-ups once for all parts (each look-up packs them anew otherwise),
    # and dropped after: the bake's Luts do not keep them.
    kept = luts._packed
    luts.keep_packed()
    try:
        for name in ("multiple", "single_mie") + (() if luts.single_fog is None else ("single_fog",)):
            luts._packed_table(name)
        _parallel_rows(fill, len(parts), progress, "ambient skylight")
    finally:
        luts._packed = kept
    return out


# -- driver --------------------------------------------------------------------------------

CLEAR_SKY_ORDERS = 4


def resolve_orders(params: AtmosphereParams, orders=None):
    """The orders a bake integrates: ``orders`` checked, or for None the default: CLEAR_SKY_ORDERS
    plus the geometric tail without fog (four orders and the tail are within 3% p99 of fifteen,
    while converging to CONVERGENCE takes ten orders, +21 s), CONVERGED with fog (a fog of a few
    hundred metres' visibility needs twenty or more)."""
    if orders is None:
        return CONVERGED if params.has_fog else CLEAR_SKY_ORDERS
    if orders == CONVERGED:
        return CONVERGED
    if isinstance(orders, bool) or not isinstance(orders, (int, np.integer)) or not 1 <= orders <= MAX_ORDERS:
        raise ValueError(f"orders must be an integer from 1 to {MAX_ORDERS} or {CONVERGED!r}, got {orders!r}")
    return int(orders)


def bake(params: Optional[AtmosphereParams] = None, *, resolution="default", orders=None,
         progress: Optional[Progress] = None, tail: bool = True) -> Luts:
    """Bake every table for ``params`` (default: the clear-sky preset).

    ``resolution``: "default" (32 x 128 x 64 x 16), "draft" (half every dimension) or a tuple of
    the four 4D sizes. ``orders``: scattering orders integrated into the multiple table (>= 1),
    "converged" or None (resolve_orders); ``tail``: the orders after them added as a geometric
    series (bake_higher_orders; needs orders >= 3). ``progress(stage, fraction)`` is called as
    stages advance.
    """
    params = (params or AtmosphereParams()).validate()
    res = resolve_resolution(resolution)
    orders = resolve_orders(params, orders)
    with tuned_for_bake():
        return _bake_stages(params, res, orders, progress or (lambda stage, fraction: None), tail)


def single_to_rgb(media, table: np.ndarray, parallel: bool = True) -> np.ndarray:
    """Single scattering's spectra to RGB (spectrum.spectra_to_rgb), on every core unless not
    ``parallel``; the Sample 2013 media's three wavelengths are the channels themselves."""
    if not media.wavelengths_nm:
        return table @ media.to_rgb.T.astype(np.float32)
    if not parallel:
        return spectra_to_rgb(table, media.wavelengths_nm)
    out = np.empty(table.shape[:-1] + (3,), np.float32)

    def convert(i):
        out[i] = spectra_to_rgb(table[i], media.wavelengths_nm)
    _parallel_rows(convert, len(table), lambda stage, fraction: None, "colour conversion")
    return out


def _bake_stages(params: AtmosphereParams, res: Resolution, orders, report: Progress, tail: bool) -> Luts:
    timings = {}

    t0 = time.perf_counter()
    optical_depth = bake_optical_depth(params, *res.optical_depth, progress=report)
    timings["optical depth"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    media = bake_media(params)
    single_rayleigh, single_mie, single_fog = bake_single(params, media, res.scattering, optical_depth, report)
    timings["single scattering"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    orders_used = 1
    if orders == CONVERGED or orders >= 2:
        higher, order_times, orders_used = bake_higher_orders(
            params, bake_media(params, "higher"), res.scattering, single_rayleigh, single_mie, orders, report,
            optical_depth, single_media=media, tail=tail, single_fog=single_fog)
        timings.update(order_times)
    else:
        higher = np.zeros(res.scattering + (3,), np.float32)
    timings["higher orders (total)"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    # Bilinear cell arithmetic leaves values of ~1e-20 below zero where radiance is zero; the
    # colour conversion's negative lobes can do the same to a near-black spectrum.
    scale = par.grid_scale(params, res.scattering).astype(np.float32)
    single, single_mie, single_fog = (None if table is None else np.maximum(single_to_rgb(media, table), 0.0) / scale
                                      for table in (single_rayleigh, single_mie, single_fog))
    higher = np.maximum(higher, 0.0)
    timings["colour conversion"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    luts = Luts(params, single, higher, optical_depth, np.zeros((res.ambient, 3), np.float32),
                single_mie=single_mie, single_fog=single_fog, orders=orders, orders_used=orders_used,
                timings=timings, tail=bool(tail and orders_used >= 3))
    luts.ambient = bake_ambient(luts, res.ambient, report)
    timings["ambient skylight"] = time.perf_counter() - t0
    report("ambient skylight", 1.0)
    problem = luts.value_problem()
    if problem:
        raise ValueError(f"these atmosphere parameters give unusable tables ({problem}); bring them closer to "
                         "Earth's (see lut_gen.model.atmosphere.PARAMETER_RANGES)")
    return luts
