"""Each scattering order's radiance L(n) on the order grid: J~ (sphere_integral) integrated along
every view ray, Yusov 2013 eq. (2). As for single scattering the integral is a product
integration: the fast-varying density x view transmittance goes into node weights once per grid
(view_rays), J~ / density is read only at HIGHER_NODES nodes per ray, blended geometrically
along the sun zenith."""
from __future__ import annotations

from typing import Optional

import numpy as np

from . import parameterization as par
from ..model.atmosphere import AtmosphereParams, rayleigh_phase
from ..model.spectrum import Media
from .bake_parallel import Progress, parallel_rows, ray_batches
from .interpolation import ABSOLUTE_FLOOR, axis_weights, gather, geometric_lerp_of_logs
from .sun_depths import node_cos_sun
from .view_rays import view_ray_nodes

HIGHER_NODES = 24               # J nodes per view ray for orders >= 2
HIGHER_SUBSTEPS = 4
HIGHER_UNIFORM_SHARE = 0.2      # J / density falls fastest near the ground: cluster there


class OrderGeometry:
    """What the view-ray integral of every order (Yusov 2013 eq. (2)) needs that does not change from one
    order to the next, per work item of one grid, found by the first order and kept: the nodes
    along each view ray with their weights (media's scattering coefficients included) and where
    each node falls on the grid's height and view-zenith axes (``item``). Where its sun falls on
    the sun-zenith axis is found again each order (``sun_rows``)."""

    def __init__(self, params: AtmosphereParams, media: Media, dims_j):
        self.params, self.media, self.dims = params, media, dims_j
        n_h, n_a, n_s, n_t = dims_j
        self.axes = par.grid_axes(params, dims_j)
        channels = media.channels
        self.tasks = ray_batches(n_h, n_a, HIGHER_NODES * n_s * n_t * 2 * max(1, channels // 3))
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
        cos_node = node_cos_sun(r, nodes, self.axes[3], ct)                                   # (a, K, s, t)
        i_s, w_s = axis_weights(par.sun_zenith_to_x(cos_node, n_s), n_s)
        return base + i_s, w_s[..., None]


def integrate_order(params, media: Media, dims_j, j_table, progress: Progress, stage: str,
                     geometry: Optional[OrderGeometry] = None):
    """L(n) on the order grid from J~ (Yusov 2013 eq. (2)), product-integrated along each view ray.
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

    parallel_rows(fill, len(geometry.tasks), progress, stage)
    return out
