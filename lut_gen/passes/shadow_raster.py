"""The shadow maps' rasteriser, pure numpy: the largest sun depth of light-space triangles over
every texel centre of a rectangle (lut_gen.passes.shadow_map renders its cascades with it).

A texel stores the largest sun depth of the geometry over its centre, EMPTY_DEPTH where no
triangle covers it. Each triangle's texel box is scanned row by row for the span inside its three
edges: small triangles scatter the texels they cover, large ones fill their whole box masked to
those spans. Texel rows run bottom to top (row 0 at the smallest y), as Blender image pixels do.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EMPTY_DEPTH = -1.0e9            # sun depth of texels no geometry covers: everything is lit there
MAX_CANDIDATES = 1 << 18        # box texels per scan batch: its temporaries stay in the cache
DENSE_TEXELS = 1 << 12          # triangles with boxes this large are filled box-wise, not scanned


def rasterize_max_depth(triangles_light: np.ndarray, center, half, resolution: int, out=None) -> np.ndarray:
    """(res, res) float32: the largest sun depth of ``triangles_light`` (M, 3, 3: x, y, d per
    vertex) over each texel centre of the rectangle center +- half; EMPTY_DEPTH where none.
    ``out``: a C-contiguous (res, res) float32 array to rasterise into (a cascade of a stack
    allocated once: at 4096 texels each cascade is 64 MiB)."""
    if resolution < 1:
        raise ValueError(f"the shadow map resolution must be at least 1 texel, got {resolution}")
    if out is None:
        out = np.empty((resolution, resolution), dtype=np.float32)
    x, y, d = np.asarray(triangles_light, dtype=np.float64).reshape(-1, 3, 3).transpose(2, 1, 0)
    _rasterize(out, x, y, d, (_least(x), _least(y)), (_greatest(x), _greatest(y)), center, half, slice(None))
    return out


def _rasterize(out, x, y, d, low, high, center, half, candidates):
    """rasterize_max_depth into ``out`` (res, res) of the triangles ``candidates`` (an index or
    slice) of those given by their light-space corners ``x``, ``y`` and sun depths ``d``, (3, M)
    each: vertex by triangle (one vertex's values side by side, so that the per-triangle work
    runs on flat arrays), and their light-space boxes ``low`` and ``high`` ((x, y) of (M,)
    arrays)."""
    resolution = out.shape[-1]
    depth = out.reshape(-1)                 # a view: the scan writes into ``out``
    depth.fill(EMPTY_DEPTH)
    texel = 2.0 * np.asarray(half, dtype=np.float64) / resolution
    origin = np.asarray(center, dtype=np.float64) - half

    def to_texels(v, axis):                 # texel centres at integer coordinates
        return (v - origin[axis]) / texel[axis] - 0.5

    # The texel box from the light-space box (to_texels is monotonic: the same as the box of the
    # corners' texel coordinates); the corners only of the triangles whose box holds a texel
    # centre (a sixth of the forest's in the far cascades).
    lo_x = np.maximum(np.ceil(to_texels(low[0][candidates], 0)), 0).astype(np.int64)
    hi_x = np.minimum(np.floor(to_texels(high[0][candidates], 0)), resolution - 1).astype(np.int64)
    lo_y = np.maximum(np.ceil(to_texels(low[1][candidates], 1)), 0).astype(np.int64)
    hi_y = np.minimum(np.floor(to_texels(high[1][candidates], 1)), resolution - 1).astype(np.int64)
    inside = np.flatnonzero((hi_x >= lo_x) & (hi_y >= lo_y))
    lo_x, hi_x, lo_y, hi_y = lo_x[inside], hi_x[inside], lo_y[inside], hi_y[inside]
    keep = np.arange(x.shape[1])[candidates][inside]
    px, py = to_texels(x[:, keep], 0), to_texels(y[:, keep], 1)
    area = (px[1] - px[0]) * (py[2] - py[0]) - (px[2] - px[0]) * (py[1] - py[0])
    solid = np.abs(area) > 1e-12
    if not solid.any():
        return
    px, py, d, area = px[:, solid], py[:, solid], d[:, keep[solid]], area[solid]
    lo_x, hi_x, lo_y, hi_y = lo_x[solid], hi_x[solid], lo_y[solid], hi_y[solid]
    planes = _barycentric_planes(px - lo_x, py - lo_y, area)
    d0 = d[0]
    depth_plane = planes[1] * (d[1] - d0) + planes[2] * (d[2] - d0)         # (3 coefficients, M)
    box = _Boxes(lo_x, lo_y, hi_x - lo_x + 1, hi_y - lo_y + 1)
    # Scanline: per triangle and row of its box, the texel span inside all three edges. Large
    # triangles then fill their boxes masked to those spans; the rest scatter only the texels
    # they cover.
    big = box.width * box.height >= DENSE_TEXELS
    for batch, rows in _height_batches(box, np.flatnonzero(big)):
        x_lo, span = _row_spans(planes[..., batch], box.take(batch), rows)
        for t, first, count in zip(batch, x_lo, span):
            _fill(out, first, count, depth_plane[:, t], d0[t], box.take(slice(t, t + 1)))
    for batch, rows in _height_batches(box, np.flatnonzero(~big)):
        _scan(depth, resolution, planes[..., batch], depth_plane[:, batch], d0[batch], box.take(batch), rows)


def _height_batches(box, which):
    """(triangle indices, rows) of the triangles ``which``: groups of similar box height, each
    group's rows a (triangles, rows) broadcast with ``rows`` the power of two at or above their
    heights, in batches of at most MAX_CANDIDATES box texels (4 M took 1.3x as long: the
    temporaries left the cache)."""
    group = np.frexp(box.height[which] - 1)[1]          # ceil(log2(height)): heights in (rows / 2, rows]
    order = which[np.argsort(group, kind="stable")]
    group = np.sort(group)
    box_start = np.concatenate([[0], np.cumsum((box.width * box.height)[order])])
    first = 0
    while first < len(order):
        last = int(np.searchsorted(box_start, box_start[first] + MAX_CANDIDATES, side="right")) - 1
        last = min(max(last, first + 1), int(np.searchsorted(group, group[first], side="right")))
        yield order[first:last], 1 << int(group[first])
        first = last


@dataclass
class _Boxes:
    """Texel boxes of triangles: the first column and row, and the width and height in texels."""
    lo_x: np.ndarray
    lo_y: np.ndarray
    width: np.ndarray
    height: np.ndarray

    def take(self, which) -> "_Boxes":
        return _Boxes(self.lo_x[which], self.lo_y[which], self.width[which], self.height[which])


def _least(v):
    """Per triangle the least of the three vertices' values (v: (3, M)): np.min over the
    short axis is several times slower."""
    return np.minimum(np.minimum(v[0], v[1]), v[2])


def _greatest(v):
    return np.maximum(np.maximum(v[0], v[1]), v[2])


def _row_spans(planes, box: _Boxes, rows: int):
    """(first column, texel count), (triangles, rows) int64 each: the texel centres inside the
    triangles on each of the first ``rows`` rows of their boxes (none past a box's height)."""
    oy = np.arange(rows, dtype=np.float64)
    lower = np.zeros((len(box.height), rows))
    upper = np.where(oy < box.height[:, None], (box.width - 1.0)[:, None], -1.0)
    bound = np.empty_like(lower)
    eps = -1e-7
    for a, b, c in planes:
        # a x >= eps - b y - c: an edge bounds the span from below (a > 0) or above (a < 0) at
        # x = (eps - c) / a - (b / a) y: a multiply-add per row and triangle (a division per
        # row for each bound, NaN-masked for the other, took 15% longer).
        with np.errstate(divide="ignore", invalid="ignore"):
            inverse = 1.0 / a
            np.multiply((-b * inverse)[:, None], oy, out=bound)
            bound += ((eps - c) * inverse)[:, None]
        np.maximum(lower, bound, out=lower, where=(a > 0)[:, None])
        np.minimum(upper, bound, out=upper, where=(a < 0)[:, None])
        flat = np.flatnonzero(a == 0)
        if len(flat):
            # A row edge empties the rows where eps - b y - c > 0.
            rest = eps - b[flat, None] * oy - c[flat, None]
            upper[flat] = np.where(rest > 0, -1.0, upper[flat])
    x_lo = np.ceil(lower - 1e-9).astype(np.int64)
    x_hi = np.floor(np.maximum(upper, -1.0) + 1e-9).astype(np.int64)
    return x_lo, np.maximum(x_hi - x_lo + 1, 0)


def _scan(depth, resolution, planes, depth_plane, d0, box: _Boxes, rows: int):
    """Max-scatter the sun depth of triangles over the texel centres they cover, row by row;
    ``rows``: a power of two at least every box's height."""
    x_lo, span = _row_spans(planes, box, rows)
    span = span.ravel()
    covered = np.flatnonzero(span)
    if len(covered) == 0:
        return
    tri, oy = covered // rows, covered % rows
    x_lo, span = x_lo.ravel()[covered], span[covered]
    # Per texel only two repeats and a multiply-add: the covered texel i of the batch (counting
    # across spans) sits at flat index (span start - its first i) + i, and its depth is linear in
    # i along the span. Expanding per-texel triangle and row indices first and gathering from
    # them took three times as long at 4096 texels (84 M texels for the sample).
    first = np.cumsum(span) - span
    row = box.lo_y[tri] + oy
    column = box.lo_x[tri] + x_lo
    step = depth_plane[0, tri]
    start = d0[tri] + step * x_lo + depth_plane[1, tri] * oy + depth_plane[2, tri]
    count = int(first[-1] + span[-1])
    flat = np.repeat(row * resolution + column - first, span) + np.arange(count, dtype=np.int64)
    # i as float64 of its own: a float64 times int64 product runs a slow casting loop (1.7x).
    value = np.repeat(start - step * first, span) + np.repeat(step, span) * np.arange(count, dtype=np.float64)
    np.maximum.at(depth, flat, value.astype(np.float32))


def _fill(out, x_lo, span, depth_plane, d0, box: _Boxes):
    """Max the sun depth of one large triangle into ``out`` (res, res) over its whole box at
    once, masked to its row spans (first column ``x_lo``, ``span`` texels, per box row and
    more): no per-texel indices or scatter (3-4x faster than the scan for the ground's and
    near trees' triangles, which hold most of a map's texels). The depth is the sum of a
    per-column and a per-row part in float32, within 2 float32 steps of the scan's (far below
    the depth bias)."""
    y, x, height, width = int(box.lo_y[0]), int(box.lo_x[0]), int(box.height[0]), int(box.width[0])
    # int32 columns: the mask's comparisons run twice as wide as on int64.
    x_lo, x_end = x_lo[:height].astype(np.int32), (x_lo[:height] + span[:height]).astype(np.int32)
    columns = np.arange(width, dtype=np.int32)
    inside = (columns >= x_lo[:, None]) & (columns < x_end[:, None])
    along = (d0 + depth_plane[0] * np.arange(width, dtype=np.float64)).astype(np.float32)
    across = (depth_plane[1] * np.arange(height, dtype=np.float64) + depth_plane[2]).astype(np.float32)
    view = out[y:y + height, x:x + width]
    np.maximum(view, np.add.outer(across, along), out=view, where=inside)


def _barycentric_planes(px, py, area):
    """(3, 3, M): per vertex and triangle, (a, b, c) with barycentric weight a x + b y + c at
    grid offset (x, y) from the triangle's box corner (px, py: (3, M))."""
    planes = np.empty((3, 3, len(area)))
    for vertex, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
        # Twice the signed area of (i, j, point), over twice the triangle's.
        planes[vertex, 0] = -(py[j] - py[i]) / area
        planes[vertex, 1] = (px[j] - px[i]) / area
        planes[vertex, 2] = ((py[j] - py[i]) * px[i] - (px[j] - px[i]) * py[i]) / area
    return planes
