"""The sky as an equirectangular panorama for lighting: "OLS Sky Light".

Non-camera rays of the OLS Sky world read this image instead of the 4D look-up (see
nodes/sky.py). It holds sky radiance per unit sun (lut_gen's numpy look-up, the node groups'
twin) for the current sun direction and camera height, so it is recomputed when either
changes (scene handlers) and after a re-bake. Pixel (i, j) of a W x H image (rows bottom to
top) looks at azimuth ((i + 0.5) / W - 0.5) 2 pi from +Y toward +X and elevation
((j + 0.5) / H - 0.5) pi.
"""
from __future__ import annotations

import bpy
import numpy as np

from ...lut_gen import atlas
from ...lut_gen.sampling import Luts

IMAGE_NAME = "OLS Sky Light"
SIZE = (512, 256)
SUN_TOLERANCE = 1e-5        # radians-ish: below this the panorama is not recomputed
HEIGHT_TOLERANCE_M = 1.0

_tables = {}                # bake key -> Luts holding the multiple table read back from its image
_state = {}                 # image name -> (key, sun direction, height) it was computed for


def panorama_directions(width: int, height: int) -> np.ndarray:
    azimuth = ((np.arange(width) + 0.5) / width - 0.5) * 2 * np.pi
    elevation = ((np.arange(height) + 0.5) / height - 0.5) * np.pi
    elevation, azimuth = np.meshgrid(elevation, azimuth, indexing="ij")
    return np.stack([np.sin(azimuth) * np.cos(elevation), np.cos(azimuth) * np.cos(elevation),
                     np.sin(elevation)], axis=-1)


def sky_panorama(luts: Luts, sun_direction, camera_height: float, size=SIZE) -> np.ndarray:
    """(H, W, 3) sky radiance per unit sun, rows bottom to top."""
    d = panorama_directions(*size)
    sun = np.asarray(sun_direction, dtype=np.float64)
    return luts.sky_radiance(max(camera_height, 0.0), d[..., 2], sun[2], d @ sun)


def ensure_image():
    image = bpy.data.images.get(IMAGE_NAME)
    if image is None or tuple(image.size) != SIZE:
        if image is not None:
            bpy.data.images.remove(image)
        image = bpy.data.images.new(IMAGE_NAME, SIZE[0], SIZE[1], alpha=True, float_buffer=True)
        image.colorspace_settings.is_data = True
    return image


def _table_from_image(image, dims) -> np.ndarray:
    width, height = image.size
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return atlas.unpack(pixels.reshape(height, width, 4)[..., :3], dims)


def _luts_from_images(key: str, images, params, dims) -> Luts:
    """Luts holding the multiple and single Mie tables read back from their images."""
    if key not in _tables:
        multiple_image, mie_image = images
        table = _table_from_image(multiple_image, dims)
        empty = np.zeros((2, 2, 3), np.float32)
        _tables.clear()
        _tables[key] = Luts(params, single=table, higher=np.zeros_like(table), optical_depth=empty,
                            ambient=empty[0], multiple=table, single_mie=_table_from_image(mie_image, dims))
    return _tables[key]


def update(key: str, images, params, dims, sun_direction, camera_height: float, force=False) -> bool:
    """Recompute the panorama when the sun, the camera height or the bake changed; ``images``:
    the multiple and single Mie atlases."""
    image = ensure_image()
    sun = np.asarray(sun_direction, dtype=np.float64)
    previous = _state.get(image.name)
    if (not force and previous is not None and previous[0] == key
            and np.abs(previous[1] - sun).max() < SUN_TOLERANCE and abs(previous[2] - camera_height) < HEIGHT_TOLERANCE_M):
        return False
    radiance = sky_panorama(_luts_from_images(key, images, params, dims), sun, camera_height)
    rgba = np.ones(radiance.shape[:2] + (4,), dtype=np.float32)
    rgba[..., :3] = radiance
    image.pixels.foreach_set(rgba.ravel())
    image.update()
    _state[image.name] = (key, sun, camera_height)
    return True


def forget():
    _tables.clear()
    _state.clear()
