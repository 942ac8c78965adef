"""The cloud layer as the numpy code reads it from the .blend: the map image's ranks (read once
per seed) and the frame's CloudLayer. Here, below the stages, because the per-frame work (the
epipolar tables) and Set Up Scene (the lighting panoramas) both need it."""
from __future__ import annotations

import bpy
import numpy as np

from ....lut_gen.clouds.layer import CloudLayer
from ...settings import Sanitized
from .. import names


def map_ranks(image) -> np.ndarray:
    """The map as the numpy code reads it: the image's red channel (rows bottom to top)."""
    size = tuple(image.size)
    pixels = np.empty(size[0] * size[1] * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(size[1], size[0], 4)[..., 0].copy()


def numpy_layer(scene, layer=None):
    """(CloudLayer, map ranks) for the numpy code while the layer is on, else None: ``layer``
    (the frame's, lut_gen.clouds.layer.CloudLayer) or the scene's. The ranks are read from the
    image once per seed."""
    settings = getattr(scene, "ols", None)
    image = bpy.data.images.get(names.CLOUD_MAP_IMAGE)
    if settings is None or not settings.clouds_enabled or image is None:
        return None
    key = (image.name, image.get(names.CLOUD_SEED_KEY))
    if _ranks.get("key") != key:
        _ranks.update(key=key, ranks=map_ranks(image))
    return layer or CloudLayer.of(Sanitized(settings)), _ranks["ranks"]


_ranks = {}
