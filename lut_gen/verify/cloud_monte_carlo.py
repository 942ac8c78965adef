"""Monte Carlo path tracer of the atmosphere with a uniform cloud layer: the reference the world
sky model's clouds (lut_gen.clouds.sky, the twin of the "OLS Clouds" node group) are checked
against (tests/numpy_only/test_cloud_monte_carlo.py).

The medium is the atmosphere tracer's (lut_gen.verify.monte_carlo_media: Rayleigh, Mie and ozone
of lut_gen.model.atmosphere, a Lambertian ground) plus the cloud layer at coverage 1: a spherical
shell between ``base`` and ``base + thickness`` above the ground of constant, grey extinction
``density`` that only scatters (single-scattering albedo 1), with the cloud phase function of
lut_gen.model.cloud_medium. A layer at coverage 1 fills every column to its full thickness
(field.thickness_fraction is 1 for every rank), so the whole medium is spherically symmetric. It shares no code with the cloud model
(slab.radiance, sky.view): only the media definitions and the atmosphere tracer's geometry,
optical-depth quadrature and phase-function samplers (lut_gen.verify.monte_carlo_media,
monte_carlo_segments, monte_carlo_events).

Why a tracer of its own rather than monte_carlo's forced collisions: a cloud of optical
thickness 20 takes hundreds of scatterings per path, and integrating every segment's optical
depth by quadrature (monte_carlo's way) would cost minutes per view. Here paths are walked by
*spectral tracking* (Kutz et al. 2017), delta tracking with a grey majorant per spherical shell
(below the cloud, in it, above it; the majorant is the largest extinction of any channel in the
shell, plus the cloud's in the cloud): tentative collisions at the majorant's rate, each a real
scattering with probability P_s or a null collision otherwise, the three channels' weights
corrected by sigma_s / (majorant P_s) and sigma_n / (majorant (1 - P_s)), with P_s taken from
the path's own weighted coefficients so that the weights stay bounded. Crossing a shell's sphere
restarts the (memoryless) free flight with the next shell's majorant. Absorption (Mie absorption,
ozone) enters through the null weights, so nothing is biased by a grey approximation.

Estimator: paths start at the viewer along the line of sight; at every scattering (and every
ground reflection) next-event estimation toward each sun direction given scores
    weight x kernel(cos) x T_sun,
kernel = beta_R p_R + beta_M p_M + density p_cloud (per channel; albedo / pi x cos(sun zenith)
on the ground), T_sun the sun's transmittance: the atmosphere's (monte_carlo's quadrature) times
the cloud's, exp(-density x chord), the chord through the shell along the sun found analytically.
Where the cloud's part is small the quadrature is done only for a random share of the vertices
(Russian roulette on the estimate, weighted back: no bias), since deep in a thick cloud the
quadrature would otherwise cost most of the time. New directions come from the mixture of the
three phase functions by the media's (channel-summed) share of the scattering there, each
channel's weight then correcting for its own kernel; on the ground, cosine-weighted. Paths
end on leaving the top of the atmosphere, or by Russian roulette once their weights are small.

No fog layer (AtmosphereParams.fog_visibility): ``radiance`` and ``irradiance`` refuse params
with fog (lut_gen.verify.monte_carlo traces it); ``direct_transmittance`` includes it.

The random walk does not depend on the sun: one walk scores every sun direction at once, so
that a view is traced once for all the suns it is checked against. All orders are included
(the atmosphere's too, unlike monte_carlo's ``orders``); the sun's direct beam is not (a delta,
it is the sun disc's, not the sky's). Results are per unit extraterrestrial sun irradiance, the
unit of the tables.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..clouds import field
from ..clouds.layer import CloudLayer
from ..model import cloud_medium
from ..model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase
from . import monte_carlo_events as mc_events, monte_carlo_media as mc_media, monte_carlo_segments as mc_segments
from .slab_monte_carlo import _sample_phase as _sample_cloud_cos

__all__ = ["CloudShell", "CloudRadiance", "radiance", "irradiance", "direct_transmittance", "DEFAULT_PATHS"]

DEFAULT_PATHS = 4096
# Paths walked together: the walk's loop runs as long as its longest path, so big batches
# spend less time per path on the thin tail of long random walks in thick clouds.
BATCH_PATHS = 16_384
# Below this cloud transmittance toward the sun the atmosphere's part of T_sun is integrated for
# a random share T_cloud / NEE_SURE of the vertices only (weighted back).
NEE_SURE = 0.05
# Russian roulette: paths whose largest channel weight falls under this survive with
# probability weight / ROULETTE_BELOW.
ROULETTE_BELOW = 0.25
# A safety cap on the walk's steps (tentative collisions and crossings of the longest path).
MAX_STEPS = 20_000
# Majorants: the largest extinction over a fine height grid of each shell, with a margin.
MAJORANT_GRID = 2001
MAJORANT_MARGIN = 1.02


@dataclass(frozen=True)
class CloudShell:
    """A uniform cloud layer: heights above the ground (m) and its extinction = scattering (1/m)."""

    base: float
    top: float
    density: float

    @classmethod
    def of(cls, layer: CloudLayer | None) -> "CloudShell":
        """The shell of a layer at coverage 1 (every column full thickness); None: no cloud.
        Partial coverage is a map of columns, which this tracer does not model."""
        if layer is None:
            return cls(0.0, 0.0, 0.0)
        layer = layer.clamped()
        if float(np.min(field.thickness_fraction(np.array([0.0, 1.0]), layer.coverage))) < 1.0:
            raise ValueError(f"the path tracer takes uniform layers (coverage 1) only, got coverage {layer.coverage}")
        return cls(layer.base, layer.base + layer.thickness, layer.density)


@dataclass(frozen=True)
class CloudRadiance:
    """(S, 3) radiance (or irradiance) per sun direction and channel, per unit sun, and its
    standard errors."""

    value: np.ndarray
    se: np.ndarray
    paths: int


# -- the medium --------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Medium:
    air: mc_media._Media
    radii: np.ndarray        # (4,) ground, cloud base, cloud top, top of the atmosphere
    density: float           # the cloud's extinction
    majorant: np.ndarray     # (3,) per shell: below the cloud, in it, above it

    @classmethod
    def of(cls, params: AtmosphereParams, shell: CloudShell) -> "_Medium":
        air = mc_media._Media.of(params)
        big_r = params.earth_radius
        base = min(max(shell.base, 0.0), params.atmosphere_height)
        top = min(max(shell.top, base), params.atmosphere_height)
        radii = np.array([big_r, big_r + base, big_r + top, params.top_radius])
        majorant = np.zeros(3)
        for k in range(3):
            h = np.linspace(radii[k], radii[k + 1], MAJORANT_GRID) - big_r
            dens = np.stack([d if d is not None else np.zeros_like(h) for d in air.densities(h + big_r)], axis=-1)
            majorant[k] = MAJORANT_MARGIN * float((dens @ air.extinction).max()) + (shell.density if k == 1 else 0.0)
        return cls(air, radii, float(shell.density) if top > base else 0.0, majorant)

    def coefficients(self, points, in_cloud):
        """(N, 3) Rayleigh and Mie scattering, cloud scattering (N,) and extinction (N, 3)."""
        r = mc_media._norm(points)
        beta_r, beta_m, _ = self.air.scattering(r)  # no fog here (_checked)
        dens = [d if d is not None else np.zeros_like(r) for d in self.air.densities(r)]
        cloud = np.where(in_cloud, self.density, 0.0)
        extinction = np.stack(dens, axis=-1) @ self.air.extinction + cloud[:, None]
        return beta_r, beta_m, cloud, extinction


# -- geometry ----------------------------------------------------------------------------------

def _shell_exit(r, mu, r_in, r_out):
    """(distance, inward): where rays from radius r (zenith cosine mu) leave the shell
    [r_in, r_out], cancellation-free near both spheres, and whether through the inner one."""
    rmu = r * mu
    q_in = np.maximum(r - r_in, 0.0) * (r + r_in)                                      # r^2 - r_in^2 >= 0
    disc_in = rmu * rmu - q_in
    inward = (mu < 0.0) & (disc_in >= 0.0)
    denominator = -rmu + np.sqrt(np.maximum(disc_in, 0.0))
    to_in = np.divide(q_in, denominator, out=np.zeros_like(r), where=inward & (denominator > 0.0))
    q_out = np.maximum(r_out - r, 0.0) * (r_out + r)                                   # r_out^2 - r^2 >= 0
    root = np.sqrt(rmu * rmu + q_out)
    to_out = np.where(mu > 0.0, q_out / np.maximum(rmu + root, 1e-300), root - rmu)
    return np.where(inward, to_in, to_out), inward


def _inside_length(r, mu, radius):
    """Length of the part of rays from radius r (zenith cosine mu, s >= 0) inside the sphere."""
    rmu = r * mu
    disc = rmu * rmu + (radius - r) * (radius + r)
    root = np.sqrt(np.maximum(disc, 0.0))
    return np.where(disc > 0.0, np.maximum(-rmu + root, 0.0) - np.maximum(-rmu - root, 0.0), 0.0)


def _cloud_transmittance(medium: _Medium, points, suns):
    """(N,) exp(-density x chord) of the cloud shell from the points along their sun directions
    (N, 3)."""
    if medium.density <= 0.0:
        return np.ones(points.shape[0])
    r = mc_media._norm(points)
    mu = np.clip(mc_media._dot(points, suns) / r, -1.0, 1.0)
    chord = _inside_length(r, mu, medium.radii[2]) - _inside_length(r, mu, medium.radii[1])
    return np.exp(-medium.density * np.maximum(chord, 0.0))


_GAUSS = np.polynomial.legendre.leggauss(mc_segments.SUN_GAUSS_NODES)


def _air_transmittance(air: mc_media._Media, points, suns):
    """(N, 3) the air's transmittance from the points to the top along their sun directions
    (N, 3), 0 where the Earth hides the sun: monte_carlo's sun-ray quadrature, for a sun per
    point (every vertex's suns in one call) and with its Gauss nodes made once."""
    r = np.clip(mc_media._norm(points), air.earth_radius, air.top_radius)
    mu = np.clip(mc_media._dot(points, suns) / r, -1.0, 1.0)
    blocked, _ = mc_media._ground_hit(air, r, mu)
    nodes = mc_segments._ray_nodes(air, r, mu, mc_media._distance_to_top(air, r, mu),
                                   mc_segments.SUN_SIDE_INTERVALS)
    x, w = _GAUSS
    mid = 0.5 * (nodes[:, 1:] + nodes[:, :-1])
    half = 0.5 * (nodes[:, 1:] - nodes[:, :-1])
    s = mid[..., None] + half[..., None] * x
    rr = r[:, None, None]
    radius = np.sqrt(np.maximum(rr * rr + s * (s + 2.0 * (r * mu)[:, None, None]), 0.0))
    net = np.zeros((r.size, air.extinction.shape[0]))
    for m, density in enumerate(air.densities(radius)):
        if density is not None:
            net[:, m] = ((density @ w) * half).sum(axis=1)
    return np.where(blocked[:, None], 0.0, np.exp(-(net @ air.extinction)))


def _sun_transmittance(medium: _Medium, points, suns, rng):
    """(N, 3) unbiased estimates of the sun's transmittance (air x cloud) from the points along
    their sun directions (N, 3); 0 where the Earth hides the sun. The air's quadrature runs for
    a random share of the points where the cloud lets little through (weighted back)."""
    cloud = _cloud_transmittance(medium, points, suns)
    keep = np.minimum(cloud / NEE_SURE, 1.0)
    chosen = rng.random(points.shape[0]) < keep
    out = np.zeros((points.shape[0], 3))
    if chosen.any():
        air = _air_transmittance(medium.air, points[chosen], suns[chosen])
        out[chosen] = air * (cloud[chosen] / keep[chosen])[:, None]
    return out


# -- events ------------------------------------------------------------------------------------

def _kernel(beta_r, beta_m, cloud, cos_theta, mie_g):
    """(N, 3) scattering coefficient x phase function, summed over the media."""
    return (beta_r * rayleigh_phase(cos_theta)[:, None] + beta_m * mie_phase(cos_theta, mie_g)[:, None]
            + (cloud * cloud_medium.phase(cos_theta))[:, None])


def _scatter(medium: _Medium, beta_r, beta_m, cloud, direction, rng):
    """New directions drawn from the media's mixture of phase functions (by their channel-summed
    share of the scattering) and the weight factors kernel / pdf (N, 3)."""
    n = direction.shape[0]
    shares = np.stack([beta_r.sum(axis=1), beta_m.sum(axis=1), 3.0 * cloud], axis=1)
    shares /= np.maximum(shares.sum(axis=1, keepdims=True), 1e-300)
    pick = (rng.random(n)[:, None] > np.cumsum(shares, axis=1)).sum(axis=1).clip(0, 2)
    cos_theta = np.empty(n)
    for k, sampler in enumerate((lambda m: mc_events._sample_rayleigh_cos(rng, m),
                                 lambda m: mc_events._sample_mie_cos(rng, m, medium.air.params.mie_g),
                                 lambda m: _sample_cloud_cos(np.zeros(m), rng))):
        mask = pick == k
        if mask.any():
            cos_theta[mask] = sampler(int(mask.sum()))
    pdf = (shares[:, 0] * rayleigh_phase(cos_theta) + shares[:, 1] * mie_phase(cos_theta, medium.air.params.mie_g)
           + shares[:, 2] * cloud_medium.phase(cos_theta))
    kernel = _kernel(beta_r, beta_m, cloud, cos_theta, medium.air.params.mie_g)
    return mc_media._around(direction, cos_theta, rng), kernel / np.maximum(pdf, 1e-300)[:, None]


def _pairs(points, suns):
    """Every point with every sun: points (N S, 3), suns (N S, 3), point-major."""
    return np.repeat(points, len(suns), axis=0), np.tile(suns, (points.shape[0], 1))


def _score_air(medium: _Medium, points, direction, beta_r, beta_m, cloud, suns, rng):
    """(N, S, 3) next-event estimates toward every sun at scattering vertices."""
    n, count = points.shape[0], len(suns)
    at, toward = _pairs(points, suns)
    cos_theta = np.clip(direction @ suns.T, -1.0, 1.0).reshape(-1)
    per_pair = (np.repeat(a, count, axis=0) for a in (beta_r, beta_m, cloud))
    kernel = _kernel(*per_pair, cos_theta, medium.air.params.mie_g)
    return (kernel * _sun_transmittance(medium, at, toward, rng)).reshape(n, count, 3)


def _score_ground(medium: _Medium, points, suns, rng):
    """(N, S, 3) next-event estimates toward every sun at ground vertices (Lambertian)."""
    n, count = points.shape[0], len(suns)
    at, toward = _pairs(points, suns)
    lambert = (medium.air.params.ground_albedo / math.pi
               * np.maximum(mc_media._dot(at, toward) / mc_media._norm(at), 0.0))
    return (lambert[:, None] * _sun_transmittance(medium, at, toward, rng)).reshape(n, count, 3)


# -- the walk ----------------------------------------------------------------------------------

def _walk(medium: _Medium, camera, directions, suns, rng) -> np.ndarray:
    """(n, S, 3) per-path radiance estimates from the viewer at ``camera`` along ``directions``
    (n, 3), for every sun."""
    n = directions.shape[0]
    score = np.zeros((n, len(suns), 3))
    ids = np.arange(n)
    points = np.repeat(camera[None], n, axis=0)
    direction = directions.copy()
    weight = np.ones((n, 3))
    radius = float(np.linalg.norm(camera))
    shell = np.full(n, int(np.searchsorted(medium.radii[1:3], radius, side="right")))
    albedo = medium.air.params.ground_albedo
    for _ in range(MAX_STEPS):
        if ids.size == 0:
            break
        r = mc_media._norm(points)
        mu = np.clip(np.einsum("ni,ni->n", points, direction) / r, -1.0, 1.0)
        exit_at, inward = _shell_exit(r, mu, medium.radii[shell], medium.radii[shell + 1])
        majorant = medium.majorant[shell]
        free = -np.log1p(-rng.random(ids.size)) / majorant
        collide = free < exit_at
        # Crossings: onto the sphere, into the next shell (or onto the ground, or out of the top).
        step = np.where(collide, free, exit_at)
        points = points + step[:, None] * direction
        crossing = ~collide
        boundary = np.where(inward, shell, shell + 1)
        onto = medium.radii[boundary]
        points[crossing] *= (onto[crossing] / mc_media._norm(points[crossing]))[:, None]
        ground = crossing & inward & (shell == 0)
        escaped = crossing & ~inward & (shell == 2)
        shell = np.where(crossing & ~ground & ~escaped, np.where(inward, shell - 1, shell + 1), shell)
        alive = ~escaped
        # Tentative collisions: a real scattering or a null collision.
        real = np.zeros(ids.size, dtype=bool)
        if collide.any():
            c = np.flatnonzero(collide)
            beta_r, beta_m, cloud, extinction = medium.coefficients(points[c], shell[c] == 1)
            scattering = beta_r + beta_m + cloud[:, None]
            null = np.maximum(majorant[c, None] - extinction, 0.0)
            w = weight[c]
            p_real = (w * scattering).sum(axis=1) / np.maximum((w * (scattering + null)).sum(axis=1), 1e-300)
            is_real = rng.random(c.size) < p_real
            real[c[is_real]] = True
            s = c[is_real]
            k = ~is_real
            weight[c[k]] = w[k] * null[k] / (majorant[c[k], None] * np.maximum(1.0 - p_real[k], 1e-300)[:, None])
            if s.size:
                br, bm, cl = beta_r[is_real], beta_m[is_real], cloud[is_real]
                ws = weight[s] / (majorant[s] * p_real[is_real])[:, None]
                score[ids[s]] += ws[:, None, :] * _score_air(medium, points[s], direction[s], br, bm, cl, suns, rng)
                new_dir, factor = _scatter(medium, br, bm, cl, direction[s], rng)
                direction[s] = new_dir
                weight[s] = ws * factor
        g = np.flatnonzero(ground)
        if g.size:
            score[ids[g]] += weight[g][:, None, :] * _score_ground(medium, points[g], suns, rng)
            normal = points[g] / mc_media._norm(points[g])[:, None]
            direction[g] = mc_media._around(normal, np.sqrt(rng.random(g.size)), rng)
            weight[g] = weight[g] * albedo
        # Russian roulette after events, on the largest channel weight.
        top = weight.max(axis=1)
        low = (real | ground) & (top < ROULETTE_BELOW)
        survive = rng.random(ids.size) < top / ROULETTE_BELOW
        weight[low & survive] /= (top[low & survive] / ROULETTE_BELOW)[:, None]
        alive &= ~(low & ~survive) & (top > 0.0)
        ids, points, direction, weight, shell = (a[alive] for a in (ids, points, direction, weight, shell))
    return score


def _suns(suns) -> np.ndarray:
    suns = np.atleast_2d(np.asarray(suns, dtype=np.float64))
    return suns / np.linalg.norm(suns, axis=1, keepdims=True)


def _camera(params: AtmosphereParams, height_m: float) -> np.ndarray:
    return np.array([0.0, 0.0, params.earth_radius + float(np.clip(height_m, 0.0, params.atmosphere_height))])


def _estimate(medium, camera, make_directions, suns, paths, rng, scale=1.0) -> CloudRadiance:
    total, square = np.zeros((len(suns), 3)), np.zeros((len(suns), 3))
    for start in range(0, paths, BATCH_PATHS):
        n = min(BATCH_PATHS, paths - start)
        c = scale * _walk(medium, camera, make_directions(n), suns, rng)
        total += c.sum(axis=0)
        square += (c * c).sum(axis=0)
    mean = total / paths
    var = np.maximum(square / paths - mean * mean, 0.0) / max(paths - 1, 1)
    return CloudRadiance(mean, np.sqrt(var), paths)


def _checked(params: AtmosphereParams, paths: int) -> int:
    if params.spectral:
        raise ValueError("the cloud path tracer needs three-channel params (spectral=False); "
                         "convert with lut_gen.model.spectrum.triple_params")
    if params.has_fog:
        raise ValueError("the cloud path tracer has no fog layer (its kernel and phase sampling know Rayleigh, "
                         "Mie and the cloud only); trace fog with lut_gen.verify.monte_carlo")
    if int(paths) < 2:
        raise ValueError(f"need paths >= 2, got {paths}")
    return int(paths)


def radiance(params: AtmosphereParams, layer: CloudLayer | None, height_m: float, view, suns,
             paths: int = DEFAULT_PATHS, seed: int = 0) -> CloudRadiance:
    """Radiance reaching a viewer ``height_m`` above the ground along the unit line of sight
    ``view`` (eye outward, z up at the viewer), per unit sun, for every unit sun direction of
    ``suns`` (S, 3) (toward the sun), with the uniform cloud ``layer`` (coverage 1; None: the
    clear sky). All orders; the sun's direct beam excluded. Deterministic for a given seed."""
    paths = _checked(params, paths)
    medium = _Medium.of(params, CloudShell.of(layer))
    view = np.asarray(view, dtype=np.float64) / np.linalg.norm(view)
    rng = np.random.default_rng(seed)
    return _estimate(medium, _camera(params, height_m), lambda n: np.repeat(view[None], n, axis=0), _suns(suns),
                     paths, rng)


def irradiance(params: AtmosphereParams, layer: CloudLayer | None, height_m: float, suns,
               paths: int = DEFAULT_PATHS, seed: int = 0) -> CloudRadiance:
    """Diffuse irradiance on a horizontal plane facing up at ``height_m`` (the upper hemisphere's
    radiance times the cosine, integrated; the sun's direct beam excluded), per unit sun: pi
    times the mean radiance of cosine-weighted lines of sight."""
    paths = _checked(params, paths)
    medium = _Medium.of(params, CloudShell.of(layer))
    rng = np.random.default_rng(seed)
    up = np.array([[0.0, 0.0, 1.0]])

    def directions(n):
        return mc_media._around(np.repeat(up, n, axis=0), np.sqrt(rng.random(n)), rng)
    return _estimate(medium, _camera(params, height_m), directions, _suns(suns), paths, rng, scale=math.pi)


def direct_transmittance(params: AtmosphereParams, layer: CloudLayer | None, height_m: float, suns) -> np.ndarray:
    """(S, 3) transmittance of the sun's direct beam from the top of the atmosphere to a point
    ``height_m`` above the ground: the air's (quadrature) times the cloud shell's (its chord
    along the sun through the curved shell); 0 where the Earth hides the sun."""
    medium = _Medium.of(params, CloudShell.of(layer))
    suns = _suns(suns)
    points = np.repeat(_camera(params, height_m)[None], len(suns), axis=0)
    return _air_transmittance(medium.air, points, suns) * _cloud_transmittance(medium, points, suns)[:, None]
