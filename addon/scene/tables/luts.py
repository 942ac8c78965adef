"""Baked tables as Blender images: loaded from a bake directory (lut_gen's EXR files),
named by bake key so that equal parameters share one set of images."""
from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np

from ....lut_gen.store.exr_header import ALL_FILES, LutError
from ....lut_gen.store.exr_read import bake_files, verify_bake
from .. import names





def file_stamp(path) -> str:
    """Size and modification time of a table file: tells an image whether it is stale."""
    info = Path(path).stat()
    return f"{info.st_size}:{info.st_mtime_ns}"


def image_name(table: str, key: str) -> str:
    return f"{names.TABLE_IMAGE_PREFIX} {table} {key[:8]}"


def load_images(directory) -> dict:
    """{table: bpy Image} for every file of the bake in ``directory``; reuses images already
    loaded for the same bake key and file. Raises LutError (from lut_gen) naming the file for a
    missing, damaged, incomplete or mixed bake: every file is verified against the bake's
    manifest first (lut_gen.store.manifest; hashes cached per file by size and mtime)."""
    directory = Path(directory)
    if not directory.is_dir():
        raise LutError(f"{directory} holds no baked tables; run Bake Tables first")
    key = verify_bake(directory)
    images = {}
    present = set(bake_files(directory))
    for table, filename in ALL_FILES.items():
        if filename not in present:     # the fog tables of a bake without fog
            continue
        path = directory / filename
        stamp = file_stamp(path)
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
            image[names.FILE_STAMP_KEY] = stamp
        if image.size[0] == 0 or image.get(names.FILE_STAMP_KEY) != stamp:
            # The file was missing when the .blend opened, or was re-baked since it was read.
            image.reload()
            image[names.FILE_STAMP_KEY] = stamp
        if image.size[0] == 0 or image.size[1] == 0:    # Blender could not decode it
            bpy.data.images.remove(image)
            raise LutError(f"{path} is damaged (Blender cannot decode it); bake the tables again")
        image.colorspace_settings.is_data = True      # raw numbers, no view transform
        image.alpha_mode = "NONE"
        # Blender gives loaded EXR files 16-bit floats on the GPU: net densities of low-sun paths
        # (over 65504 m) saturate there, and EEVEE lit the ground 22% too bright at sun 4 deg.
        image.use_half_precision = False
        images[table] = image
    fog_depth = images.get("fog_optical_depth")
    images["optical_depth"][names.FOG_DEPTH_IMAGE_KEY] = fog_depth.name if fog_depth is not None else ""
    return images


def fog_depth_image(optical_image, params):
    """The fog optical-depth image loaded with the optical-depth image ``optical_image`` (see
    names.FOG_DEPTH_IMAGE_KEY); None for params without fog. LutError when a bake with fog lost
    it (a .blend from before the fog)."""
    if not params.has_fog:
        return None
    fog = bpy.data.images.get(optical_image.get(names.FOG_DEPTH_IMAGE_KEY) or "")
    if fog is None:
        raise LutError(f"the fog's optical-depth table of {optical_image.name!r} is not loaded; run Set Up Scene")
    return fog


def wired_directory(key: str):
    """The folder the images of bake ``key`` were loaded from, None when they are not loaded."""
    image = bpy.data.images.get(image_name("multiple", key))
    return Path(bpy.path.abspath(image.filepath)).parent if image is not None and image.filepath else None


def verify_wired(key: str) -> Path:
    """The folder of bake ``key``'s images once its files are verified whole and undamaged (the
    manifest and every file's hash); LutError naming the file and the fix otherwise."""
    directory = wired_directory(key)
    if directory is None:
        raise LutError(f"the tables of bake {key[:8]} are not loaded in this file; run Set Up Scene")
    verify_bake(directory, key)
    return directory


def release_unused_images():
    """Remove OLS images no longer used by any node tree (after a re-bake swapped them)."""
    for image in list(bpy.data.images):
        if image.name.startswith(names.TABLE_IMAGE_PREFIX + " ") and image.users == 0:
            bpy.data.images.remove(image)


def _image_nodes(image):
    trees = list(bpy.data.node_groups)
    trees += [owner.node_tree for owner in (*bpy.data.materials, *bpy.data.worlds) if owner.node_tree]
    return [node for tree in trees for node in tree.nodes if getattr(node, "image", None) == image]


def write_data_image(name: str, pixels):
    """Write (height, width, 4) float pixels (rows bottom to top) into the float image ``name``,
    created or resized as needed, holding raw numbers (no colour management)."""
    height, width = pixels.shape[:2]
    image = bpy.data.images.get(name)
    users = []
    if image is not None and tuple(image.size) != (width, height):
        # Made anew: Image.scale left the pixel count stale (bpy 5.0.1: "expected sequence size
        # ..." on the next write, and in renders). The image nodes that showed it get the new one.
        users = _image_nodes(image)
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True, is_data=True)
        for node in users:
            node.image = image
    # Before writing: changing the colour space afterwards regenerates the buffer. Set only when
    # it differs: a set of the same value regenerates it too (0.025 s of every light-shaft frame).
    if not image.colorspace_settings.is_data:
        image.colorspace_settings.is_data = True
    if image.alpha_mode != "NONE":
        image.alpha_mode = "NONE"
    image.pixels.foreach_set(np.ascontiguousarray(pixels, dtype=np.float32).ravel())
    image.update()
    return image
