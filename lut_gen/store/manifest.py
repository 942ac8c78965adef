"""The manifest of a bake directory: the proof that a directory holds one whole, undamaged bake.

``save`` removes the old manifest before it renames the new tables into place and writes the
new one (atomically) only after the last rename. The manifest names the bake key and the
SHA-256 of every table file's bytes. So a directory is an intact bake only when its manifest
exists and every file still hashes to it: a truncated or bit-flipped file, a table copied from
another bake, or a bake killed between its renames all fail, and are re-baked instead of being
taken for a cache hit. Hashing file bytes needs neither OpenEXR nor Blender, so the CLI, the
add-on and the batch renderer verify the same way. Hashes are cached per file by (device,
inode, size, mtime): a second check of an unchanged file reads only its stat.
"""
from __future__ import annotations

import hashlib
import json
import os
import stat
from pathlib import Path
from typing import Dict, Iterable, Optional

from .atomic import atomic_path

MANIFEST = "bake_manifest.json"
FORMAT = 1
_CHUNK = 1 << 22

_hash_cache: Dict[tuple, str] = {}


class ManifestError(Exception):
    """Why a directory is not an intact bake (exr_header and exr_read turn it into a LutError)."""


def regular_file_stat(path: Path) -> os.stat_result:
    """stat of ``path``, refusing anything but a regular file (a FIFO named like a table would
    block a reader forever; a directory or device is never a table)."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise ManifestError(f"{path} is missing") from None
    except OSError as exc:
        raise ManifestError(f"{path} cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise ManifestError(f"{path} is not a regular file")
    return info


def bytes_sha256(data: bytes) -> str:
    """SHA-256 of bytes held in memory (a table packed in a .blend), as file_sha256 of a file."""
    return hashlib.sha256(data).hexdigest()


def file_stamp(path) -> tuple:
    """What identifies this version of a regular file (path, device, inode, size, mtime): the
    key of the caches that spare re-reading an unchanged table."""
    info = regular_file_stat(Path(path))
    return (str(path), info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns)


def file_sha256(path) -> str:
    """SHA-256 of a regular file's bytes (cached by device, inode, size and mtime)."""
    path = Path(path)
    stamp = file_stamp(path)
    cached = _hash_cache.get(stamp)
    if cached is not None:
        return cached
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(_CHUNK), b""):
                digest.update(chunk)
    except OSError as exc:
        raise ManifestError(f"{path} cannot be read ({exc.strerror or exc})") from None
    _hash_cache[stamp] = digest.hexdigest()
    return _hash_cache[stamp]


def remove(directory) -> None:
    """Withdraw the manifest (before the tables it vouches for are replaced)."""
    try:
        os.unlink(Path(directory) / MANIFEST)
    except FileNotFoundError:
        pass


def write(directory, key: str, filenames: Iterable[str]) -> Path:
    directory = Path(directory)
    doc = {"format": FORMAT, "bake_key": key,
           "files": {name: file_sha256(directory / name) for name in sorted(filenames)}}
    path = directory / MANIFEST
    with atomic_path(path) as tmp:
        Path(tmp).write_text(json.dumps(doc, indent=1, sort_keys=True))
    return path


def read(directory) -> dict:
    path = Path(directory) / MANIFEST
    info = regular_file_stat(path)
    if info.st_size > 1 << 16:
        raise ManifestError(f"{path} is not a bake manifest (too large)")
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError, RecursionError) as exc:
        raise ManifestError(f"{path} is damaged ({type(exc).__name__})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("files"), dict) \
            or not isinstance(doc.get("bake_key"), str):
        raise ManifestError(f"{path} is not a bake manifest of this version")
    return doc


def verify(directory, filenames: Iterable[str], key: Optional[str] = None) -> str:
    """The bake key of ``directory`` when every one of ``filenames`` is present and hashes to
    the manifest (and the manifest's key is ``key``, when given). Raises ManifestError naming
    the first thing wrong."""
    directory = Path(directory)
    doc = read(directory)
    if key is not None and doc["bake_key"] != key:
        raise ManifestError(f"{directory} holds bake {doc['bake_key']}, not {key}")
    for name in filenames:
        expected = doc["files"].get(name)
        if expected is None:
            raise ManifestError(f"{directory / name} is not part of the bake its manifest describes")
        if file_sha256(directory / name) != expected:
            raise ManifestError(f"{directory / name} is damaged or comes from another bake "
                                "(its bytes do not match the bake manifest)")
    return doc["bake_key"]
