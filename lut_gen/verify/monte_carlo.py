"""Monte Carlo path tracer of the atmosphere: an independent reference for multiple scattering.

``radiance_by_order`` estimates the radiance reaching a viewer, per unit extraterrestrial sun
irradiance (the unit of ``lut_gen.verify.reference.single_scattering``), split by scattering order.
It shares no code with the baker (lut_gen.bake, sampling, ground): only the media definitions
of lut_gen.model.atmosphere (densities, phase functions). Everything is float64 numpy, vectorised over
the paths of a batch.

Orders
------
The order of a light path is the number of events on it: scatterings in the atmosphere plus
reflections off the ground, the ground point the view ray itself ends on included. The result
holds two parts by the *last* event before the light reaches the viewer:

* ``atmosphere[n-1]``: order-n light last scattered in the atmosphere (``atmosphere[0]`` is
  single scattering, ``atmosphere[1:]`` the higher orders; ground reflections earlier on the
  path count as events).
* ``ground[n-1]``: order-n light reflected by the ground point the view ray ends on, as seen
  through the atmosphere (``ground[0]``: the directly sunlit ground); 0 for views that miss
  the ground.

Estimator
---------
Paths start at the viewer along the view direction; vertex k of a path (k = 1, 2, ...) is its
k-th event, and next-event estimation towards the sun there gives its order-k contribution:
phase function x scattering coefficient x sun transmittance at an atmospheric vertex,
albedo / pi x cos(sun zenith) x sun transmittance at a ground vertex (0 where the Earth
hides the sun). The path continues from the vertex along a direction drawn from the phase
functions (a Rayleigh / Mie mixture by the two media's share of the scattering there, summed
over the channels; each channel's weight then corrects for its own share) or, on the ground,
a cosine-weighted direction.

The next vertex along a segment [0, D] (D: to the ground or to the top of the atmosphere) is
either the ground end, with probability q (the ground's share of the light carried on,
albedo x T(D) against 1 - T(D) with T averaged over the channels, at most 0.9; q = 0 for
segments that leave through the top or end on a black ground), or a collision in the air,
*forced* into [0, D]: a distance drawn from the truncated exponential of one channel's
optical depth, the channel picked at random (one-sample multiple importance sampling over the
three channels, balance heuristic, so the weights stay bounded where the channels' extinction
differs a lot). The weights T(s) / ((1 - q) pdf(s)) per channel carry absorption (Mie
absorption, ozone) exactly: scattering enters only through the scattering coefficients at
the vertices. Forced collisions mean no path leaves the atmosphere early; paths end after
``orders`` vertices. The view ray's first vertex is split deterministically: one population
of paths is forced into the atmosphere (the ``atmosphere`` part), a second one starts on the
ground point the view ray hits (the ``ground`` part).

Fog (``params.has_fog``): a fourth medium, grey, that only scatters (scattering = extinction =
params.fog x exp(-h / fog_height)) with its own Cornette-Shanks phase function (fog_g). A
collision scatters off Rayleigh, Mie or fog in proportion to their channel-summed scattering
coefficients there (the fog's direction drawn with the Mie sampler at fog_g; the weight is the
three media's kernel over the mixture pdf), and next-event estimation sums the three phase
terms. Without fog every array and random draw is what it was before the fog, bit for bit.

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

Standard errors and the covariances between orders come from the per-path contributions (each
path contributes to every order, so the orders' errors are correlated). At the default 16 384
paths, 4 orders take ~2 s per view (twice that for views of the ground, with its own paths)
on one core, with standard errors of ~0.1-1 % for single scattering, ~1-2.5 % for order 2 and
~3-6 % for order 4.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.profiles import (OZONE_HALF_WIDTH_M, OZONE_PEAK_HEIGHT_M, fog_density, mie_density, ozone_density,
                              rayleigh_density)
from ..model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase

__all__ = ["OrderRadiance", "radiance_by_order", "irradiance_by_order", "DEFAULT_PATHS"]

DEFAULT_PATHS = 16_384
# Paths traced together; bounds the work arrays to a few tens of MB.
BATCH_PATHS = 2048
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


@dataclass(frozen=True)
class OrderRadiance:
    """Radiance by order (see the module docstring): arrays (orders, 3), per unit sun, and the
    covariances (orders, orders, 3) of the estimates between orders, per channel (the orders
    of one path are correlated: sums of orders need the whole matrix, ``atmosphere_sum``)."""

    atmosphere: np.ndarray
    ground: np.ndarray
    atmosphere_cov: np.ndarray
    ground_cov: np.ndarray
    paths: int

    @property
    def atmosphere_se(self) -> np.ndarray:
        """(orders, 3) standard errors of ``atmosphere``."""
        return np.sqrt(np.maximum(np.diagonal(self.atmosphere_cov).T, 0.0))

    @property
    def ground_se(self) -> np.ndarray:
        """(orders, 3) standard errors of ``ground``."""
        return np.sqrt(np.maximum(np.diagonal(self.ground_cov).T, 0.0))

    def atmosphere_sum(self, start: int = 0, stop=None):
        """((3,), (3,)): ``atmosphere[start:stop].sum(0)`` and its standard error."""
        sl = slice(start, stop)
        cov = self.atmosphere_cov[sl, sl]
        return self.atmosphere[sl].sum(axis=0), np.sqrt(np.maximum(cov.sum(axis=(0, 1)), 0.0))

    @property
    def total(self) -> np.ndarray:
        """(3,) atmosphere + ground, all orders."""
        return self.atmosphere.sum(axis=0) + self.ground.sum(axis=0)


@dataclass(frozen=True)
class _Media:
    """Three-channel coefficients of the media (1/m at unit density)."""

    params: AtmosphereParams
    rayleigh: np.ndarray     # (3,) scattering = extinction
    mie: np.ndarray          # (3,) scattering
    extinction: np.ndarray   # (media: Rayleigh, Mie, ozone and, with fog only, fog; 3 channels)
    fog: np.ndarray          # (3,) fog scattering = extinction (grey; 0 without fog)

    @classmethod
    def of(cls, params: AtmosphereParams) -> "_Media":
        rayleigh = np.asarray(params.rayleigh_scattering, dtype=np.float64)
        mie = np.asarray(params.mie_scattering, dtype=np.float64) * params.aerosol_density
        ozone = np.asarray(params.ozone_absorption, dtype=np.float64) * (1.0 if params.ozone else 0.0)
        fog = np.full(3, params.fog if params.has_fog else 0.0)
        rows = [rayleigh, mie * (1.0 + params.aerosol_absorption), ozone] + ([fog] if params.has_fog else [])
        return cls(params, rayleigh, mie, np.stack(rows), fog)

    @property
    def has_fog(self) -> bool:
        return bool(self.params.has_fog)

    @property
    def earth_radius(self) -> float:
        return self.params.earth_radius

    @property
    def top_radius(self) -> float:
        return self.params.top_radius

    def densities(self, radius: np.ndarray):
        """Rayleigh, Mie, ozone and (with fog only) fog densities at the given radii, one per row
        of ``extinction`` (ozone None without ozone)."""
        h = np.maximum(radius - self.earth_radius, 0.0)
        ozone = ozone_density(self.params, h) if self.params.ozone else None
        out = (rayleigh_density(self.params, h), mie_density(self.params, h), ozone)
        return out + (fog_density(self.params, h),) if self.has_fog else out

    def scattering(self, radius: np.ndarray):
        """(N, 3) Rayleigh, (N, 3) Mie and (N, 3) fog scattering coefficients per channel at the
        radii (the fog's None without fog)."""
        h = np.maximum(radius - self.earth_radius, 0.0)
        fog = fog_density(self.params, h)[:, None] * self.fog if self.has_fog else None
        return (rayleigh_density(self.params, h)[:, None] * self.rayleigh,
                mie_density(self.params, h)[:, None] * self.mie, fog)


# -- geometry ----------------------------------------------------------------------------------

def _norm(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ni,ni->n", x, x))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ni,ni->n", a, b)


def _distance_to_top(media: _Media, r, mu):
    disc = r * r * (mu * mu - 1.0) + media.top_radius ** 2
    return np.maximum(-r * mu + np.sqrt(np.maximum(disc, 0.0)), 0.0)


def _ground_hit(media: _Media, r, mu):
    """(hits, distance): whether the ray meets the Earth in front (tangent rays do not), and
    the distance to it, in a form without cancellation for grazing rays near the ground."""
    big_r = media.earth_radius
    rise = np.maximum(r * r - big_r * big_r, 0.0)
    hits = mu < -np.sqrt(rise) / r
    root = np.sqrt(np.maximum(r * r * mu * mu - rise, 0.0))
    denominator = -r * mu + root
    distance = np.divide(rise, denominator, out=np.zeros_like(r), where=denominator > 0.0)
    return hits, distance


def _onb(z: np.ndarray):
    """Two unit vectors completing the unit vectors z (N, 3) to orthonormal frames
    (Duff et al. 2017, branchless)."""
    sign = np.where(z[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z[:, 2])
    b = z[:, 0] * z[:, 1] * a
    e1 = np.stack([1.0 + sign * z[:, 0] ** 2 * a, sign * b, -sign * z[:, 0]], axis=-1)
    e2 = np.stack([b, sign + z[:, 1] ** 2 * a, -z[:, 1]], axis=-1)
    return e1, e2


def _around(axis: np.ndarray, cos_theta: np.ndarray, rng) -> np.ndarray:
    """Unit vectors at the given angle to ``axis`` (N, 3), uniform in azimuth."""
    e1, e2 = _onb(axis)
    phi = 2.0 * math.pi * rng.random(axis.shape[0])
    sin_theta = np.sqrt(np.maximum(1.0 - cos_theta * cos_theta, 0.0))
    return (cos_theta[:, None] * axis
            + (sin_theta * np.cos(phi))[:, None] * e1 + (sin_theta * np.sin(phi))[:, None] * e2)


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


# -- events ------------------------------------------------------------------------------------

def _sample_rayleigh_cos(rng, n: int) -> np.ndarray:
    """cos theta with density proportional to 1 + cos^2: the root of c^3 + 3c + 4 - 8 xi = 0."""
    q = 4.0 - 8.0 * rng.random(n)
    a = np.cbrt(-0.5 * q + np.sqrt(0.25 * q * q + 1.0))
    return a - 1.0 / a


def _sample_mie_cos(rng, n: int, g: float) -> np.ndarray:
    """cos theta from the Cornette-Shanks phase function: Henyey-Greenstein proposals
    accepted with probability (1 + cos^2) / 2 (CS = HG x 3 (1 + cos^2) / (2 (2 + g^2)))."""
    out = np.empty(n)
    todo = np.arange(n)
    while todo.size:
        xi = rng.random(todo.size)
        if abs(g) < 1e-6:
            c = 2.0 * xi - 1.0
        else:
            t = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi)
            c = np.clip((1.0 + g * g - t * t) / (2.0 * g), -1.0, 1.0)
        accept = rng.random(todo.size) < 0.5 * (1.0 + c * c)
        out[todo[accept]] = c[accept]
        todo = todo[~accept]
    return out


def _scatter_with_fog(media: _Media, points, direction, rng):
    """``_scatter_atmosphere`` with the fog: Rayleigh, Mie or fog picked by their channel-summed
    share of the scattering at the point, the fog's Cornette-Shanks phase (fog_g) drawn with the
    Mie sampler; the proposal pdf is the mixture of the three phase functions."""
    n = points.shape[0]
    beta_r, beta_m, beta_f = media.scattering(_norm(points))
    shares = np.stack([beta_r.sum(axis=1), beta_m.sum(axis=1), beta_f.sum(axis=1)], axis=1)
    total = shares.sum(axis=1, keepdims=True)
    shares = np.where(total > 0.0, shares / np.where(total > 0.0, total, 1.0), np.array([1.0, 0.0, 0.0]))
    pick = (rng.random(n)[:, None] > np.cumsum(shares, axis=1)).sum(axis=1).clip(0, 2)
    cos_theta = np.empty(n)
    g_mie, g_fog = media.params.mie_g, media.params.fog_g
    for k, sampler in enumerate((lambda m: _sample_rayleigh_cos(rng, m), lambda m: _sample_mie_cos(rng, m, g_mie),
                                 lambda m: _sample_mie_cos(rng, m, g_fog))):
        mask = pick == k
        if mask.any():
            cos_theta[mask] = sampler(int(mask.sum()))
    phase_r, phase_m, phase_f = rayleigh_phase(cos_theta), mie_phase(cos_theta, g_mie), mie_phase(cos_theta, g_fog)
    pdf = shares[:, 0] * phase_r + shares[:, 1] * phase_m + shares[:, 2] * phase_f
    kernel = beta_r * phase_r[:, None] + beta_m * phase_m[:, None] + beta_f * phase_f[:, None]
    return _around(direction, cos_theta, rng), kernel / pdf[:, None]


def _scatter_atmosphere(media: _Media, points, direction, rng):
    """New directions at atmospheric vertices and the weight factors (N, 3): the scattering
    coefficient x phase function of every channel over the channel-free proposal pdf."""
    if media.has_fog:
        return _scatter_with_fog(media, points, direction, rng)
    n = points.shape[0]
    beta_r, beta_m, _ = media.scattering(_norm(points))
    total_r, total_m = beta_r.sum(axis=1), beta_m.sum(axis=1)
    p_rayleigh = np.divide(total_r, total_r + total_m, out=np.ones(n), where=total_r + total_m > 0.0)
    use_rayleigh = rng.random(n) < p_rayleigh
    cos_theta = np.empty(n)
    cos_theta[use_rayleigh] = _sample_rayleigh_cos(rng, int(use_rayleigh.sum()))
    cos_theta[~use_rayleigh] = _sample_mie_cos(rng, int((~use_rayleigh).sum()), media.params.mie_g)
    phase_r = rayleigh_phase(cos_theta)
    phase_m = mie_phase(cos_theta, media.params.mie_g)
    pdf = p_rayleigh * phase_r + (1.0 - p_rayleigh) * phase_m
    kernel = beta_r * phase_r[:, None] + beta_m * phase_m[:, None]
    return _around(direction, cos_theta, rng), kernel / pdf[:, None]


def _scatter_ground(media: _Media, points, rng):
    """Cosine-weighted directions about the ground normal; the Lambertian weight is the albedo."""
    normal = points / _norm(points)[:, None]
    cos_theta = np.sqrt(rng.random(points.shape[0]))
    return _around(normal, cos_theta, rng), np.full((points.shape[0], 3), media.params.ground_albedo)


def _sun_events(media: _Media, points, direction, on_ground, sun) -> np.ndarray:
    """(N, 3) radiance towards the previous vertex per unit path weight, from the sun alone."""
    t_sun = _sun_transmittance(media, points, sun)
    beta_r, beta_m, beta_f = media.scattering(_norm(points))
    nu = np.clip(direction @ sun, -1.0, 1.0)
    in_air = beta_r * rayleigh_phase(nu)[:, None] + beta_m * mie_phase(nu, media.params.mie_g)[:, None]
    if beta_f is not None:
        in_air = in_air + beta_f * mie_phase(nu, media.params.fog_g)[:, None]
    cos_sun = np.maximum(points @ sun / _norm(points), 0.0)
    on_earth = (media.params.ground_albedo / math.pi * cos_sun)[:, None]
    return np.where(on_ground[:, None], on_earth, in_air) * t_sun


# -- paths -------------------------------------------------------------------------------------

def _trace(media: _Media, camera, view, sun, ground_first: bool, orders: int, n: int, rng) -> np.ndarray:
    """(n, orders, 3) contributions of n paths from the viewer. ``ground_first``: the first
    vertex is the ground point the view ray hits (weight T(view ray)); else a forced
    collision on the view ray. ``view``: one direction (3,) for every path, or one per path
    (n, 3)."""
    out = np.zeros((n, orders, 3))
    ids = np.arange(n)
    if view.ndim == 2:
        seg = _segment(media, np.repeat(camera[None], n, axis=0), view)
    else:
        # Every path starts on the same view ray: integrate it once.
        ray = _segment(media, camera[None], view[None])
        seg = _Segment(*(np.repeat(a, n, axis=0) for a in (ray.origin, ray.direction, ray.r, ray.mu,
                                                           ray.hits_ground, ray.nodes, ray.depth)))
    direction = seg.direction
    first_prob = np.where(seg.hits_ground, 1.0, 0.0) if ground_first else np.zeros(n)
    points, on_ground, weight = _next_vertex(media, seg, first_prob, rng)
    if ground_first:
        weight[~seg.hits_ground] = 0.0
    for k in range(orders):
        alive = np.any(weight > 0.0, axis=1)
        ids, points, direction, on_ground, weight = (a[alive] for a in (ids, points, direction, on_ground, weight))
        if ids.size == 0:
            break
        out[ids, k] = weight * _sun_events(media, points, direction, on_ground, sun)
        if k == orders - 1:
            break
        new_dir = np.empty_like(direction)
        factor = np.empty_like(weight)
        air = ~on_ground
        new_dir[air], factor[air] = _scatter_atmosphere(media, points[air], direction[air], rng)
        new_dir[on_ground], factor[on_ground] = _scatter_ground(media, points[on_ground], rng)
        seg = _segment(media, points, new_dir)
        ground_prob = _ground_probability(media, seg)
        points, on_ground, step = _next_vertex(media, seg, ground_prob, rng)
        direction = new_dir
        weight = weight * factor * step
    return out


def _view_geometry(params: AtmosphereParams, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view):
    """Viewer position, view and sun unit vectors (the viewer on the z axis, the view in the xz
    plane); the sun-view cosine is clamped into the range the zenith cosines allow."""
    h = float(np.clip(height_m, 0.0, params.atmosphere_height))
    mu_v = float(np.clip(cos_view_zenith, -1.0, 1.0))
    mu_s = float(np.clip(cos_sun_zenith, -1.0, 1.0))
    sin_v = math.sqrt(max(1.0 - mu_v * mu_v, 0.0))
    sin_s = math.sqrt(max(1.0 - mu_s * mu_s, 0.0))
    if sin_v * sin_s > 1e-12:
        cos_phi = float(np.clip((cos_sun_view - mu_v * mu_s) / (sin_v * sin_s), -1.0, 1.0))
    else:
        cos_phi = 1.0
    sin_phi = math.sqrt(max(1.0 - cos_phi * cos_phi, 0.0))
    camera = np.array([0.0, 0.0, params.earth_radius + h])
    view = np.array([sin_v, 0.0, mu_v])
    sun = np.array([sin_s * cos_phi, sin_s * sin_phi, mu_s])
    return camera, view, sun


def _mean_and_cov(total: np.ndarray, cross: np.ndarray, n: int):
    """Mean (orders, 3) and covariance of the mean (orders, orders, 3) of n path samples from
    their sum and the sum of their outer products (per channel)."""
    mean = total / n
    cov = (cross / n - mean[:, None] * mean[None, :]) / max(n - 1, 1)
    return mean, cov


def radiance_by_order(params: AtmosphereParams, height_m: float, cos_view_zenith: float,
                      cos_sun_zenith: float, cos_sun_view: float, orders: int = 4,
                      paths: int = DEFAULT_PATHS, seed: int = 0) -> OrderRadiance:
    """Radiance reaching a viewer at ``height_m`` looking along the view direction, per unit
    extraterrestrial sun irradiance, by order (``orders`` of them), estimated from ``paths``
    paths (plus as many for the ground the view ray hits, if it does).

    Order n: light that scattered in the atmosphere or reflected off the ground n times in
    all, the ground point the view ray ends on counting as an event. ``atmosphere`` (orders, 3):
    light whose last event before the viewer is a scattering in the atmosphere
    (``atmosphere[0]`` = single scattering, as ``reference.single_scattering``);
    ``ground`` (orders, 3): light reflected towards the viewer by the ground point its view
    ray hits (``ground[0]``: the directly sunlit ground; lookups add this term themselves).
    ``*_se``: their standard errors, ``*_cov``: the covariances between orders, ``atmosphere_sum``:
    a sum of orders with its standard error. Three-channel params only (``spectral=False``;
    convert spectral ones per wavelength with ``spectrum.triple_params``). Deterministic for
    a given ``seed``. The height is clamped to the atmosphere and the sun-view cosine into the
    range the two zenith cosines allow.
    """
    if params.spectral:
        raise ValueError("radiance_by_order needs three-channel params (spectral=False); "
                         "convert with lut_gen.model.spectrum.triple_params")
    if int(orders) < 1 or int(paths) < 2:
        raise ValueError(f"need orders >= 1 and paths >= 2, got {orders}, {paths}")
    orders, paths = int(orders), int(paths)
    media = _Media.of(params)
    camera, view, sun = _view_geometry(params, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view)
    sees_ground = bool(_segment(media, camera[None], view[None]).hits_ground[0])
    rng = np.random.default_rng(seed)
    sums = {part: [np.zeros((orders, 3)), np.zeros((orders, orders, 3))] for part in ("atmosphere", "ground")}
    for start in range(0, paths, BATCH_PATHS):
        n = min(BATCH_PATHS, paths - start)
        for part, ground_first in (("atmosphere", False), ("ground", True)):
            if ground_first and not sees_ground:
                continue
            c = _trace(media, camera, view, sun, ground_first, orders, n, rng)
            sums[part][0] += c.sum(axis=0)
            sums[part][1] += np.einsum("pic,pjc->ijc", c, c)
    atmosphere, atmosphere_cov = _mean_and_cov(*sums["atmosphere"], paths)
    ground, ground_cov = _mean_and_cov(*sums["ground"], paths)
    return OrderRadiance(atmosphere, ground, atmosphere_cov, ground_cov, paths)


def irradiance_by_order(params: AtmosphereParams, height_m: float, cos_sun_zenith: float, facing_up: bool = True,
                        orders: int = 4, paths: int = DEFAULT_PATHS, seed: int = 0) -> OrderRadiance:
    """Diffuse irradiance on a horizontal plane at ``height_m`` facing up (the sky above it) or
    down (``facing_up=False``: the air and the ground below it), per unit extraterrestrial sun
    irradiance, by order: pi x the mean radiance (``radiance_by_order``'s orders and parts) of
    ``paths`` cosine-weighted lines of sight about the plane's normal (each population, the
    ``atmosphere`` part and the ``ground`` part of the lines of sight that hit the ground, traced
    on the same lines of sight). The sun's direct beam is not included (add cos_sun_zenith x
    T_sun for a plane facing up). Energy: in a medium that only scatters, over a ground of
    albedo 1, all the light leaves through the top, so the ``total`` of all orders facing down
    above the media is cos_sun_zenith."""
    if params.spectral:
        raise ValueError("irradiance_by_order needs three-channel params (spectral=False); "
                         "convert with lut_gen.model.spectrum.triple_params")
    if int(orders) < 1 or int(paths) < 2:
        raise ValueError(f"need orders >= 1 and paths >= 2, got {orders}, {paths}")
    orders, paths = int(orders), int(paths)
    media = _Media.of(params)
    camera, _, sun = _view_geometry(params, height_m, 1.0, cos_sun_zenith, cos_sun_zenith)
    normal = np.array([0.0, 0.0, 1.0 if facing_up else -1.0])
    rng = np.random.default_rng(seed)
    sums = {part: [np.zeros((orders, 3)), np.zeros((orders, orders, 3))] for part in ("atmosphere", "ground")}
    for start in range(0, paths, BATCH_PATHS):
        n = min(BATCH_PATHS, paths - start)
        views = _around(np.repeat(normal[None], n, axis=0), np.sqrt(rng.random(n)), rng)
        for part, ground_first in (("atmosphere", False), ("ground", True)):
            if ground_first and facing_up:
                continue  # lines of sight above the horizontal plane never reach the ground
            c = math.pi * _trace(media, camera, views, sun, ground_first, orders, n, rng)
            sums[part][0] += c.sum(axis=0)
            sums[part][1] += np.einsum("pic,pjc->ijc", c, c)
    atmosphere, atmosphere_cov = _mean_and_cov(*sums["atmosphere"], paths)
    ground, ground_cov = _mean_and_cov(*sums["ground"], paths)
    return OrderRadiance(atmosphere, ground, atmosphere_cov, ground_cov, paths)
