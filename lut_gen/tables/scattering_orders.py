"""The scattering orders 2..N baked and summed into the "higher" table: each order scatters the
one before (sphere_integral's J~, Yusov 2013 eq. (1)) and integrates that along the view rays
(order_integral, Yusov 2013 eq. (2)); the orders after the last as a geometric tail, or orders
until they converge.

The orders are smooth, so they are computed on a grid with half the nodes along height, view
and sun zenith (higher_order_dims), the late ones on a coarser grid still (late_order_dims), and
resampled onto the full grid at the end."""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from typing import Optional, Tuple

import numpy as np

from . import parameterization as par
from .process_tuning import blas_on_one_thread
from ..model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase
from ..model.spectrum import Media, spectral_resample_matrix
from .bake_parallel import Progress, workers
from .ground import GroundSource
from .interpolation import resample_matrix, resample_separable, resample_sun_geometric
from .order_integral import OrderGeometry, integrate_order
from .sphere_integral import SPHERE_AZIMUTHS, phase_kernels, scattered_radiance, sphere_zenith_grid

MAX_ORDERS = 30                 # the most orders a bake integrates (also when converging)


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
    parts = [part for part in np.array_split(np.arange(n_t), min(n_t, workers())) if len(part)]

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
        j_table = scattered_radiance(params, dims_j, prev, mu, kernels, SPHERE_AZIMUTHS, prev_mie,
                                      None if ground is None else (ground, irradiance), prev_fog)
        if ground is not None and order < cap:
            irradiance = ground.sky_irradiance(prev, prev_mie, prev_fog)
        before = prev if prev_mie is None else None
        prev, prev_mie, prev_fog = integrate_order(params, media, dims_j, j_table, progress,
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

