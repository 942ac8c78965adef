"""Tables that travel with the .blend: a render-farm worker with an empty cache renders without
baking.

Packing stores each table file's bytes in its Blender image (Image.pack) and the bake manifest
(lut_gen.store.manifest: every file's SHA-256) as a property of the "multiple" image. On a machine
where the bake is not in the cache, the packed bytes are written back as a bake folder (the
cache's own, or a temporary one where the cache cannot be written), verified against the packed
manifest like any bake, and the images point at it. Damaged packed bytes are named and the
tables re-baked, as for a damaged cache.
"""
from __future__ import annotations

import json
import tempfile
from pathlib import Path

import bpy

from .... import lut_gen
from ....lut_gen.store import manifest
from ....lut_gen.store.atomic import atomic_path
from ....lut_gen.store.exr_header import ALL_FILES, FILES, LutError
from ....lut_gen.store.exr_read import is_intact, verify_bake
from . import luts
from .. import names



def _images(key: str) -> dict:
    """{table: image or None} of bake ``key``: every table of FILES, and the fog's where loaded
    (a bake with fog; one without has no fog images)."""
    images = {table: bpy.data.images.get(luts.image_name(table, key)) for table in ALL_FILES}
    return {table: image for table, image in images.items() if table in FILES or image is not None}


def is_packed(key: str) -> bool:
    images = _images(key)
    return all(image is not None and image.packed_file is not None for image in images.values()) \
        and bool(images["multiple"].get(names.PACKED_MANIFEST_KEY))


def pack(key: str) -> int:
    """Pack bake ``key``'s verified table files into their images; returns the bytes packed."""
    directory = luts.verify_wired(key)
    images = _images(key)
    text = (directory / manifest.MANIFEST).read_text()
    for image in images.values():
        if image.packed_file is None:
            image.pack()
    images["multiple"][names.PACKED_MANIFEST_KEY] = text
    return sum(image.packed_file.size for image in images.values())


def _write_bake(directory: Path, key: str, images: dict, text: str) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    for table, image in images.items():
        with atomic_path(directory / ALL_FILES[table]) as tmp:
            Path(tmp).write_bytes(image.packed_file.data)
    with atomic_path(directory / manifest.MANIFEST) as tmp:     # last, as a bake writes it
        Path(tmp).write_text(text)


def restore(key: str) -> Path:
    """Write the packed tables of bake ``key`` back as a verified bake folder and point the images
    at it; returns the folder. LutError naming the table when the packed bytes are damaged."""
    images = _images(key)
    text = images["multiple"].get(names.PACKED_MANIFEST_KEY) if images["multiple"] is not None else None
    if not is_packed(key) or not isinstance(text, str):
        raise LutError(f"the tables of bake {key[:8]} are not packed in this file")
    try:
        doc = json.loads(text)
    except ValueError:
        raise LutError(f"the packed bake manifest of bake {key[:8]} is damaged") from None
    if not isinstance(doc, dict) or doc.get("bake_key") != key or not isinstance(doc.get("files"), dict):
        raise LutError(f"the packed bake manifest does not describe bake {key[:8]}")
    for table, image in images.items():
        if manifest.bytes_sha256(image.packed_file.data) != doc["files"].get(ALL_FILES[table]):
            raise LutError(f"the packed table {ALL_FILES[table]} (image {image.name!r}) is damaged or comes "
                           "from another bake")
    directory = lut_gen.store.cache.default_cache_root() / key
    if not is_intact(directory, key):
        try:
            _write_bake(directory, key, images, text)
        except OSError:
            # A read-only or full cache: a folder of this Blender process's own.
            directory = Path(tempfile.mkdtemp(prefix=f"ols_packed_{key[:8]}_"))
            _write_bake(directory, key, images, text)
    verify_bake(directory, key)
    for table, image in images.items():
        image.filepath_raw = str(directory / ALL_FILES[table])     # still packed: renders read the bytes
    return directory
