"""Epipolar sampling of the light shafts (Yusov 2012, "IVB Atmospheric Light Scattering"), as
per-frame tables: the numpy twin of the "OLS Light Shafts" group's epipolar technique, and what
the add-on writes before each frame. The grid the tables are laid out on (slices x samples, by
angle about and from the sun): lut_gen.passes.epipolar_grid.

Before the render, for a grid of slices x samples (phi x theta) covering the screen, the rays
are marched through the shadow cascades at ``K`` distances from the camera and the table keeps,
per distance t, the lit length L(t), the first lit distance F(t) and, for the INTEGRATION mode,
the shadowed single-scattering integral S(t). Only every ``initial_sample_step``-th sample of a
slice (denser near the epipole) is marched; where two marched neighbours disagree by more than
the refinement threshold the sample halfway between them is marched too, until the
disagreeing neighbours are adjacent; the rest are interpolated.

In the compositor each pixel finds its slice and sample, reads L, F and S at its own depth
(trilinear), and applies the scattering modes from the in-scattering tables of
lut_gen.passes.epipolar_air. Depth breaks cost nothing: no pixel borrows another's depth.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import aerial, min_max, shaft_boundary
from ..clouds import shafts as cloud_shafts
from .epipolar_grid import EpipolarFrame, EpipolarSettings
from .shadow_map import Camera, ShadowCascades, visibility

MAX_TABLE_TEXELS = 1 << 24      # (slices + 1) x samples x distances kept at most (memory)


@dataclass
class EpipolarTables:
    """Per grid node (slices + 1, samples) and distance K: lit length, first lit distance,
    (INTEGRATION) shadowed single scattering; ``marched`` flags the ray-marched samples."""
    lit_length: np.ndarray
    first_lit: np.ndarray
    integrated: np.ndarray | None
    marched: np.ndarray


def initial_samples(samples: int, step: int, density: int) -> np.ndarray:
    """Indices of the initially marched samples of a slice: every ``step``-th, and near the
    epipole (the first eighth of the slice) every ``step / density``-th, as Yusov 2012 places
    them; the last sample always."""
    step = max(int(step), 1)
    near_step = max(step // max(int(density), 1), 1)
    near = np.arange(0, max(samples // 8, 1), near_step)
    rest = np.arange(0, samples, step)
    return np.unique(np.concatenate([near, rest, [samples - 1]]))


def march(frame: EpipolarFrame, directions, cascades: ShadowCascades, camera: Camera, smooth: bool,
          best_search: bool, first_cascade: int, luts=None, integrate: bool = False, maps=None, clouds=None,
          integral=None):
    """(lit length, first lit, integrated or None, geometry's lit length) at the frame's
    distances for rays ``directions`` (n, 3): one shadow test per distance interval at its
    centre, as the brute force march does per step. ``maps`` (lut_gen.passes.min_max) skip the
    taps of decided points; ``clouds`` ((layer, map)) weight every test by the cloud's
    transmittance (lut_gen.clouds.shafts). The geometry's lit length is the lit length without
    the clouds (the lit length itself when there are none): what the refinement looks at.
    ``integral(directions, t, lit) -> (n, K, 3)``, given, is the INTEGRATION table instead of the
    tables' single scattering (the analytic model's, lut_gen.passes.analytic_shafts), from the
    lit fraction of each distance interval (n, K - 1)."""
    t = frame.distances()
    centres = 0.5 * (t[1:] + t[:-1])
    lengths = np.diff(t)
    # float32: the shadow test's points are the march's bulk (texel coordinates to 1e-4 of a
    # texel, sun depths to a millimetre at 10 km: finer than the depth bias).
    points = (camera.position.astype(np.float32) + directions[:, None, :].astype(np.float32)
              * centres[None, :, None].astype(np.float32))                                 # (n, K-1, 3)

    def is_lit(at):
        if maps is not None:
            return min_max.visibility(cascades, maps, at, camera, best_search, first_cascade)
        return visibility(cascades, at, camera, smooth, best_search, first_cascade)

    lit = is_lit(points)
    zero = np.zeros((len(directions), 1))
    geometry_length = np.concatenate([zero, np.cumsum(lit * lengths, axis=-1)], axis=-1)
    if clouds is not None:
        # Each interval's cloud factor is its mean, not its centre's (intervals reach kilometres);
        # the edge refinement below tests single points.
        lit = lit * cloud_shafts.interval_transmittance(*clouds, camera.position, directions, t, frame.sun)
        is_lit = cloud_shafts.sun_visibility(is_lit, *clouds, frame.sun)
    lit_length = geometry_length if clouds is None else np.concatenate([zero, np.cumsum(lit * lengths, axis=-1)],
                                                                       axis=-1)
    # F(t): the start of the first interval with light among those before t, else t itself.
    starts = np.where(lit >= shaft_boundary.LIT_FLOOR, t[None, :-1], np.inf)
    first = np.minimum.accumulate(starts, axis=-1)
    first_lit = np.minimum(np.concatenate([zero + np.inf, first], axis=-1), t[None, :])
    # The first shadow edge between its two samples, as the brute-force march places it
    # (lut_gen.passes.shaft_boundary): intervals j - 1 and j meet at t[j].
    j, before, after = shaft_boundary.first_transition(lit)
    crossed = j < len(centres)
    safe = np.clip(j, 1, len(centres) - 1)
    # Only the rays that cross an edge are refined (the others' edge is never read).
    edge = t[safe]
    if crossed.any():
        edge[crossed] = shaft_boundary.refine(is_lit, camera.position, directions[crossed], centres[safe - 1][crossed],
                                              centres[safe][crossed], before[crossed], after[crossed])
    crossed, edge, boundary = crossed[:, None], edge[:, None], t[safe][:, None]
    lit_length = lit_length + np.where(crossed, (before - after)[:, None] * (np.minimum(t, edge) - np.minimum(t, boundary)), 0.0)
    starts_shadowed = crossed & (lit[:, :1] < shaft_boundary.HALF)
    first_lit = np.where(starts_shadowed, np.minimum(t[None, :], edge), first_lit)
    integrated = None
    if integrate and integral is not None:
        integrated = integral(directions, t, lit)
    elif integrate:
        sun = frame.sun
        terms = aerial.integration_terms(luts, camera.position, directions, points,
                                         np.broadcast_to(lengths, lit.shape), sun)
        integrated = np.concatenate([np.zeros((len(directions), 1, 3)),
                                     np.cumsum(terms * lit[..., None], axis=-2)], axis=-2)
    return lit_length, first_lit, integrated, geometry_length


def build_tables(frame: EpipolarFrame, cascades: ShadowCascades, camera: Camera, settings: EpipolarSettings,
                 smooth: bool = True, best_search: bool = True, first_cascade: int = 0, luts=None,
                 integrate: bool = False, clouds=None, integral=None, needed=None, maps=None) -> EpipolarTables:
    """March the initial samples of every slice, refine between marched neighbours that
    disagree, and interpolate the rest along each slice (``integral``: as for march).
    ``needed`` ((slices + 1, samples) bool, screen_nodes): the nodes to build; then only the
    spans between initial samples that hold one are marched and refined, which gives those
    nodes the values the whole grid's build gives them (a node's value comes from its span's
    ends and bisection alone). The other nodes hold 0 unless marched. ``maps``: the cascades'
    min/max maps when the caller built them (min_max.fill_cascade while rasterising), else
    built here as the settings ask."""
    settings = settings.checked()
    nodes = frame.node_directions()
    n_slices, n_samples = nodes.shape[:2]
    K = frame.steps
    t = frame.distances()
    # One float32 array for both (the images are float32): filled and packed in one pass.
    lit_and_first = np.zeros((n_slices, n_samples, K, 2), dtype=np.float32)
    lit_length, first_lit = lit_and_first[..., 0], lit_and_first[..., 1]
    # The refinement looks for the geometry's shadow edges: the clouds' factor varies smoothly
    # along a slice (cloud features span tens to hundreds of pixels) and interpolates well, but
    # counted in, it sent a second refinement round over most slices (the epipolar tables
    # 1.5 -> 3.5 s a frame with clouds on the sample).
    geometry_length = lit_length if clouds is None else np.zeros_like(lit_length)
    integrated = np.zeros((n_slices, n_samples, K, 3), dtype=np.float32) if integrate else None
    marched = np.zeros((n_slices, n_samples), dtype=bool)
    if not settings.use_min_max:
        maps = None
    elif maps is None or maps.smooth != smooth:
        maps = min_max.build(cascades, smooth)

    def run(mask):
        idx = np.nonzero(mask & ~marched)
        if len(idx[0]) == 0:
            return
        chunk = max(1, (1 << 21) // K)
        for start in range(0, len(idx[0]), chunk):
            sel = (idx[0][start:start + chunk], idx[1][start:start + chunk])
            L, F, S, G = march(frame, nodes[sel], cascades, camera, smooth, best_search, first_cascade, luts,
                               integrate, maps, clouds, integral)
            lit_length[sel], first_lit[sel] = L, F
            if clouds is not None:
                geometry_length[sel] = G
            if integrate:
                integrated[sel] = S
        marched[idx] = True

    initial_indices = initial_samples(n_samples, settings.initial_sample_step, settings.epipole_sampling_density)
    pairs = _initial_pairs(n_slices, initial_indices)
    if needed is not None:
        pairs = _spans_holding(pairs, needed)
    initial = np.zeros(marched.shape, dtype=bool)
    initial[pairs[0], pairs[1]] = initial[pairs[0], pairs[2]] = True
    run(initial)
    if settings.refinement_threshold > 0:
        # Bisection: where two marched neighbours disagree, march the sample halfway between
        # them, until every disagreeing pair is adjacent. A shadow edge inside a span of 16
        # costs about log2(16) rays, not the 15 that marching the whole span cost.
        while True:
            pairs, need = _disagreeing_midpoints(geometry_length, pairs, t, settings.refinement_threshold)
            if not need.any():
                break
            run(need)
    _fill_between_marched(lit_and_first, marched, needed)
    if integrate:
        _fill_between_marched(integrated, marched, needed)
    return EpipolarTables(lit_length, first_lit, integrated, marched)


def _initial_pairs(n_slices: int, samples):
    """(slice, lower sample, upper sample) of each two consecutive ``samples`` of every slice."""
    slices = np.repeat(np.arange(n_slices), len(samples) - 1)
    return slices, np.tile(samples[:-1], n_slices), np.tile(samples[1:], n_slices)


def _spans_holding(pairs, needed):
    """The pairs (slice, lower sample, upper sample) whose span, ends included, holds a node
    ``needed`` marks."""
    slices, lower, upper = pairs
    before = np.cumsum(needed, axis=1) - needed                 # needed nodes below each sample
    holds = before[slices, upper] + needed[slices, upper] > before[slices, lower]
    return slices[holds], lower[holds], upper[holds]


def _disagreeing_midpoints(lit_length, pairs, t, threshold):
    """(the next round's pairs, (slices, samples) bool of the samples to march): the sample
    halfway between each pair of consecutive marched samples (slice, lower, upper) that are
    not adjacent and whose lit fraction L(t) / t differs by more than ``threshold`` at some
    distance. Only the halves of those pairs are looked at again: a pair that agrees keeps its
    values and stays consecutive (all pairs each round took a third of the tables' time)."""
    slices, lower, upper = pairs
    apart = upper - lower > 1
    slices, lower, upper = slices[apart], lower[apart], upper[apart]
    difference = lit_length[slices, lower, 1:] / t[1:] - lit_length[slices, upper, 1:] / t[1:]
    pick = np.abs(difference).max(axis=-1) > threshold
    slices, lower, upper = slices[pick], lower[pick], upper[pick]
    middle = (lower + upper) // 2
    need = np.zeros(lit_length.shape[:2], dtype=bool)
    need[slices, middle] = True
    halves = (np.concatenate([slices, slices]), np.concatenate([lower, middle]), np.concatenate([middle, upper]))
    return halves, need


def _fill_between_marched(table, marched, needed=None):
    """Linear interpolation along each slice's samples from its marched ones (the first and
    the last sample of a slice are always marched), in place (``table``: C-contiguous): only
    the unmarched rows are gathered and written, of those ``needed`` marks when given (a half
    to two thirds of the grid: the fill took 0.04-0.07 s of the forest's frame)."""
    n_samples = marched.shape[1]
    samples = np.broadcast_to(np.arange(n_samples), marched.shape)
    before = np.maximum.accumulate(np.where(marched, samples, 0), axis=1)
    after = np.minimum.accumulate(np.where(marched, samples, n_samples - 1)[:, ::-1], axis=1)[:, ::-1]
    slices, unmarched = np.nonzero(~marched if needed is None else ~marched & needed)
    if len(slices) == 0:
        return
    low, high = before[slices, unmarched], after[slices, unmarched]
    weight = ((unmarched - low) / np.maximum(high - low, 1)).astype(table.dtype)
    # The table as one row per node, gathered by flat row index and blended in place: indexing
    # by (slice, sample) pairs and the blend's temporaries took twice as long.
    rows = table.reshape(marched.size, -1)
    if not np.shares_memory(rows, table):
        raise ValueError("the table to fill must be C-contiguous (filled through a reshaped view)")
    start = slices * n_samples
    below, above = np.take(rows, start + low, axis=0), np.take(rows, start + high, axis=0)
    above -= below
    above *= weight[:, None]
    above += below
    rows[start + unmarched] = above


def trilinear(frame: EpipolarFrame, table, directions, distances) -> np.ndarray:
    """``table`` (slices + 1, samples, steps[, channels]) at rays ``directions`` (..., 3) and
    distances (...): trilinear in (slice, sample, distance), as the compositor's filtered
    fetches."""
    x, y = frame.direction_to_x(directions)
    z = frame.distance_to_x(distances)
    shape = np.shape(distances)
    coords = [np.asarray(c).reshape(-1) for c in (x, y, z)]
    i0 = np.minimum(np.floor(coords[0]).astype(int), table.shape[0] - 2)
    j0 = np.minimum(np.floor(coords[1]).astype(int), table.shape[1] - 2)
    k0 = np.minimum(np.floor(coords[2]).astype(int), table.shape[2] - 2)
    wi, wj, wk = coords[0] - i0, coords[1] - j0, coords[2] - k0
    out = 0.0
    for di, fi in ((0, 1 - wi), (1, wi)):
        for dj, fj in ((0, 1 - wj), (1, wj)):
            for dk, fk in ((0, 1 - wk), (1, wk)):
                w = fi * fj * fk
                v = table[i0 + di, j0 + dj, k0 + dk]
                out = out + (w[:, None] * v if v.ndim == 2 else w * v)
    return out.reshape(shape + table.shape[3:])


def look_up(frame: EpipolarFrame, tables: EpipolarTables, directions, distances):
    """(lit length, first lit, integrated or None) for pixel rays ``directions`` (..., 3) at
    their own distances (...): trilinear in (slice, sample, distance)."""
    lit_length = trilinear(frame, tables.lit_length, directions, distances)
    first_lit = trilinear(frame, tables.first_lit, directions, distances)
    integrated = None if tables.integrated is None else trilinear(frame, tables.integrated, directions, distances)
    # Beyond the grid (surfaces that cast no shadow, past the farthest caster) the air is lit,
    # as it is outside every cascade for brute force.
    beyond = np.maximum(np.asarray(distances) - frame.t_max, 0.0)
    return np.minimum(lit_length, distances) + beyond, np.minimum(first_lit, distances), integrated


def sampling_overlay(frame: EpipolarFrame, marched, camera: Camera, width: int, height: int) -> np.ndarray:
    """(height, width) float32, rows bottom to top: 1 where Show Sampling paints red. Ray-marched
    samples are thick dots (3 x 3 pixels), interpolated ones thin (1 pixel), at the screen
    positions of the grid's nodes."""
    directions = frame.node_directions()
    local = directions @ np.asarray(camera.rotation, dtype=np.float64)            # (S+1, N, 3) camera axes
    ahead = local[..., 2] < -1e-9
    depth = np.where(ahead, -local[..., 2], 1.0)
    tx, ty = camera.tan_half_fov
    column = np.floor((local[..., 0] / depth / tx + 1.0) * 0.5 * width).astype(np.int64)
    row = np.floor((local[..., 1] / depth / ty + 1.0) * 0.5 * height).astype(np.int64)
    overlay = np.zeros((height, width), dtype=np.float32)
    thick = np.asarray(marched, dtype=bool)
    for offsets, which in ((((0, 0),), ~thick), ([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)], thick)):
        for dx, dy in offsets:
            c, r = column + dx, row + dy
            keep = ahead & which & (c >= 0) & (c < width) & (r >= 0) & (r < height)
            overlay[r[keep], c[keep]] = 1.0
    return overlay
