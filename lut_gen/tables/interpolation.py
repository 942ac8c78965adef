"""Multilinear interpolation on regular grids in texel-index coordinates.

The same arithmetic as linear texture filtering with clamp-to-edge: a coordinate x on an axis
with N nodes blends nodes i0 = floor(x) and i0 + 1 with weight x - i0, after clamping x to
[0, N-1]. Tables carry channels in their last axis.
"""
from __future__ import annotations

import itertools

import numpy as np


def axis_weights(x, n: int):
    """Lower node index and the weight of the upper node for coordinates x on an n-node axis."""
    x = np.asarray(x)
    x = np.clip(x if x.dtype == np.float32 else x.astype(np.float64), 0, n - 1)
    if n == 1:
        return np.zeros(x.shape, dtype=np.int64), np.zeros(x.shape, dtype=np.float32)
    i0 = np.minimum(x.astype(np.int64), n - 2)      # x >= 0, so truncation is floor
    return i0, (x - i0).astype(np.float32)


def packed_rows(table: np.ndarray):
    """View a (N, C) float32 table as one record per row, padded to 4, 8 or 16 channels: numpy
    gathers records (one memcpy per item) several times faster than (N, C) float rows.
    Returns (packed 1D array, padded channel count)."""
    rows = np.asarray(table, dtype=np.float32).reshape(-1, table.shape[-1])
    width = next(w for w in (4, 8, 16, rows.shape[1]) if w >= rows.shape[1])
    if rows.shape[1] != width:
        rows = np.concatenate([rows, np.zeros((rows.shape[0], width - rows.shape[1]), np.float32)], axis=1)
    record = np.dtype([("v", np.float32, (width,))])
    return np.ascontiguousarray(rows).view(record).reshape(-1), width


def gather(packed: np.ndarray, width: int, index: np.ndarray) -> np.ndarray:
    """Rows of a packed table at integer ``index`` (any shape) as (*index.shape, width) float32."""
    return np.take(packed, index.reshape(-1)).view(np.float32).reshape(index.shape + (width,))


def interpolate(table: np.ndarray, coords, chunk: int = 1 << 20, geometric_axes=(), packed=None) -> np.ndarray:
    """Linear interpolation of ``table`` (*axes, C) at texel coordinates ``coords`` (one array per
    axis, broadcast together). Returns (*broadcast shape, C) float32.

    ``geometric_axes``: axes blended geometrically (geometric_lerp) after the linear blend of the
    others, i.e. bilinear in log space on those axes. ``packed``: packed_rows(table), when the
    caller keeps it (packing copies the table)."""
    return interpolate_many([table], coords, chunk, geometric_axes, [packed])[0]


def interpolate_many(tables, coords, chunk: int = 1 << 20, geometric_axes=(), packed=None) -> list:
    """interpolate() of several tables of the same axes at the same coordinates: the corners'
    indices and weights are found once for all of them. ``packed``: a list (entries may be
    None) as interpolate's."""
    axes = tables[0].shape[:-1]
    if any(t.shape[:-1] != axes for t in tables):
        raise ValueError(f"tables of different axes: {[t.shape for t in tables]}")
    packed = [p if p is not None else packed_rows(t) for t, p in zip(tables, packed or [None] * len(tables))]
    return interpolate_packed(axes, packed, [t.shape[-1] for t in tables], coords, chunk, geometric_axes)


def interpolate_packed(axes, packed, channels, coords, chunk: int = 1 << 20, geometric_axes=()) -> list:
    """interpolate_many() of tables given as their packed_rows() only: ``axes`` the tables'
    node counts, ``packed`` their (rows, width) and ``channels`` their channel counts. Several
    tables of one grid side by side in one packed table (packed_side_by_side) are looked up
    with one gather per corner instead of one per table (0.6x the time of the epipolar
    in-scattering tables' three)."""
    axes = tuple(axes)
    if len(coords) != len(axes):
        raise ValueError(f"{len(axes)}D table needs {len(axes)} coordinates, got {len(coords)}")
    coords = np.broadcast_arrays(*[np.asarray(c, dtype=np.float64) for c in coords])
    shape = coords[0].shape
    flat_coords = [c.reshape(-1) for c in coords]
    strides = np.cumprod((1,) + axes[::-1])[:-1][::-1]
    outs = [np.empty((flat_coords[0].size, count), dtype=np.float32) for count in channels]
    for start in range(0, flat_coords[0].size, chunk):
        sl = slice(start, start + chunk)
        lows, weights = zip(*(axis_weights(c[sl], n) for c, n in zip(flat_coords, axes)))
        # Per axis the lower and upper node's offset into the rows and their weights, once for
        # all corners (per corner they cost a fifth of the look-ups on the epipolar air tables).
        offsets = [(low * stride, np.minimum(low + 1, n - 1) * stride) for low, stride, n in zip(lows, strides, axes)]
        factors = [(1.0 - w, w) for w in weights]
        linear = [axis for axis in range(len(axes)) if axis not in geometric_axes]
        # Each half of the axes' corner offsets and (linear) weights first, then a corner's as one
        # sum and one product of its halves' (per corner and axis they took half the look-up).
        halves = [_half_corners(offsets, factors, linear, part)
                  for part in (range(len(axes) // 2), range(len(axes) // 2, len(axes)))]
        partials = [{} for _ in channels]   # linear blends keyed by their corner on the geometric axes
        for (low_corner, low_index, low_weight), (high_corner, high_index, high_weight) in itertools.product(*halves):
            corner = low_corner + high_corner
            index = high_index if low_index is None else low_index + high_index
            weight = low_weight if high_weight is None else high_weight if low_weight is None else low_weight * high_weight
            key = tuple(corner[axis] for axis in geometric_axes)
            for count, (rows, width), partial in zip(channels, packed, partials):
                # The gathered rows are a fresh array: weighted and summed in place, no temporaries,
                # padding included (numpy's loops over a row's first ``count`` floats ran 3-4x
                # slower than over the whole contiguous rows).
                term = gather(rows, width, index)
                if weight is not None:
                    term *= weight[:, None]
                if key in partial:
                    partial[key] += term
                else:
                    partial[key] = term
        for out, partial in zip(outs, partials):
            for axis in geometric_axes:   # log-space blending is separable: the order does not matter
                w = weights[axis][:, None]
                partial = {key[1:]: geometric_lerp(partial[(0,) + key[1:]], partial[(1,) + key[1:]], w)
                           for key in partial if key[0] == 0}
            out[sl] = partial[()][:, :out.shape[1]]
    return [out.reshape(shape + (count,)) for out, count in zip(outs, channels)]


def _half_corners(offsets, factors, linear, axes):
    """(corner bits, row offset, weight or None) of every corner of the axes ``axes`` alone:
    the offsets summed and the factors of the ``linear`` ones multiplied."""
    found = []
    for corner in itertools.product((0, 1), repeat=len(axes)):
        index, weight = None, None
        for axis, bit in zip(axes, corner):
            index = offsets[axis][bit] if index is None else index + offsets[axis][bit]
            if axis in linear:
                factor = factors[axis][bit].astype(np.float32, copy=False)
                weight = factor if weight is None else weight * factor
        found.append((corner, index, weight))
    return found


def packed_side_by_side(tables):
    """packed_rows of tables of one grid (*axes, C_i) with their channels side by side, one
    record per node (interpolate_packed looks them all up with one gather per corner)."""
    return packed_rows(np.concatenate([np.asarray(t, dtype=np.float32) for t in tables], axis=-1))


def resample_matrix(x, n: int) -> np.ndarray:
    """(len(x), n) matrix that linearly interpolates an n-node axis at coordinates x."""
    i0, w = axis_weights(x, n)
    m = np.zeros((len(i0), n), dtype=np.float64)
    rows = np.arange(len(i0))
    m[rows, i0] += 1.0 - w
    m[rows, np.minimum(i0 + 1, n - 1)] += w
    return m


def resample_separable(table: np.ndarray, matrices) -> np.ndarray:
    """Apply one resample matrix per axis (None keeps an axis) to a (*axes, C) table."""
    out = np.asarray(table, dtype=np.float32)
    for axis, m in enumerate(matrices):
        if m is None:
            continue
        out = np.moveaxis(np.tensordot(m.astype(np.float32), out, axes=([1], [axis])), 0, axis)
    return np.ascontiguousarray(out, dtype=np.float32)


# Below this fraction of a node pair's larger value, geometric interpolation falls back to 0.
GEOMETRIC_FLOOR = np.float32(1e-9)
ABSOLUTE_FLOOR = np.float32(1e-30)      # ... and below this value
LOG_GEOMETRIC_FLOOR = np.float32(np.log(GEOMETRIC_FLOOR))
LOG_ABSOLUTE_FLOOR = np.float32(np.log(ABSOLUTE_FLOOR))


def geometric_lerp(low: np.ndarray, high: np.ndarray, weight) -> np.ndarray:
    """low^(1-w) high^w. Used along the sun zenith on the coarse grid of the higher orders
    (lut_gen.bake). At twilight their radiance falls by a constant factor per degree of sun depression;
    linear interpolation across the 32 sun nodes of that grid overestimated it (the second
    order 7% at sun -4 deg against the brute-force reference), geometric interpolation follows
    it (1%) and equals linear interpolation where the sky changes slowly."""
    return geometric_lerp_of_logs(floored_log(low), floored_log(high), weight)


def floored_log(values: np.ndarray) -> np.ndarray:
    """log(max(values, ABSOLUTE_FLOOR)) in float32: the logs geometric_lerp_of_logs blends."""
    return np.log(np.maximum(values, ABSOLUTE_FLOOR)).astype(np.float32, copy=False)


def geometric_lerp_of_logs(log_low: np.ndarray, log_high: np.ndarray, weight) -> np.ndarray:
    """geometric_lerp of exp(log_low) and exp(log_high), floors included, from logs taken once
    per table entry (floored_log) instead of twice per look-up: log is monotonic, so
    log(max(x, floor)) is the max of the logs."""
    floor = np.maximum(np.maximum(log_low, log_high) + LOG_GEOMETRIC_FLOOR, LOG_ABSOLUTE_FLOOR)
    low, high = np.maximum(log_low, floor), np.maximum(log_high, floor)
    high -= low
    high *= weight
    high += low
    return np.exp(high, out=high)


def resample_sun_geometric(table: np.ndarray, matrices) -> np.ndarray:
    """resample_separable with the sun-zenith axis (2) interpolated geometrically."""
    out = resample_separable(table, [m if axis != 2 else None for axis, m in enumerate(matrices)])
    if matrices[2] is None:
        return out
    i0, w = _axis_weights_of(matrices[2])
    low, high = np.take(out, i0, axis=2), np.take(out, i0 + 1, axis=2)
    return geometric_lerp(low, high, w[None, None, :, None, None])


def _axis_weights_of(matrix: np.ndarray):
    """(lower node, weight of the upper node) per row of a linear resample matrix."""
    n = matrix.shape[1]
    i0 = np.minimum(np.argmax(matrix > 0, axis=1), n - 2)
    return i0, matrix[np.arange(len(i0)), i0 + 1].astype(np.float32)
