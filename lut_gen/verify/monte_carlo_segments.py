"""Segments of the atmosphere's Monte Carlo path tracer (lut_gen.verify.monte_carlo): the optical
depth along rays, and where a path's next vertex falls on its segment.

The next vertex along a segment [0, D] (D: to the ground or to the top of the atmosphere) is
either the ground end, with probability q (the ground's share of the light carried on,
albedo x T(D) against 1 - T(D) with T averaged over the channels, at most 0.9; q = 0 for
segments that leave through the top or end on a black ground), or a collision in the air,
*forced* into [0, D]: a distance drawn from the truncated exponential of one channel's
optical depth, the channel picked at random (one-sample multiple importance sampling over the
three channels, balance heuristic, so the weights stay bounded where the channels' extinction
differs a lot). The weights T(s) / ((1 - q) pdf(s)) per channel carry absorption (Mie
absorption, ozone) exactly: scattering enters only through the scattering coefficients at
the vertices.

Optical depths are integrated numerically: every ray is cut at its lowest point (where the
density peaks), each side into intervals growing geometrically away from it, and every
interval gets Gauss-Legendre quadrature (the crossings of the ozone tent's kink heights are
nodes too, so every interval's integrand is smooth; with fog, so are the crossings of the
heights FOG_NODE_HEIGHTS fog scale heights above the ground, which resolve a fog of any scale
height). Collision distances are drawn from the
segment's optical depth taken as linear between nodes (piecewise constant extinction), with
that approximation's exact pdf, and weighted with the transmittance integrated up to the
distance drawn, so the approximation adds no bias. The quadrature's is ~1e-5: optical depths
are within ~1e-5 (relative) of reference.net_density_to_top.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.profiles import OZONE_HALF_WIDTH_M, OZONE_PEAK_HEIGHT_M
from .monte_carlo_media import _Media, _distance_to_top, _dot, _ground_hit, _norm

# Intervals on each side of a ray's lowest point, and Gauss-Legendre nodes per interval:
# segments need fine intervals (distances are drawn from their linear optical depth), sun
# rays only an accurate total.
SEGMENT_SIDE_INTERVALS = 48
SEGMENT_GAUSS_NODES = 2
SUN_SIDE_INTERVALS = 12
SUN_GAUSS_NODES = 4
# Cap on the probability of continuing a path on the ground instead of in the air.
MAX_GROUND_PROBABILITY = 0.9
# Length scale of the geometric interval growth: intervals start about this long at the
# lowest point, well under the Mie scale height, and grow by a constant factor from there.
FIRST_INTERVAL_M = 100.0
# With fog: extra nodes where rays cross these heights, in fog scale heights above the ground
# (the fog's density changes by at most e^0.5 between two of them below 6 scale heights, and
# e^-40 of it is left above the last).
FOG_NODE_HEIGHTS = (0.25, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 13.0, 17.0, 22.0, 30.0, 40.0)


# -- optical depth -----------------------------------------------------------------------------

def _side_offsets(length: np.ndarray, n: int) -> np.ndarray:
    """(N, n+1) distances from a ray's lowest point, 0 to ``length``, growing geometrically
    (ratio ~ exp(ln(1 + length / FIRST_INTERVAL_M) / n)): the density falls off roughly
    exponentially away from that point on every ray."""
    u = np.arange(n + 1, dtype=np.float64) / n
    a = np.log1p(length / FIRST_INTERVAL_M)[:, None]
    small = a < 1e-9
    a_safe = np.where(small, 1.0, a)
    frac = np.where(small, u, np.expm1(a_safe * u) / np.expm1(a_safe))
    return length[:, None] * frac


def _ozone_kinks(media: _Media, r, mu, length) -> np.ndarray:
    """(N, 6) distances where the rays cross the heights of the ozone profile's kinks, clamped
    into [0, length] (0 for crossings that do not exist): the tent is smooth between them."""
    out = []
    for height in (OZONE_PEAK_HEIGHT_M - OZONE_HALF_WIDTH_M, OZONE_PEAK_HEIGHT_M,
                   OZONE_PEAK_HEIGHT_M + OZONE_HALF_WIDTH_M):
        disc = r * r * (mu * mu - 1.0) + (media.earth_radius + height) ** 2
        root = np.sqrt(np.maximum(disc, 0.0))
        for sign in (-1.0, 1.0):
            out.append(np.where(disc > 0.0, np.clip(-r * mu + sign * root, 0.0, length), 0.0))
    return np.stack(out, axis=-1)


def _fog_crossings(media: _Media, r, mu, length) -> np.ndarray:
    """(N, 2 len(FOG_NODE_HEIGHTS)) distances where the rays cross the heights of
    FOG_NODE_HEIGHTS fog scale heights above the ground, clamped into [0, length] (0 where a
    crossing does not exist): nodes that resolve a fog layer of any scale height."""
    out = []
    rmu = r * mu
    for c in FOG_NODE_HEIGHTS:
        rc = media.earth_radius + c * media.params.fog_height
        disc = rmu * rmu + (rc - r) * (rc + r)
        root = np.sqrt(np.maximum(disc, 0.0))
        for sign in (-1.0, 1.0):
            out.append(np.where(disc > 0.0, np.clip(-rmu + sign * root, 0.0, length), 0.0))
    return np.stack(out, axis=-1)


def _ray_nodes(media: _Media, r, mu, length, n: int) -> np.ndarray:
    """(N, 2n+1) increasing distances along rays [0, length], clustered at the lowest point,
    plus the ozone kink crossings when there is ozone and the fog's height crossings with fog
    (intervals of length 0 are harmless)."""
    s_low = np.clip(-r * mu, 0.0, length)
    before = s_low[:, None] - _side_offsets(s_low, n)[:, ::-1]
    after = s_low[:, None] + _side_offsets(length - s_low, n)[:, 1:]
    nodes = np.concatenate([before, after], axis=1)
    if media.params.ozone:
        nodes = np.sort(np.concatenate([nodes, _ozone_kinks(media, r, mu, length)], axis=1), axis=1)
    if media.has_fog:
        nodes = np.sort(np.concatenate([nodes, _fog_crossings(media, r, mu, length)], axis=1), axis=1)
    return nodes


def _interval_net_densities(media: _Media, r, mu, nodes, gauss: int) -> np.ndarray:
    """(N, intervals, media): densities integrated over every interval between the nodes
    of rays from radius r with zenith cosine mu (Gauss-Legendre, ``gauss`` points), one per
    row of ``media.extinction``."""
    x, w = np.polynomial.legendre.leggauss(gauss)
    mid = 0.5 * (nodes[:, 1:] + nodes[:, :-1])
    half = 0.5 * (nodes[:, 1:] - nodes[:, :-1])
    s = mid[..., None] + half[..., None] * x
    rr = r[:, None, None]
    radius = np.sqrt(np.maximum(rr * rr + s * (s + 2.0 * (r * mu)[:, None, None]), 0.0))
    out = np.zeros(half.shape + (media.extinction.shape[0],))
    for m, density in enumerate(media.densities(radius)):
        if density is not None:
            out[..., m] = (density @ w) * half
    return out


def _sun_transmittance(media: _Media, points: np.ndarray, sun: np.ndarray) -> np.ndarray:
    """(N, 3) transmittance from the points to the top of the atmosphere along the sun
    direction; 0 where the Earth hides the sun."""
    r = np.clip(_norm(points), media.earth_radius, media.top_radius)
    mu = np.clip(points @ sun / r, -1.0, 1.0)
    blocked, _ = _ground_hit(media, r, mu)
    length = _distance_to_top(media, r, mu)
    nodes = _ray_nodes(media, r, mu, length, SUN_SIDE_INTERVALS)
    net = _interval_net_densities(media, r, mu, nodes, SUN_GAUSS_NODES).sum(axis=1)
    return np.where(blocked[:, None], 0.0, np.exp(-(net @ media.extinction)))


@dataclass
class _Segment:
    """A ray from ``origin`` along ``direction`` to the ground or the top of the atmosphere,
    with its optical depth per channel at the nodes (linear in between)."""

    origin: np.ndarray      # (N, 3)
    direction: np.ndarray   # (N, 3)
    r: np.ndarray           # (N,) radius of the origin
    mu: np.ndarray          # (N,) zenith cosine of the direction there
    hits_ground: np.ndarray  # (N,)
    nodes: np.ndarray       # (N, K) distances, nodes[:, -1] = length
    depth: np.ndarray       # (N, K, 3) optical depth per channel from the origin

    @property
    def transmittance(self) -> np.ndarray:
        """(N, 3) transmittance of the whole segment."""
        return np.exp(-self.depth[:, -1])


def _segment(media: _Media, origin: np.ndarray, direction: np.ndarray) -> _Segment:
    r = np.clip(_norm(origin), media.earth_radius, media.top_radius)
    mu = np.clip(_dot(origin, direction) / r, -1.0, 1.0)
    hits, to_ground = _ground_hit(media, r, mu)
    to_top = _distance_to_top(media, r, mu)
    length = np.where(hits, np.minimum(to_ground, to_top), to_top)
    nodes = _ray_nodes(media, r, mu, length, SEGMENT_SIDE_INTERVALS)
    per_interval = _interval_net_densities(media, r, mu, nodes, SEGMENT_GAUSS_NODES) @ media.extinction
    depth = np.concatenate([np.zeros_like(per_interval[:, :1]), np.cumsum(per_interval, axis=1)], axis=1)
    return _Segment(origin, direction, r, mu, hits, nodes, depth)


# -- sampling the next vertex ------------------------------------------------------------------

def _forced_collision(media: _Media, seg: _Segment, rng):
    """A distance in (0, length) for every ray, from the balance-heuristic mixture of the
    channels' truncated exponentials, and the weights T(s) / pdf(s) per channel ((N,), (N, 3)).

    The distances follow the segment's piecewise linear optical depth, but the weights use the
    transmittance integrated up to the very distance drawn: the approximation then costs a
    little variance and no bias (it was up to 0.15 % on long grazing rays)."""
    n = seg.nodes.shape[0]
    total = seg.depth[:, -1]                               # (N, 3)
    interacts = -np.expm1(-total)                          # 1 - T(D)
    usable = interacts > 1e-300
    count = usable.sum(axis=1)
    share = usable / np.maximum(count, 1)[:, None]         # channel choice probabilities
    channel = (rng.random(n)[:, None] > np.cumsum(share, axis=1)).sum(axis=1).clip(0, 2)
    rows = np.arange(n)
    target = -np.log1p(rng.random(n) * np.expm1(-total[rows, channel]))
    depth_c = seg.depth[rows, :, channel]                  # (N, K)
    k = (depth_c[:, 1:-1] <= target[:, None]).sum(axis=1)  # interval index
    d0, d1 = depth_c[rows, k], depth_c[rows, k + 1]
    frac = np.clip(np.divide(target - d0, d1 - d0, out=np.zeros(n), where=d1 > d0), 0.0, 1.0)
    s0, s1 = seg.nodes[rows, k], seg.nodes[rows, k + 1]
    s = s0 + frac * (s1 - s0)
    lo, hi = seg.depth[rows, k], seg.depth[rows, k + 1]    # (N, 3)
    depth_s = lo + frac[:, None] * (hi - lo)
    width = (s1 - s0)[:, None]
    extinction = np.divide(hi - lo, width, out=np.zeros_like(lo), where=width > 0.0)
    pdf = np.sum(share * extinction * np.exp(-depth_s) / np.where(usable, interacts, 1.0), axis=1)
    partial = _interval_net_densities(media, seg.r, seg.mu, np.stack([s0, s], axis=1), SEGMENT_GAUSS_NODES)
    transmittance = np.exp(-(lo + partial[:, 0] @ media.extinction))
    ok = (count > 0) & (pdf > 0.0)
    weight = np.where(ok[:, None], transmittance / np.where(ok, pdf, 1.0)[:, None], 0.0)
    return s, weight


def _ground_probability(media: _Media, seg: _Segment) -> np.ndarray:
    """(N,) probability of ending a segment on the ground rather than in the air: the ground
    branch's share of the light it carries on (albedo x T(D) against 1 - T(D), roughly), so
    that a black ground takes no paths; capped, so that the air is never starved."""
    t = seg.transmittance.mean(axis=1)
    ground = media.params.ground_albedo * t
    share = np.divide(ground, ground + (1.0 - t), out=np.zeros_like(t), where=ground > 0.0)
    return np.where(seg.hits_ground, np.minimum(share, MAX_GROUND_PROBABILITY), 0.0)


def _next_vertex(media: _Media, seg: _Segment, ground_prob: np.ndarray, rng):
    """Pick the ground end with probability ``ground_prob`` (0 where the segment does not end
    on the ground), else a forced collision. Returns points (N, 3), on_ground (N,) and the
    weight factors (N, 3)."""
    n = seg.nodes.shape[0]
    to_ground = rng.random(n) < ground_prob
    s, medium_weight = _forced_collision(media, seg, rng)
    length = seg.nodes[:, -1]
    dist = np.where(to_ground, length, s)
    points = seg.origin + dist[:, None] * seg.direction
    # Snap onto the shell [R, R + H]: the ground exactly, the others against rounding.
    r = _norm(points)
    target = np.where(to_ground, media.earth_radius, np.clip(r, media.earth_radius, media.top_radius))
    points *= (target / np.maximum(r, 1.0))[:, None]
    ground_weight = seg.transmittance / np.maximum(ground_prob, 1e-300)[:, None]
    medium_weight = medium_weight / np.maximum(1.0 - ground_prob, 1e-300)[:, None]
    return points, to_ground, np.where(to_ground[:, None], ground_weight, medium_weight)
