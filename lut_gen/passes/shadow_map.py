"""Cascaded sun shadow maps: an orthographic depth render along the sun direction, pure numpy.

The light frame has axes (right, up, sun): a world point P sits at light coordinates
x = P.right, y = P.up and has "sun depth" d = P.sun, which grows toward the sun. A shadow map
texel stores the largest sun depth of the geometry over its centre, so a point is lit when its
own sun depth is not below the stored one (minus a bias of a few texels). Nothing is clipped in
depth: every occluder between a point and the sun shares the point's (x, y).

Cascades split the camera's view depth between ``near`` and ``far`` (the sample's partitioning
factor blends uniform and logarithmic splits). Cascade i covers, in light space, the bounding
rectangle of the view frustum from the camera to split i + 1, so the cascades are nested and
each one contains every frustum point its depth range selects. The triangles are rasterised by
lut_gen.passes.shadow_raster.

Texel rows run bottom to top (row 0 at the smallest y), as Blender image pixels do.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .shadow_raster import EMPTY_DEPTH, _greatest, _least, _rasterize

BIAS_TEXELS = 2.0               # depth bias, in texel sizes, against self-shadowing of surfaces
PAD_TEXELS = 2.0                # margin around each cascade's footprint, so PCF taps stay inside
CASCADE_COLORS = np.array([(1.0, 0.3, 0.3), (0.3, 1.0, 0.3), (0.3, 0.3, 1.0), (1.0, 1.0, 0.3),
                           (1.0, 0.3, 1.0), (0.3, 1.0, 1.0), (1.0, 0.65, 0.2), (0.7, 0.7, 0.7)])

MIN_FORWARD_COSINE = 1e-3       # keeps the sky march length finite for rays across the view plane


def light_frame(sun_direction) -> np.ndarray:
    """(3, 3) rows right, up, sun: an orthonormal frame whose third axis points at the sun."""
    sun = np.asarray(sun_direction, dtype=np.float64)
    norm = np.linalg.norm(sun)
    if not np.isfinite(norm) or norm == 0.0:
        raise ValueError(f"the sun direction must be a non-zero vector, got {tuple(sun)}")
    sun = sun / norm
    helper = np.array([0.0, 0.0, 1.0]) if abs(sun[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(helper, sun)
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(sun, right), sun])


def cascade_splits(near: float, far: float, count: int, partitioning_factor: float) -> np.ndarray:
    """(count + 1,) view depths bounding the cascades: uniform (factor 0) to logarithmic (1)."""
    if count < 1:
        raise ValueError(f"the number of cascades must be at least 1, got {count}")
    if not 0.0 < near < far:
        raise ValueError(f"cascades need 0 < near < far, got near={near}, far={far}")
    i = np.arange(count + 1) / count
    uniform = near + (far - near) * i
    logarithmic = near * (far / near) ** i
    splits = uniform + (logarithmic - uniform) * float(np.clip(partitioning_factor, 0.0, 1.0))
    # Exactly near and far at the ends (the blend rounds them): the frame's epipolar grid is
    # laid out from ``far`` before the cascades exist (addon/scene/frame/frame_update.py) and
    # must match the one laid out from the cascades' last split.
    splits[0], splits[-1] = near, far
    return splits


@dataclass
class Camera:
    """A perspective camera: position, rotation (columns: right, up, backward, as Blender's
    matrix_world), the tangents of the half field of view in x and y, and the clip end."""
    position: np.ndarray
    rotation: np.ndarray
    tan_half_fov: tuple
    clip_end: float = float("inf")

    @property
    def forward(self) -> np.ndarray:
        return -np.asarray(self.rotation)[:, 2]

    def frustum_points(self, depth: float) -> np.ndarray:
        """(5, 3): the camera and the four frustum corners at view depth ``depth``."""
        tx, ty = self.tan_half_fov
        local = np.array([(sx * tx * depth, sy * ty * depth, -depth) for sx in (-1, 1) for sy in (-1, 1)])
        corners = local @ np.asarray(self.rotation, dtype=np.float64).T + self.position
        return np.vstack([np.asarray(self.position, dtype=np.float64)[None], corners])

    def view_directions(self, width: int, height: int) -> np.ndarray:
        """(height, width, 3) unit world directions through pixel centres, rows bottom to top."""
        tx, ty = self.tan_half_fov
        x = ((np.arange(width) + 0.5) / width * 2.0 - 1.0) * tx
        y = ((np.arange(height) + 0.5) / height * 2.0 - 1.0) * ty
        local = np.stack(np.broadcast_arrays(x[None, :], y[:, None], -1.0), axis=-1)
        world = local @ np.asarray(self.rotation, dtype=np.float64).T
        return world / np.linalg.norm(world, axis=-1, keepdims=True)


@dataclass
class ShadowCascades:
    """Cascaded shadow maps: ``frame`` from light_frame, per cascade the light-space centre
    (N, 2), half extents (N, 2), the view depth where it ends (N,), and the maps (N, res, res)."""
    frame: np.ndarray
    centers: np.ndarray
    halves: np.ndarray
    far_depths: np.ndarray
    depths: np.ndarray

    @property
    def count(self) -> int:
        return len(self.centers)

    @property
    def resolution(self) -> int:
        return self.depths.shape[-1]

    def texel_sizes(self) -> np.ndarray:
        """(N, 2) texel size in metres along x and y."""
        return 2.0 * self.halves / self.resolution

    def biases(self) -> np.ndarray:
        """(N,) depth bias in metres."""
        return BIAS_TEXELS * self.texel_sizes().max(axis=-1)


def cascade_footprints(camera: Camera, frame: np.ndarray, splits: np.ndarray, resolution: int):
    """Light-space centres and half extents (N, 2) of the frustum from the camera to each far
    split, padded by PAD_TEXELS texels."""
    centers, halves = [], []
    for depth in splits[1:]:
        xy = camera.frustum_points(depth) @ frame[:2].T
        low, high = xy.min(axis=0), xy.max(axis=0)
        half = np.maximum((high - low) / 2.0, 1e-3)
        half = half * resolution / max(resolution - 2.0 * PAD_TEXELS, 1.0)
        centers.append((low + high) / 2.0)
        halves.append(half)
    return np.array(centers), np.array(halves)


def render_cascades(triangles_world, camera: Camera, sun_direction, resolution: int, count: int,
                    partitioning_factor: float, near: float, far: float, threads: int = 1,
                    on_cascade=None) -> ShadowCascades:
    """Shadow maps of world-space triangles (M, 3, 3) for ``camera`` and the sun. ``threads``:
    how many cascades rasterise at once (each writes only its own map, so the maps are the same
    for any count; numpy releases the GIL in the loops, and two threads rasterise the forest's
    six cascades in 0.55x the time of one on 2 cores). ``on_cascade(i, depths)``: run on the
    rasterising thread as soon as cascade i's map is done (lut_gen.passes.min_max.fill_cascade
    builds its min/max maps there, while the other cascades still rasterise)."""
    if resolution < 16:
        raise ValueError(f"the shadow map resolution must be at least 16 texels, got {resolution}")
    frame = light_frame(sun_direction)
    splits = cascade_splits(near, far, count, partitioning_factor)
    centers, halves = cascade_footprints(camera, frame, splits, resolution)
    # Light space as (3 coordinates, 3 vertices, M), one product per vertex straight into
    # contiguous rows: the (M, 3, 3) product and the boxes over its short axes took 0.3 s of
    # the forest's 0.66 M triangles, strided views of one (3M, 3) product 0.05 s, this 0.023 s
    # (and the cascades' gathers from contiguous rows run faster).
    triangles_world = np.asarray(triangles_world, dtype=np.float64).reshape(-1, 3, 3)
    light = np.empty((3, 3, len(triangles_world)))
    depths = np.empty((len(centers), resolution, resolution), dtype=np.float32)
    boxes = {}

    def to_light(vertex):
        np.matmul(frame, triangles_world[:, vertex, :].T, out=light[:, vertex])

    def box(axis):                                  # light-space boxes, once
        boxes[axis] = _least(light[axis]), _greatest(light[axis])

    def rasterise(i):
        (low_x, high_x), (low_y, high_y) = boxes[0], boxes[1]
        low, high = (low_x, low_y), (high_x, high_y)
        c, h = centers[i], halves[i]
        _rasterize(depths[i], light[0], light[1], light[2], low, high, c, h,
                   np.flatnonzero(_overlapping(low, high, c, h)))
        if on_cascade is not None:
            on_cascade(i, depths[i])

    # The outer cascades first: nested, they hold the most triangles (the forest's took 0.02
    # to 0.16 s from the inner to the outer), so that the threads end together.
    stages = ((to_light, range(3)), (box, range(2)), (rasterise, reversed(range(len(centers)))))
    if threads <= 1:
        for work, items in stages:
            for item in items:
                work(item)
    else:
        with ThreadPoolExecutor(min(threads, len(centers)), thread_name_prefix="OLS shadow cascades") as pool:
            for work, items in stages:
                for done in [pool.submit(work, item) for item in items]:
                    done.result()
    return ShadowCascades(frame, centers, halves, splits[1:], depths)


def _overlapping(low, high, center, half):
    """Mask of the triangles whose light-space bounding box (low, high: x and y arrays) meets
    the rectangle center +- half."""
    return ((high[0] >= center[0] - half[0]) & (low[0] <= center[0] + half[0])
            & (high[1] >= center[1] - half[1]) & (low[1] <= center[1] + half[1]))


def select_cascade(cascades: ShadowCascades, light_xy, view_depth, best_search: bool):
    """Cascade index per point; ``count`` where no cascade applies (the point is lit).
    ``view_depth`` is read only without ``best_search``."""
    x, y = light_xy[..., 0], light_xy[..., 1]
    # One cascade at a time on flat arrays: an (n, cascades, 2) comparison costs several times more.
    inside = [(np.abs(x - cx) <= hx) & (np.abs(y - cy) <= hy)
              for (cx, cy), (hx, hy) in zip(cascades.centers, cascades.halves)]
    if best_search:
        # Nested cascades: the smallest one a point projects into is the number it misses.
        missed = np.full(x.shape, cascades.count, dtype=np.int64)
        for covered in inside:
            missed -= covered
        return missed
    index = np.sum(np.asarray(view_depth)[..., None] > cascades.far_depths, axis=-1)
    clamped = np.minimum(index, cascades.count - 1)
    covered = np.choose(clamped, inside)
    return np.where(covered, index, cascades.count)


# Smooth shadows: bilinear percentage-closer filtering, the four texels around the point's
# position compared and weighted by its offset from their centres (as hardware PCF does). The
# lit fraction is then continuous in the point's position, which the shaft boundary's
# refinement (lut_gen.passes.shaft_boundary) needs to place a shadow's edge between march
# samples: a five-tap cross answers in fifths, which draws texel-sized blocks into the darkened
# sky. Without smoothing one tap: the texel under the point.
PCF_OFFSETS = np.array([(0, 0), (1, 0), (0, 1), (1, 1)])


def locate(cascades: ShadowCascades, points, camera: Camera, best_search: bool = True, first_cascade: int = 0):
    """Where world points (...) are tested: (tested mask, cascade index, texel y, texel x, sun
    depth, depth bias), with x and y continuous texel coordinates (texel i spans [i, i + 1)).
    Untested points (outside every cascade) are lit. As the sample's "First cascade to ray
    march", cascades below ``first_cascade`` are skipped: their points are tested in that
    (larger, nested) cascade instead. Coordinates are clamped to [-1, res + 1], which leaves
    every tap's clamped texel as it was."""
    points = np.asarray(points)
    # float32 points stay float32 (the epipolar march's many points; the compositor tests in
    # float32 too), anything else is taken as float64.
    dtype = np.float32 if points.dtype == np.float32 else np.float64
    points = points.astype(dtype, copy=False)
    # One (n, 3) product: a stack of (..., 3) @ (3, 3) products runs numpy's slower loop (1.4x).
    light = (points.reshape(-1, 3) @ cascades.frame.T.astype(dtype)).reshape(points.shape)
    view_depth = None if best_search else (points - camera.position) @ camera.forward
    index = select_cascade(cascades, light[..., :2], view_depth, best_search)
    index = np.maximum(index, min(first_cascade, cascades.count - 1))
    safe = np.minimum(index, cascades.count - 1)
    # Per cascade, texel coordinate = light * scale + offset: np.take of (count,) arrays per
    # point costs a fraction of indexing (count, 2) ones (this is the epipolar march's hot loop).
    texel = cascades.texel_sizes()
    scale = 1.0 / texel
    offset = (-(cascades.centers - cascades.halves) * scale).astype(dtype)
    scale = scale.astype(dtype)
    res = cascades.resolution
    x = np.clip(light[..., 0] * np.take(scale[:, 0], safe) + np.take(offset[:, 0], safe), -1.0, res + 1.0)
    y = np.clip(light[..., 1] * np.take(scale[:, 1], safe) + np.take(offset[:, 1], safe), -1.0, res + 1.0)
    return index < cascades.count, safe, y, x, light[..., 2], np.take(cascades.biases().astype(dtype), safe)


def tap_texels(x, y, smooth: bool):
    """[(row, column, weight)] of the PCF taps at continuous texel coordinates (x, y): the
    four texels around (x, y) with bilinear weights when ``smooth``, else the texel under it."""
    if not smooth:
        return [(np.floor(y).astype(np.int64), np.floor(x).astype(np.int64), 1.0)]
    u, v = np.asarray(x) - 0.5, np.asarray(y) - 0.5          # texel centres at integers
    column, row = np.floor(u), np.floor(v)
    fx, fy = u - column, v - row
    column, row = column.astype(np.int64), row.astype(np.int64)
    return [(row + dy, column + dx, (fx if dx else 1.0 - fx) * (fy if dy else 1.0 - fy)) for dx, dy in PCF_OFFSETS]


def tap_fraction(cascades: ShadowCascades, cascade, y, x, depth, bias, smooth: bool) -> np.ndarray:
    """Fraction of the sun a point at texel coordinates (x, y) of ``cascade`` passes: 0 or 1
    from one tap, or the bilinear weight of the four taps it passes when ``smooth``."""
    res = cascades.resolution
    lit = np.zeros(np.shape(depth))
    for row, column, weight in tap_texels(x, y, smooth):
        stored = cascades.depths[cascade, np.clip(row, 0, res - 1), np.clip(column, 0, res - 1)]
        lit += weight * (depth >= stored - bias)
    return lit


def visibility(cascades: ShadowCascades, points, camera: Camera, smooth: bool = False,
               best_search: bool = True, first_cascade: int = 0) -> np.ndarray:
    """Fraction of the sun visible from world points (...): 1 lit, 0 in shadow; bilinear PCF
    fractions when ``smooth``. Points outside every cascade are lit (see ``locate``)."""
    tested, cascade, y, x, depth, bias = locate(cascades, points, camera, best_search, first_cascade)
    return np.where(tested, tap_fraction(cascades, cascade, y, x, depth, bias, smooth), 1.0)


# -- packing for the compositor -----------------------------------------------------------------
# Atlas: cascade i sits in block i // 3 (columns [block * res, (block + 1) * res)), in colour
# channel i % 3 (R, G, B), rows bottom to top. Parameter image: one column per cascade plus a
# last one for points outside every cascade; rows as PARAM_ROWS.
CASCADES_PER_BLOCK = 3
PARAM_ROWS = ("center_far", "half_bias", "channel_mask", "block", "color")


def pack_atlas(cascades: ShadowCascades, out=None) -> np.ndarray:
    """(res, blocks * res, 4) float32 RGBA atlas of the cascades' depth maps. ``out``: an array
    of that shape to pack into, e.g. the previous frame's: at 4096 texels the atlas is 512 MiB,
    and touching fresh memory of that size cost more than a second inside Blender."""
    res, count = cascades.resolution, cascades.count
    blocks = -(-count // CASCADES_PER_BLOCK)
    shape = (res, blocks * res, 4)
    atlas = out if out is not None and out.shape == shape and out.dtype == np.float32 else np.empty(shape, np.float32)
    for block in range(blocks):
        columns = slice(block * res, (block + 1) * res)
        for channel in range(CASCADES_PER_BLOCK):
            i = block * CASCADES_PER_BLOCK + channel
            atlas[:, columns, channel] = cascades.depths[i] if i < count else EMPTY_DEPTH
        atlas[:, columns, 3] = 1.0
    return atlas


def pack_parameters(cascades: ShadowCascades) -> np.ndarray:
    """(len(PARAM_ROWS), count + 1, 4) float32: per cascade its light-space rectangle, far view
    depth, depth bias, atlas channel and block, and its Show Cascades colour."""
    count = cascades.count
    table = np.zeros((len(PARAM_ROWS), count + 1, 4), dtype=np.float32)
    table[..., 3] = 1.0
    table[0, :count, :2], table[0, :count, 2] = cascades.centers, cascades.far_depths
    table[1, :count, :2], table[1, :count, 2] = cascades.halves, cascades.biases()
    for i in range(count):
        block, channel = divmod(i, CASCADES_PER_BLOCK)
        table[2, i, channel] = 1.0
        table[3, i, 0] = block
    table[4, :count, :3] = CASCADE_COLORS[:count]
    table[4, count, :3] = 1.0
    return table
