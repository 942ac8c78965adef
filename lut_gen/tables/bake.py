"""The bake: every table of one AtmosphereParams, stage by stage (Yusov 2013, "Multiple
Scattering"). This module holds the orchestration; each stage, a pure function of
AtmosphereParams, has its own module beside it:

  optical depth   optical_depth_bake: net Rayleigh/Mie/ozone/fog density from (height, cos
                  zenith) to the top
  single          single_scattering: L1, Yusov 2013 eq. (2) with the sun term, parabolas between
                  view-ray nodes, Rayleigh and Mie kept apart without their phase functions
                  (applied exactly at look-up); the sun's net densities at the nodes from
                  sun_depths
  orders 2..N     scattering_orders: J(n) = sphere integral of L(n-1) against the phase functions
                  (Yusov 2013 eq. (1), sphere_integral), L(n) = its integral along the view ray
                  (Yusov 2013 eq. (2), order_integral); summed into "higher"
  ambient         ambient_table: E_sky, Yusov 2013 eq. (3), over the upper hemisphere at 20 m

A fog, where the params have one, is a medium of every stage rather than a stage of its own: a
fourth column of the optical-depth table, its own single-scattering table, a third phase kernel
in the orders. The stages share the cores through bake_parallel.

Spectral params are integrated at the wavelengths of lut_gen.model.spectrum (every stage works on C
channels at once: the optical-depth table holds net densities, which do not depend on
wavelength) and converted to linear Rec.709 at the end.

Two ideas keep this fast in numpy without giving up accuracy:

* Product integration along view rays. The integrand of Yusov 2013 eqs. (1)-(2) is (density x
  view transmittance), which varies fast and does not depend on the sun, times a slowly varying
  sun factor (sun transmittance for L1, J / density for higher orders). The first is integrated
  per ray on a fine grid into node weights A_k (lut_gen.tables.view_rays); the second is evaluated only at a few
  nodes k per ray and per sun configuration: L = sum_k A_k * f(node k).
* The sphere integral of Yusov 2013 eq. (1) for fixed height and sun zenith is a convolution in
  azimuth with the phase function, done with real FFTs over a fixed direction grid; the discrete
  kernel is normalised so that a constant radiance integrates exactly.

Higher orders are smooth, so they are computed on a grid with half the nodes along height,
view and sun zenith and resampled onto the full grid at the end.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Optional, Sequence, Tuple, Union

import numpy as np

from .process_tuning import tuned_for_bake
from . import parameterization as par
from ..model.atmosphere import AtmosphereParams
from ..model.spectrum import bake_media
from .ambient_table import bake_ambient
from .bake_parallel import Progress
from .lookup import Luts
from .optical_depth_bake import bake_optical_depth
from .scattering_orders import CONVERGED, MAX_ORDERS, bake_higher_orders
from .single_scattering import bake_single, single_to_rgb


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


CLEAR_SKY_ORDERS = 4            # the orders of a bake without fog (resolve_orders)


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
    series (scattering_orders.bake_higher_orders; needs orders >= 3). ``progress(stage, fraction)`` is called as
    stages advance.
    """
    return bake_validated((params or AtmosphereParams()).validate(), resolution=resolution, orders=orders,
                          progress=progress, tail=tail)


def bake_validated(params: AtmosphereParams, *, resolution="default", orders=None,
                   progress: Optional[Progress] = None, tail: bool = True) -> Luts:
    """``bake`` for parameters already validated where they entered (the store, the add-on):
    they are handed down as they are, not checked again."""
    res = resolve_resolution(resolution)
    orders = resolve_orders(params, orders)
    with tuned_for_bake():
        return _bake_stages(params, res, orders, progress or (lambda stage, fraction: None), tail)


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
