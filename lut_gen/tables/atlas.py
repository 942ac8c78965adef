"""Packing of the 4D scattering tables into 2D images Blender can filter.

Layout (pixel rows counted bottom to top, Blender's convention; x to the right):

    tile column  = sun-view node   i_t  (n_t tiles across)
    tile row     = height node     i_h  (n_h tiles up)
    inside tile  : x = view-zenith node i_a (n_a), y = sun-zenith node i_s (n_s)

    pixel (x, y) = (i_t * n_a + i_a,  i_h * n_s + i_s);  image size (n_t*n_a) x (n_h*n_s)

For the default 32 x 128 x 64 x 16 tables this is a 2048 x 2048 image. A look-up filters the
view- and sun-zenith axes in hardware (bilinear inside one tile, texture coordinate
((i_t*n_a + x_a + 0.5) / W, (i_h*n_s + x_s + 0.5) / H) with x_a, x_s clamped to the tile) and
blends the four tiles of the neighbouring height and sun-view nodes by hand (Yusov 2013 Listing 1
does the same with one manual axis in a 3D texture). The view-zenith axis never blends across its
horizon seam (Yusov 2013 Listing 2 keeps x_a inside one half).
"""
from __future__ import annotations

import numpy as np


def atlas_shape(dims):
    n_h, n_a, n_s, n_t = dims
    return n_h * n_s, n_t * n_a


def pack(table: np.ndarray) -> np.ndarray:
    """(n_h, n_a, n_s, n_t, C) -> (n_h*n_s, n_t*n_a, C), row 0 at the bottom."""
    n_h, n_a, n_s, n_t, c = table.shape
    return np.ascontiguousarray(table.transpose(0, 2, 3, 1, 4).reshape(n_h * n_s, n_t * n_a, c))


def unpack(image: np.ndarray, dims) -> np.ndarray:
    n_h, n_a, n_s, n_t = dims
    if image.shape[:2] != atlas_shape(dims):
        raise ValueError(f"atlas is {image.shape[1]}x{image.shape[0]}, layout {dims} needs "
                         f"{atlas_shape(dims)[1]}x{atlas_shape(dims)[0]}")
    c = image.shape[2]
    return np.ascontiguousarray(image.reshape(n_h, n_s, n_t, n_a, c).transpose(0, 3, 1, 2, 4))
