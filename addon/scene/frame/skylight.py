"""The world's per-frame images: the sky and the lit ground as equirectangular panoramas for
lighting ("OLS Sky Light" and "OLS Ground Light") and the camera's twilight correction
("OLS Sky View", lut_gen.passes.sky_view), all for the frame's sun and camera height.

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

from ....lut_gen.clouds import air_map
from ....lut_gen.clouds import sky as cloud_sky
from ....lut_gen.passes import panorama, sky_view
from .. import names

SIZE = (512, 256)
SUN_TOLERANCE = 1e-5        # radians-ish: below this the panorama is not recomputed
HEIGHT_TOLERANCE_M = 1.0

_state = {}                 # image name -> (key, sun direction, height) it was computed for


def forget():
    """After a file load (or undo) the images may be new and blank: recompute them next time.
    A .blend keeps a generated image's name, not its pixels."""
    _state.clear()


def ensure_image(name=names.SKY_LIGHT_IMAGE, size=SIZE):
    image = bpy.data.images.get(name)
    if image is None or tuple(image.size) != tuple(size):
        if image is not None:
            bpy.data.images.remove(image)
        image = bpy.data.images.new(name, size[0], size[1], alpha=True, float_buffer=True)
        image.colorspace_settings.is_data = True
    return image


def ensure_ground_image():
    return ensure_image(names.GROUND_LIGHT_IMAGE)


def ensure_sky_view_image():
    return ensure_image(names.SKY_VIEW_IMAGE, (sky_view.NODES_AZIMUTH * len(sky_view.MEDIA), sky_view.NODES_VIEW))


def ensure_cloud_air_image():
    rows, columns = air_map.atlas_shape()
    return ensure_image(names.CLOUD_AIR_IMAGE, (columns, rows))


def _with_clouds(luts, clouds, sun, camera_height, sky, ground, camera_xy):
    """lut_gen.clouds.sky.composite split between the panoramas: the sky image (scaled by the
    scattering scale) loses what the clouds hide of the air behind them, and the ground image
    (scaled by the sun strength alone) gains the clouds' own light."""
    layer, ranks = clouds
    view = cloud_sky.view(luts, layer, ranks, camera_height, panorama.directions(*SIZE), sun, camera_xy)
    hidden = view.alpha[..., None] * view.sky_behind + cloud_sky.air_taken(view)
    behind_ground = 1.0 - np.where(camera_height >= layer.middle, view.alpha, 0.0)[..., None]
    return sky - hidden, ground * behind_ground + view.light


def write_sky_view(luts, camera_height: float, cos_sun: float):
    """Compute the camera's twilight correction into its image; returns it (a SkyView)."""
    view = sky_view.compute(luts, camera_height, cos_sun)
    image = ensure_sky_view_image()
    image.pixels.foreach_set(sky_view.image_pixels(view).ravel())
    image.update()
    return view


def _write(image, radiance):
    rgba = np.ones(radiance.shape[:2] + (4,), dtype=np.float32)
    rgba[..., :3] = radiance
    image.pixels.foreach_set(rgba.ravel())
    image.update()


def _update_cloud_air(info, sun, camera_height, layer, force):
    """The camera rays' air map (lut_gen.clouds.air_map) when the sun, the camera height, the
    layer (its mean over the map: coverage, height, thickness, density) or the bake changed;
    the map's seed, scale and offset and the camera's x, y leave it."""
    image = ensure_cloud_air_image()
    key = (info.key, layer.coverage, layer.base, layer.thickness, layer.density)
    if not force and _current(image, key, sun, camera_height):
        return
    _write(image, air_map.compute(info.image_luts(), layer, camera_height, sun))
    _state[image.name] = (key, sun, camera_height)


def _update_sky_view(info, luts, sun, camera_height, force):
    """The camera's twilight correction, recomputed only when the sun, the camera height or the
    bake changed (a cloud change re-mixes the panoramas but leaves it)."""
    image = ensure_sky_view_image()
    if not force and _current(image, info.key, sun, camera_height):
        return _state[image.name][3]
    view = write_sky_view(luts, camera_height, float(sun[2]))
    _state[image.name] = (info.key, sun, camera_height, view)
    return view


def _current(image, key, sun, camera_height) -> bool:
    """The image was last computed for ``key`` and this sun and camera height (within the
    tolerances)."""
    previous = _state.get(image.name)
    return (previous is not None and previous[0] == key and np.abs(previous[1] - sun).max() < SUN_TOLERANCE
            and abs(previous[2] - camera_height) < HEIGHT_TOLERANCE_M)


def update(info, sun_direction, camera_height: float, force=False, clouds=None, camera_xy=(0.0, 0.0)) -> bool:
    """Recompute the panoramas when the sun, the camera height, the clouds or the bake changed;
    ``info``: the wired bake (tables.wired_bake.BakeInfo); ``clouds``: (CloudLayer, map ranks)
    while the cloud layer is on."""
    image, ground_image = ensure_image(), ensure_ground_image()
    sun = np.asarray(sun_direction, dtype=np.float64)
    # The camera's x, y matter only to the clouds (where the map is read).
    cloud_key = None if clouds is None else (clouds[0], tuple(camera_xy))
    if clouds is not None:
        _update_cloud_air(info, sun, camera_height, clouds[0], force)
    if not force and _current(image, (info.key, cloud_key), sun, camera_height):
        return False
    luts = info.image_luts()
    view = _update_sky_view(info, luts, sun, camera_height, force)
    sky, ground = panorama.panoramas(luts, sun, camera_height, SIZE)
    # Lighting sees the same corrected sky as the camera.
    directions = panorama.directions(*SIZE)
    sky = sky + sky_view.correction_at(luts.params, view, directions[..., 2], directions @ sun)
    if clouds is not None:
        sky, ground = _with_clouds(luts, clouds, sun, camera_height, sky, ground, camera_xy)
    _write(image, sky)
    _write(ground_image, ground)
    _state[image.name] = ((info.key, cloud_key), sun, camera_height)
    return True
