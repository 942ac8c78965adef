"""The cloud layer's images and settings in the .blend: the cloud map (from the seed) and the
higher-orders table, both packed into the file so that every farm worker renders the same
clouds, and the CloudLayer the numpy code reads from scene.ols."""
from __future__ import annotations

import bpy
import numpy as np

from ...lut_gen.clouds import field, slab
from ...lut_gen.clouds.layer import CloudLayer
from . import names
from .setup import drivers

# Sky-group input <- scene.ols control (the offset's two components are driven one by one).
SKY_INPUTS = {"Cloud Coverage": "cloud_coverage", "Cloud Base": "cloud_base",
              "Cloud Thickness": "cloud_thickness", "Cloud Density": "cloud_density", "Cloud Scale": "cloud_scale"}

SEED_KEY = "ols_cloud_seed"         # the seed the map image holds


def _float_image(name, width, height):
    image = bpy.data.images.get(name)
    if image is None or tuple(image.size) != (width, height) or not image.is_float:
        if image is not None:
            bpy.data.images.remove(image)
        image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
        image.colorspace_settings.is_data = True
    return image


def _fill(image, rgba):
    image.pixels.foreach_set(np.ascontiguousarray(rgba, dtype=np.float32).ravel())
    image.update()
    image.pack()


def ensure_map_image(seed: int):
    """The "OLS Cloud Map" image for ``seed``: generated (0.9 s) only when the seed changed."""
    image = _float_image(names.CLOUD_MAP_IMAGE, field.MAP_SIZE, field.MAP_SIZE)
    if image.get(SEED_KEY) != int(seed) or not image.packed_file:
        ranks = field.cloud_map(int(seed))
        rgba = np.ones(ranks.shape + (4,), dtype=np.float32)
        rgba[..., :3] = ranks[..., None]
        _fill(image, rgba)
        image[SEED_KEY] = int(seed)
    return image


def map_ranks(image) -> np.ndarray:
    """The map as the numpy code reads it: the image's red channel (rows bottom to top)."""
    size = tuple(image.size)
    pixels = np.empty(size[0] * size[1] * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(size[1], size[0], 4)[..., 0].copy()


def ensure_table_image():
    pixels = slab.table_pixels()
    image = _float_image(names.CLOUD_TABLE_IMAGE, pixels.shape[1], pixels.shape[0])
    _fill(image, pixels)
    return image


def layer_of(settings) -> CloudLayer:
    """The scene's cloud layer, clamped as the drivers clamp it (settings: scene.ols, Sanitized)."""
    return CloudLayer(coverage=settings.cloud_coverage, base=settings.cloud_base, thickness=settings.cloud_thickness,
                      density=settings.cloud_density, scale=settings.cloud_scale,
                      offset=tuple(settings.cloud_offset)[:2], seed=int(settings.cloud_seed)).clamped()


def seed_of(scene) -> int:
    settings = getattr(scene, "ols", None)
    return 0 if settings is None else int(settings.cloud_seed)


def drive_sky_inputs(group, scene):
    """Drivers from scene.ols onto the sky group's cloud inputs, clamped as the controls are:
    keyframed controls (the offset, for wind) then animate the clouds in every render, farm
    chunks included."""
    drivers.drive_switch(group.inputs["Clouds"], scene, "clouds_enabled")
    for socket, name in SKY_INPUTS.items():
        drivers.drive_scene_setting(group.inputs[socket], scene, name)
    for axis in range(2):
        drivers.drive_vector_setting(group.inputs["Cloud Offset"], axis, scene, "cloud_offset")


def sync(scene):
    """After the seed changed: the map for the new seed (the groups read the image in place)."""
    if bpy.data.node_groups.get(names.CLOUDS_GROUP) is not None:
        ensure_map_image(seed_of(scene))
