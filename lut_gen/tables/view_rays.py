"""View rays of the bake: their nodes and the sun-independent weights of product integration
(lut_gen.tables.bake's module docstring). Along a ray the fast-varying density x view
transmittance is integrated on a fine grid into one weight per node and medium, so that
in-scattering is sum_k A_k f(node k) for a slowly varying sun factor f known only at the nodes
(sun transmittance for single scattering, J / density for the higher orders).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..model.atmosphere import AtmosphereParams
from ..model.geometry import clustered_nodes, radius_along, ray_length
from ..model.profiles import ozone_density
from ..model.spectrum import Media


def densities32(params, heights):
    """(..., 4) Rayleigh, Mie, ozone and fog densities in float32."""
    profiles = density_profiles(params, heights.astype(np.float32))
    zeros = np.zeros_like(profiles[1])
    return np.stack([zeros if p is None else p for p in profiles], axis=-1)


def density_profiles(params, heights):
    """Rayleigh, Mie, ozone and fog densities as separate contiguous float32 arrays (None for an
    ozone layer that is switched off and for no fog)."""
    heights = np.maximum(heights, np.float32(0.0))
    rayleigh = np.exp(heights * np.float32(-1.0 / params.rayleigh_scale_height))
    mie = np.exp(heights * np.float32(-1.0 / params.mie_scale_height))
    ozone = ozone_density(params, heights).astype(np.float32) if params.ozone else None
    fog = np.exp(heights * np.float32(-1.0 / params.fog_height)) if params.has_fog else None
    return rayleigh, mie, ozone, fog


@dataclass
class RayNodes:
    """Nodes along a batch of view rays and their sun-independent weights (node_basis)."""
    s: np.ndarray          # (rays, K) distance from the ray start
    radius: np.ndarray     # (rays, K) distance to the Earth centre
    weight_rayleigh: np.ndarray   # (rays, K, C) integral of rho_R * T_view * basis_k ds
    weight_mie: np.ndarray        # (rays, K, C) same with rho_M
    weight_fog: Optional[np.ndarray] = None   # same with rho_F (None without fog)

    def rays(self, which) -> "RayNodes":
        """The nodes of some of the rays (an index or slice of the first axis)."""
        return RayNodes(self.s[which], self.radius[which], self.weight_rayleigh[which], self.weight_mie[which],
                        None if self.weight_fog is None else self.weight_fog[which])


# Share of a view ray's nodes spread evenly over its fog column (the rest keep the clear sky's
# spacing): a fog 50 m thick fills the first few metres of an upward ray whose nodes are 1.5 km
# apart, and the fog's own scattering then came from one or two substeps.
FOG_NODE_SHARE = 0.5
FOG_PREGRID = 512               # samples of the fog column that place those nodes
FOG_NODE_MIN_DEPTH = 1e-3       # fog optical depth from which a ray gets the full share


def with_fog_nodes(params: AtmosphereParams, r, c, length, base):
    """Nodes (rays, K) that keep ``base``'s spacing for (1 - share) of their count and spread
    the rest evenly over the fog's opacity along each ray."""
    pre = clustered_nodes(r, c, length, FOG_PREGRID)                                     # (rays, P)
    heights = radius_along(r[:, None], c[:, None], pre) - params.earth_radius
    density = np.exp(-np.maximum(heights, 0.0) / params.fog_height)
    column = np.concatenate([np.zeros_like(pre[:, :1]),
                             np.cumsum(0.5 * (density[:, 1:] + density[:, :-1]) * np.diff(pre, axis=1), axis=1)], axis=1)
    total = column[:, -1]
    share = FOG_NODE_SHARE * np.minimum(total * params.fog / FOG_NODE_MIN_DEPTH, 1.0)
    # Even in the fog's opacity from the ray start, 1 - exp(-optical depth), not in its column:
    # the same where the fog is thin, and where it is thick the nodes stay where the light
    # seen comes from. Spread over the column, a horizontal ray 2 m up in a 1 km / 50 m fog
    # (a column of ~22 km, 88 optical depths) had its first node 1.8 km out, seven extinction
    # lengths, and the higher orders seen along it came out 20% too bright.
    opacity = -np.expm1(-params.fog * column)
    thick = opacity[:, -1] > 1e-9
    fog_measure = np.where(thick[:, None], opacity / np.where(thick, opacity[:, -1], 1.0)[:, None],
                           column / np.maximum(total, 1e-30)[:, None])
    t = np.linspace(0.0, 1.0, base.shape[1])
    nodes = np.empty_like(base)
    for ray in range(len(base)):
        clear_measure = np.interp(pre[ray], base[ray], t)
        measure = (1.0 - share[ray]) * clear_measure + share[ray] * fog_measure[ray]
        nodes[ray] = np.interp(t, measure, pre[ray])
    nodes[:, 0], nodes[:, -1] = 0.0, length
    return nodes


# Widest ratio of a node triple's two spacings that keeps its parabola (beyond it, or where two
# fog nodes coincide, the triple's intervals fall back to hat functions).
QUADRATIC_SPACING_RATIO = 8.0


def node_basis(s, tau, quadratic: bool):
    """(rays, K-1, M+1, 3) weights that interpolate a function known at the nodes s (rays, K)
    at the substeps tau (M+1,) of every interval, and (K-1,) the first node of each interval's
    triple. Hat functions are the trapezoid rule; with ``quadratic`` each interval takes the
    parabola through a triple of nodes (Simpson's rule on interval pairs, the last interval
    sharing its neighbour's parabola). A low sun's transmittance is convex along a view ray
    toward it, and linear between the 32 nodes read its single scattering 6-10% too bright at
    the tables' own nodes; the parabolas cost nothing per sun angle, since they do not depend
    on it."""
    n_rays, n_nodes = s.shape
    intervals = n_nodes - 1
    k = np.arange(intervals)
    # Every triple lies on the ray: the last interval is the second of its triple.
    start = np.where(k % 2 == 0, k, k - 1) if quadratic else k
    start = np.maximum(np.minimum(start, n_nodes - 3), 0)
    offset = k - start                                         # 0: interval (a, b), 1: (b, c)
    hat = np.zeros((intervals, len(tau), 3))
    hat[k, :, offset] = 1.0 - tau
    hat[k, :, offset + 1] = tau
    basis = np.broadcast_to(hat, (n_rays,) + hat.shape)
    if not (quadratic and n_nodes >= 3):
        return basis.astype(np.float32), start
    a, b, c = s[:, start], s[:, start + 1], s[:, start + 2]    # (rays, K-1)
    left, right = b - a, c - b
    narrow, wide = np.minimum(left, right), np.maximum(left, right)
    ok = narrow > wide / QUADRATIC_SPACING_RATIO
    x = s[:, :-1, None] + (s[:, 1:, None] - s[:, :-1, None]) * tau                    # (rays, K-1, M+1)
    a, b, c, left, right = (v[..., None] for v in (a, b, c, left, right))
    safe = lambda d: np.where(ok[..., None], d, 1.0)
    quad = np.stack([(x - b) * (x - c) / safe(left * (left + right)),
                     -(x - a) * (x - c) / safe(left * right),
                     (x - a) * (x - b) / safe(right * (left + right))], axis=-1)
    return np.where(ok[..., None, None], quad, basis).astype(np.float32), start


def view_ray_nodes(params: AtmosphereParams, media: Media, height: float, cos_view, above, n_nodes: int,
                   substeps: int, uniform_share: float, quadratic: bool = False) -> RayNodes:
    r = np.full(len(cos_view), params.earth_radius + height)
    c = np.asarray(cos_view, dtype=np.float64)
    length = ray_length(params, r, c, ~np.asarray(above))
    s = clustered_nodes(r, c, length, n_nodes, uniform_share)                 # (rays, K)
    fog = media.has_fog
    if fog:
        s = with_fog_nodes(params, r, c, length, s)
    tau = np.linspace(0.0, 1.0, substeps + 1)
    s_fine = s[:, :-1, None] + (s[:, 1:, None] - s[:, :-1, None]) * tau    # (rays, K-1, M+1)
    h_fine = radius_along(r[:, None, None], c[:, None, None], s_fine) - params.earth_radius
    media_used = 4 if fog else 3
    dens = densities32(params, h_fine)[..., :media_used]                   # (rays, K-1, M+1, media)
    sigma = dens @ media.extinction_matrix()[:media_used].astype(np.float32)     # extinction per channel
    ds = ((s[:, 1:] - s[:, :-1]) / substeps).astype(np.float32)[..., None, None]
    # Optical depth from the ray start: trapezoid inside each interval plus earlier intervals.
    inside = np.concatenate([np.zeros_like(sigma[:, :, :1]),
                             np.cumsum(0.5 * (sigma[:, :, 1:] + sigma[:, :, :-1]) * ds, axis=2)], axis=2)
    before = np.cumsum(inside[:, :, -1], axis=1) - inside[:, :, -1]
    view_trans = np.exp(-(inside + before[:, :, None, :]))
    trap = np.full(substeps + 1, 1.0, dtype=np.float32)
    trap[[0, -1]] = 0.5
    basis, start = node_basis(s, tau, quadratic)
    basis = basis * trap[:, None]
    # Each interval's triple onto the ray's nodes (a ray of two nodes has no third).
    onto_nodes = np.zeros((n_nodes - 1, 3, n_nodes), np.float32)
    for j in range(min(3, n_nodes)):
        onto_nodes[np.arange(n_nodes - 1), j, start + j] = 1.0
    onto_nodes = onto_nodes.reshape(-1, n_nodes)
    weights = []
    for medium in ((0, 1, 3) if fog else (0, 1)):
        g = dens[..., medium:medium + 1] * view_trans * ds                       # (rays, K-1, M+1, C)
        per_triple = np.matmul(g.transpose(0, 3, 1, 2)[..., None, :], basis[:, None, :, :, :])   # (rays, C, K-1, 1, 3)
        w = per_triple.reshape(len(r), media.channels, -1) @ onto_nodes                         # (rays, C, K)
        weights.append(np.ascontiguousarray(w.transpose(0, 2, 1)))
    return RayNodes(s, radius_along(r[:, None], c[:, None], s), *weights)
