"""The camera's sky at twilight: single scattering integrated per frame for the camera's height
and the sun, as a correction to the 4D tables' look-up (Hillaire 2020's sky-view idea, used
here to mend the tables where they are weakest).

At a low sun the 4D tables' nodes are within 1-2% of the spectral reference, but between
nodes the radiance changes by factors of 10-100 (the Earth's shadow crosses the rays, the sun's
path grazes the ground): the look-up was 9-17% off (p99) with the sun from +5 to -6 deg, and
about 8x the table would be needed to bring that to 5% (docs/accuracy.md). Over one frame the
camera height and the sun are fixed, so the sky the camera sees is a 2D function of the view:
integrated on a 2D grid of views (single_scattering.bake_single's integrator, the bake's
wavelengths), it needs no interpolation across sun zenith, height or coarse sun-view nodes.

The grid: NODES_VIEW view zeniths split at the camera's horizon like Yusov 2013 eq. (5)
(parameterization.view_zenith_to_x), and NODES_AZIMUTH azimuths from the sun, evenly spaced
over [0, pi] (the sky is symmetric about the sun's vertical plane). It holds what the tables
miss, phase-free like them: exact minus looked up, for single Rayleigh, single Mie and (with
fog) single fog, so the sky group adds correction * phase to its look-up (addon/nodes/sky_view.py
is the twin of ``correction_at``). By day the correction is a fraction of a percent.

Image layout (``image_pixels``): NODES_AZIMUTH x NODES_VIEW tiles side by side, one per
medium (Rayleigh, Mie, fog), azimuth along x within a tile, view zenith along y, RGB + 1.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.spectrum import bake_media
from ..tables import parameterization as par
from ..tables.single_scattering import bake_single, single_to_rgb
from ..tables.sun_depths import sun_depths
from ..tables.interpolation import interpolate
from ..tables.lookup import Luts, with_phases

NODES_VIEW = 256
NODES_AZIMUTH = 64
# Nodes per view ray, twice the bake's: the camera's grazing rays toward a sun under its
# horizon run hundreds of km (from 640 m, 0.55 deg down, 0.4 deg under the sun: 23% off with
# 32, 3% with 64; 96 and 128 gain nothing more).
RAY_NODES = 64
MEDIA = ("single", "single_mie", "single_fog")


@dataclass(frozen=True)
class SkyView:
    """The correction for one camera height and sun zenith: (n_a, n_t, 3) per medium."""

    height_m: float
    cos_sun_zenith: float
    tiles: tuple            # (rayleigh, mie[, fog]) (n_a, n_t, 3) float32

    @property
    def shape(self):
        return self.tiles[0].shape[:2]


def view_grid(params, height_m: float, n_a: int = NODES_VIEW, n_t: int = NODES_AZIMUTH):
    """(cos view zenith (n_a,), above-horizon flags (n_a,), azimuths from the sun (n_t,))."""
    cos_view, above = par.x_to_view_zenith(np.arange(n_a), height_m, n_a, params.earth_radius)
    return np.asarray(cos_view, np.float64), np.asarray(above), np.linspace(0.0, math.pi, n_t)


def cos_sun_view(cos_view, cos_sun, azimuth):
    sin_view = np.sqrt(np.clip(1.0 - np.square(cos_view), 0.0, 1.0))
    sin_sun = math.sqrt(max(1.0 - cos_sun * cos_sun, 0.0))
    return np.clip(cos_view * cos_sun + sin_view * sin_sun * np.cos(azimuth), -1.0, 1.0)


_kept = {}


def _depths(params, optical_depth, media_used):
    """sun_depths.sun_depths of the last optical-depth table seen (half of a sun move's time
    otherwise): kept while it is the same array."""
    kept = _kept.get("depths")
    if kept is None or kept[0] is not optical_depth or kept[1] != (params, media_used):
        kept = _kept["depths"] = (optical_depth, (params, media_used), sun_depths(params, optical_depth, media_used, band=True))
    return kept[2]


def exact_single(luts: Luts, height_m: float, cos_sun: float, grid):
    """Single scattering on ``grid`` (view_grid at ``height_m``), phase-free per medium,
    (n_a, n_t, 3) each: the bake's integrator on the camera's own rays."""
    params = luts.params
    h = float(np.clip(height_m, 0.0, params.atmosphere_height))
    cos_view, above, azimuth = grid
    n_a, n_t = len(cos_view), len(azimuth)
    c_s = float(np.clip(cos_sun, -1.0, 1.0))

    def sun_view(i, rays):
        return cos_sun_view(cos_view[rays, None, None], c_s, azimuth[None, None, :])
    media = bake_media(params)
    axes = (np.array([h]), cos_view[None, :], above, np.array([c_s]), sun_view)
    tables = bake_single(params, media, (1, n_a, 1, n_t), luts.optical_depth, lambda stage, fraction: None, axes=axes,
                         depths=_depths(params, luts.optical_depth, 4 if media.has_fog else 3), nodes=RAY_NODES)
    return tuple(None if t is None else np.maximum(single_to_rgb(media, t, parallel=False), 0.0)[0, :, 0]
                 for t in tables)


def compute(luts: Luts, height_m: float, cos_sun: float, n_a: int = NODES_VIEW, n_t: int = NODES_AZIMUTH) -> SkyView:
    """The correction: exact single scattering minus the tables' look-up on the grid."""
    params = luts.params
    h = float(np.clip(height_m, 0.0, params.atmosphere_height))
    grid = view_grid(params, h, n_a, n_t)
    exact = exact_single(luts, h, cos_sun, grid)
    cos_view, above, azimuth = grid
    ca = cos_view[:, None]
    ct = cos_sun_view(ca, float(cos_sun), azimuth[None, :])
    names = MEDIA if params.has_fog else MEDIA[:2]
    looked_up = luts.sky_radiance(h, ca, float(cos_sun), ct, table=names, above_horizon=above[:, None],
                                  phase_free=True)
    return SkyView(h, float(cos_sun), tuple((e - l).astype(np.float32) for e, l in zip(exact, looked_up)))


def grid_coordinates(params, view: SkyView, cos_view, cos_sun_view_):
    """Texel coordinates (x_a, x_t) and the horizon flags of views with these cosines."""
    n_a, n_t = view.shape
    x_a, above = par.view_zenith_to_x(cos_view, view.height_m, n_a, params.earth_radius)
    cs = view.cos_sun_zenith
    sin_prod = np.sqrt(np.clip(1.0 - np.square(cos_view), 0.0, 1.0) * max(1.0 - cs * cs, 0.0))
    cos_azimuth = np.clip((cos_sun_view_ - cos_view * cs) / np.maximum(sin_prod, 1e-9), -1.0, 1.0)
    x_t = np.arccos(cos_azimuth) / math.pi * (n_t - 1)
    return x_a, x_t, above


def correction_at(params, view: SkyView, cos_view, cos_sun_view_) -> np.ndarray:
    """(..., 3) radiance the look-up at these views misses, phases applied: the twin of
    addon/nodes/sky_view.py. The view axis stays on the view's side of the horizon."""
    cos_view = np.asarray(cos_view, np.float64)
    cos_sun_view_ = par.clamp_sun_view(cos_view, view.cos_sun_zenith, cos_sun_view_)
    x_a, x_t, above = grid_coordinates(params, view, cos_view, cos_sun_view_)
    half = view.shape[0] // 2
    x_a = np.where(above, np.maximum(x_a, half), np.minimum(x_a, half - 1))
    parts = [interpolate(tile, (x_a, x_t)) for tile in view.tiles]
    return with_phases(params, parts[0], parts[1], cos_sun_view_, parts[2] if len(parts) > 2 else None)


def image_pixels(view: SkyView) -> np.ndarray:
    """(n_a, n_t * 3, 4) float32 RGBA rows bottom to top: the tiles side by side (the fog's
    zero without fog, so the node group is the same for every bake)."""
    n_a, n_t = view.shape
    out = np.zeros((n_a, n_t * len(MEDIA), 4), np.float32)
    out[..., 3] = 1.0
    for k, tile in enumerate(view.tiles):
        out[:, k * n_t:(k + 1) * n_t, :3] = tile
    return out


def camera_sky(luts: Luts, view: SkyView, cos_view, cos_sun_view_, table: str = "multiple") -> np.ndarray:
    """(..., 3) the sky the camera sees (the "OLS Sky" group's twin): the 4D look-up of
    ``table`` at the view's height and sun plus the correction."""
    looked_up = luts.sky_radiance(view.height_m, cos_view, view.cos_sun_zenith, cos_sun_view_, table=table)
    return looked_up + correction_at(luts.params, view, cos_view, cos_sun_view_)
