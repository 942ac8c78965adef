"""Single scattering baked (Yusov 2013 eq. (2) with the sun term, L1): for every view ray of the
4D table, the light scattered once toward the camera, with parabolas between the ray's nodes.
Rayleigh, Mie and the fog are kept apart without their phase functions, which the look-up
applies exactly (lut_gen.tables.lookup). The sun's transmittance at each node comes from the
optical-depth table (sun_depths); the density x view transmittance along the ray is
product-integrated into node weights (view_rays)."""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from . import parameterization as par
from ..model.atmosphere import AtmosphereParams
from ..model.spectrum import Media, spectra_to_rgb
from .bake_parallel import Progress, parallel_rows, ray_batches
from .interpolation import axis_weights, gather
from .optical_depth import below_first_row_factors, fog_column_scale
from .sun_depths import node_cos_sun, sun_depths, sun_near_horizon
from .view_rays import view_ray_nodes

SINGLE_NODES = 32               # sun-transmittance nodes per view ray
SINGLE_SUBSTEPS = 8             # fine steps per node interval for density x transmittance
NODE_UNIFORM_SHARE = 0.6        # keeps far, sunlit stretches of twilight rays sampled


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
    # node in the Earth's shadow (sun_near_horizon). Without one (no air) nothing scatters.
    opaque_medium = int(np.argmax(extinction.min(axis=1)))
    media_scatter = np.stack([media.rayleigh, media.mie] + ([media.fog] if fog else []), axis=-1).astype(np.float32)
    k_nodes = nodes or SINGLE_NODES
    channels = media.channels
    out_r = np.empty((n_h, n_a, n_s, n_t, channels), dtype=np.float32)
    out_m = np.empty((n_h, n_a, n_s, n_t, channels), dtype=np.float32)
    out_f = np.empty((n_h, n_a, n_s, n_t, channels), dtype=np.float32) if fog else None
    tasks = ray_batches(n_h, n_a, k_nodes * n_s * n_t * max(1, channels // 3))
    # The view rays' nodes, a height's rays at a time (2 rays a call spent 1.4 s of one core
    # in numpy's per-call overhead).
    nodes_at = [None] * n_h

    def find_nodes(i):
        nodes_at[i] = view_ray_nodes(params, media, heights[i], cos_view[i], above, k_nodes, SINGLE_SUBSTEPS,
                                     NODE_UNIFORM_SHARE, quadratic=True)
    parallel_rows(find_nodes, n_h, lambda stage, fraction: progress(stage, 0.0), "single scattering")

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
        cos_node = node_cos_sun(params.earth_radius + heights[i], nodes, cos_sun, ct)       # (a, K, s, t)
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
        sun_near_horizon(params, depths, sun_net, node_h, cos_node, cos_sun, nodes.s, n_odh, n_odc, opaque_medium)
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

    parallel_rows(fill, len(tasks), progress, "single scattering")
    return out_r, out_m, out_f


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
    parallel_rows(convert, len(table), lambda stage, fraction: None, "colour conversion")
    return out
