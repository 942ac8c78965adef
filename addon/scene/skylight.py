"""The sky and the lit ground as equirectangular panoramas for lighting: "OLS Sky Light" and
"OLS Ground Light".

Non-camera rays of the OLS Sky world read these images instead of the 4D look-up and the ground
term (see nodes/sky.py): two texture fetches. They hold sky radiance and ground radiance per
unit sun (lut_gen's numpy look-ups, the node groups' twins), apart because the sky is scaled by
the scattering scale and the ground is not, for the current sun direction and camera height, so
they are recomputed when either changes (scene handlers) and after a re-bake, by
lut_gen.passes.panorama (its docstring has the pixel layout).
"""
from __future__ import annotations

import bpy
import numpy as np

from ...lut_gen.tables import atlas
from ...lut_gen.passes import panorama
from ...lut_gen.tables.lookup import Luts

IMAGE_NAME = "OLS Sky Light"
GROUND_IMAGE_NAME = "OLS Ground Light"
SIZE = (512, 256)
SUN_TOLERANCE = 1e-5        # radians-ish: below this the panorama is not recomputed
HEIGHT_TOLERANCE_M = 1.0

_tables = {}                # bake key -> Luts holding the tables read back from their images
_state = {}                 # image name -> (key, sun direction, height) it was computed for


def ensure_image(name=IMAGE_NAME):
    image = bpy.data.images.get(name)
    if image is None or tuple(image.size) != SIZE:
        if image is not None:
            bpy.data.images.remove(image)
        image = bpy.data.images.new(name, SIZE[0], SIZE[1], alpha=True, float_buffer=True)
        image.colorspace_settings.is_data = True
    return image


def ensure_ground_image():
    return ensure_image(GROUND_IMAGE_NAME)


def _pixels(image) -> np.ndarray:
    """(height, width, 3) of a loaded table image (rows bottom to top, as the arrays lut_gen
    writes)."""
    width, height = image.size
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(height, width, 4)[..., :3]


def _luts_from_images(key: str, images, params, dims) -> Luts:
    """Luts holding the tables the panoramas need, read back from their images: the multiple
    and single Mie atlases, the optical depth (stored height along x) and the ambient skylight.
    Kept packed: the ground look-ups otherwise copied the optical-depth table three times a
    sun move (10 ms each)."""
    if key not in _tables:
        multiple_image, mie_image, optical_image, ambient_image = images
        table = atlas.unpack(_pixels(multiple_image), dims)
        _tables.clear()
        _tables[key] = Luts(params, single=table, higher=np.zeros_like(table),
                            optical_depth=np.ascontiguousarray(_pixels(optical_image).transpose(1, 0, 2)),
                            ambient=np.ascontiguousarray(_pixels(ambient_image)[0]), multiple=table,
                            single_mie=atlas.unpack(_pixels(mie_image), dims)).keep_packed()
    return _tables[key]


def _write(image, radiance):
    rgba = np.ones(radiance.shape[:2] + (4,), dtype=np.float32)
    rgba[..., :3] = radiance
    image.pixels.foreach_set(rgba.ravel())
    image.update()


def update(key: str, images, params, dims, sun_direction, camera_height: float, force=False) -> bool:
    """Recompute the panoramas when the sun, the camera height or the bake changed; ``images``:
    the multiple, single Mie, optical-depth and ambient-skylight images of the bake."""
    image, ground_image = ensure_image(), ensure_ground_image()
    sun = np.asarray(sun_direction, dtype=np.float64)
    previous = _state.get(image.name)
    if (not force and previous is not None and previous[0] == key
            and np.abs(previous[1] - sun).max() < SUN_TOLERANCE and abs(previous[2] - camera_height) < HEIGHT_TOLERANCE_M):
        return False
    luts = _luts_from_images(key, images, params, dims)
    sky, ground = panorama.panoramas(luts, sun, camera_height, SIZE)
    _write(image, sky)
    _write(ground_image, ground)
    _state[image.name] = (key, sun, camera_height)
    return True


def forget():
    _tables.clear()
    _state.clear()
