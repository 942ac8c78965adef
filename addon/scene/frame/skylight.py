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

from ....lut_gen.passes import panorama
from .. import names

SIZE = (512, 256)
SUN_TOLERANCE = 1e-5        # radians-ish: below this the panorama is not recomputed
HEIGHT_TOLERANCE_M = 1.0

_state = {}                 # image name -> (key, sun direction, height) it was computed for


def ensure_image(name=names.SKY_LIGHT_IMAGE):
    image = bpy.data.images.get(name)
    if image is None or tuple(image.size) != SIZE:
        if image is not None:
            bpy.data.images.remove(image)
        image = bpy.data.images.new(name, SIZE[0], SIZE[1], alpha=True, float_buffer=True)
        image.colorspace_settings.is_data = True
    return image


def ensure_ground_image():
    return ensure_image(names.GROUND_LIGHT_IMAGE)


def _write(image, radiance):
    rgba = np.ones(radiance.shape[:2] + (4,), dtype=np.float32)
    rgba[..., :3] = radiance
    image.pixels.foreach_set(rgba.ravel())
    image.update()


def update(info, sun_direction, camera_height: float, force=False) -> bool:
    """Recompute the panoramas when the sun, the camera height or the bake changed; ``info``:
    the wired bake (tables.wired_bake.BakeInfo)."""
    image, ground_image = ensure_image(), ensure_ground_image()
    sun = np.asarray(sun_direction, dtype=np.float64)
    previous = _state.get(image.name)
    if (not force and previous is not None and previous[0] == info.key
            and np.abs(previous[1] - sun).max() < SUN_TOLERANCE and abs(previous[2] - camera_height) < HEIGHT_TOLERANCE_M):
        return False
    luts = info.image_luts()
    sky, ground = panorama.panoramas(luts, sun, camera_height, SIZE)
    _write(image, sky)
    _write(ground_image, ground)
    _state[image.name] = (info.key, sun, camera_height)
    return True

    _state.clear()
