"""Baked tables as Blender images: loaded from a bake directory (lut_gen's EXR files),
named by bake key so that equal parameters share one set of images."""
from __future__ import annotations

from pathlib import Path

import bpy

from ...lut_gen.exr_io import FILES, LutError, read_key

IMAGE_PREFIX = "OLS"


def image_name(table: str, key: str) -> str:
    return f"{IMAGE_PREFIX} {table} {key[:8]}"


def load_images(directory) -> dict:
    """{table: bpy Image} for every file of the bake in ``directory``; reuses images already
    loaded for the same bake key. Raises LutError (from lut_gen) for a missing or damaged bake."""
    directory = Path(directory)
    key = read_key(directory)
    if key is None:
        raise LutError(f"{directory} holds no baked tables; run Bake Tables first")
    images = {}
    for table, filename in FILES.items():
        path = directory / filename
        if not path.exists():
            raise LutError(f"{path} is missing; bake the tables again")
        name = image_name(table, key)
        image = bpy.data.images.get(name)
        if image is None or bpy.path.abspath(image.filepath) != str(path):
            if image is not None:
                bpy.data.images.remove(image)
            try:
                image = bpy.data.images.load(str(path))
            except RuntimeError as exc:
                raise LutError(f"{path} cannot be read ({exc}); bake the tables again") from None
            image.name = name
        if image.size[0] == 0:                          # e.g. the file was missing when the .blend opened
            image.reload()
        if image.size[0] == 0 or image.size[1] == 0:    # Blender could not decode it
            bpy.data.images.remove(image)
            raise LutError(f"{path} is damaged (Blender cannot decode it); bake the tables again")
        image.colorspace_settings.is_data = True      # raw numbers, no view transform
        image.alpha_mode = "NONE"
        # Blender gives loaded EXR files 16-bit floats on the GPU: net densities of low-sun paths
        # (over 65504 m) saturate there, and EEVEE lit the ground 22% too bright at sun 4 deg.
        image.use_half_precision = False
        images[table] = image
    return images


def release_unused_images():
    """Remove OLS images no longer used by any node tree (after a re-bake swapped them)."""
    for image in list(bpy.data.images):
        if image.name.startswith(IMAGE_PREFIX + " ") and image.users == 0:
            bpy.data.images.remove(image)


def write_data_image(name: str, pixels):
    """Write (height, width, 4) float pixels (rows bottom to top) into the float image ``name``,
    created or resized as needed, holding raw numbers (no colour management)."""
    import numpy as np
    height, width = pixels.shape[:2]
    image = bpy.data.images.get(name)
    if image is None:
        image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True, is_data=True)
    elif tuple(image.size) != (width, height):
        image.scale(width, height)
    # Before writing: changing the colour space afterwards regenerates the buffer.
    image.colorspace_settings.is_data = True
    image.alpha_mode = "NONE"
    image.pixels.foreach_set(np.ascontiguousarray(pixels, dtype=np.float32).ravel())
    image.update()
    return image
