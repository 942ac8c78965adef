"""Writing a bake: every table of a Luts as an EXR file (exr_header names them and fills their
headers), then the bake manifest. Writes are atomic per file (temporary name + rename; no
manifest while the files change), a directory that holds a different bake is never overwritten
unless asked, and a file named like a table that lut_gen did not write is never replaced."""
from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..tables import atlas
from . import exr_min, manifest
from .dir_lock import LOCK_NAME, locked
from .atomic import atomic_path, default_mode
from .exr_header import (ALL_FILES, EXR_MAGIC, FILES, FOG_FILES, PREFIX, LutError, check_baker, check_layout,
                         content_hash, header_attributes, header_or_empty, luts_key, read_header)
from .exr_read import is_intact
from ..tables.lookup import Luts


def _openexr_or_none():
    try:
        import OpenEXR
    except ImportError:
        return None
    return OpenEXR


def _write_rgb(OpenEXR, path, rgb_top_down, strings: dict):
    """ZIP-compressed through OpenEXR when it is installed; else lut_gen's own uncompressed
    writer (inside Blender). Both read back bit-exactly."""
    pixels = np.ascontiguousarray(rgb_top_down, dtype=np.float32)
    if OpenEXR is None:
        with open(path, "wb") as f:
            f.write(exr_min.encode_rgb_float(pixels, strings))
        return
    header = dict(strings, compression=OpenEXR.ZIP_COMPRESSION, type=OpenEXR.scanlineimage)
    with OpenEXR.File(header, {"RGB": pixels}) as exr:
        exr.write(str(path))


def write_rgb(path, rgb_bottom_up) -> Path:
    """A linear RGB image (rows bottom to top, as Blender's) as an EXR file (atomic write)."""
    with atomic_path(path) as tmp:
        _write_rgb(_openexr_or_none(), tmp, np.asarray(rgb_bottom_up)[::-1], {})
    return Path(path)


def _images(luts: Luts) -> dict:
    images = {
        "single": atlas.pack(luts.single),
        "single_mie": atlas.pack(luts.single_mie),
        "higher": atlas.pack(luts.higher),
        "multiple": atlas.pack(luts.multiple),
        "optical_depth": np.ascontiguousarray(luts.optical_depth[..., :3].transpose(1, 0, 2)),  # x = height
        "ambient": luts.ambient[None, :, :],
    }
    if luts.single_fog is not None:
        images["single_fog"] = atlas.pack(luts.single_fog)
        fog = np.zeros_like(luts.optical_depth[..., :3])
        fog[..., 0] = luts.optical_depth[..., 3]
        images["fog_optical_depth"] = np.ascontiguousarray(fog.transpose(1, 0, 2))
    return images


@contextmanager
def removed_if_left_empty(directory):
    """A bake that fails leaves nothing behind: a directory it created is removed again when
    nothing but its lock file is in it."""
    directory = Path(directory)
    existed = directory.exists()
    try:
        yield
    except BaseException:
        if not existed:
            try:
                (directory / LOCK_NAME).unlink(missing_ok=True)
                directory.rmdir()
            except OSError:
                pass
        raise


def _remedy(what: str, option: str, can_overwrite: bool) -> str:
    """What the user can do about a directory holding another bake: the command's way out."""
    if can_overwrite:
        return f"choose another directory, or pass --overwrite to replace {what}"
    return f"choose another {option} directory, or delete {what}"


def check_output_directory(directory, key: str, *, overwrite: bool = False, option: str = "--out",
                           can_overwrite: bool = True) -> Path:
    """Create ``directory`` if needed and make sure a bake with ``key`` may be written there:
    writable, and not holding a different bake unless ``overwrite``. Cheap: call it before
    a long bake so that a bad --out fails at once. ``option`` and ``can_overwrite``: how the
    calling command names the directory and whether it has --overwrite (the messages say so)."""
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise LutError(f"cannot create output directory {directory}: {exc.strerror}") from exc
    if not os.access(directory, os.W_OK | os.X_OK):
        raise LutError(f"output directory {directory} is not writable; choose another with {option}")
    for filename in ALL_FILES.values():
        _refuse_foreign_file(directory / filename)
    existing = _existing_key(directory)
    if existing == UNREADABLE and not overwrite:
        raise LutError(f"{directory} holds damaged tables whose bake cannot be told "
                       f"({_read_problem(directory / FILES['multiple'])}); "
                       + _remedy("them", option, can_overwrite))
    if existing not in (None, key) and not overwrite:
        header = header_or_empty(directory / FILES["multiple"])
        if header:
            if can_overwrite:
                check_layout(directory, header)
                check_baker(directory, header, "choose another directory, or pass --overwrite to replace them")
            else:
                check_layout(directory, header, f"re-bake into an empty {option} directory, or delete them")
                check_baker(directory, header, f"re-bake into an empty {option} directory, or delete them")
        raise LutError(f"{directory} holds a different bake ({existing}); " + _remedy("it", option, can_overwrite))
    return directory


def save(luts: Luts, directory, *, overwrite: bool = False) -> Path:
    """Write every table of ``luts`` to ``directory`` (created if missing)."""
    OpenEXR = _openexr_or_none()
    directory = Path(directory)
    key = luts_key(luts)
    with locked(check_output_directory(directory, key, overwrite=overwrite)):
        # Again under the lock: a bake that finished meanwhile may have put another bake here,
        # or this very bake: then nothing is rewritten (farm workers sharing a cold cache each
        # bake; rewriting the folder under a worker that already verified it, and renders from
        # it, would withdraw its manifest mid-render).
        check_output_directory(directory, key, overwrite=overwrite)
        if is_intact(directory, key):
            return directory
        _remove_stale_temporaries(directory)
        _write_tables(OpenEXR, directory, key, luts)
    return directory


def _write_tables(OpenEXR, directory: Path, key: str, luts: Luts):
    common = header_attributes(luts, key)
    staged = []
    try:
        for name, image in _images(luts).items():
            header = dict(common)
            header.update({PREFIX + "table": name, PREFIX + "content_sha256": content_hash(image),
                           PREFIX + "shape": json.dumps(list(image.shape))})
            fd, tmp = tempfile.mkstemp(prefix=f".{ALL_FILES[name]}.", suffix=".tmp", dir=directory)
            os.close(fd)
            staged.append((tmp, directory / ALL_FILES[name]))
            _write_rgb(OpenEXR, tmp, image[::-1], header)
            os.chmod(tmp, default_mode())
        # No manifest while the files change: a bake killed between two renames leaves a
        # directory that reads as damaged, not as a mix taken for a whole bake.
        manifest.remove(directory)
        for tmp, final in staged:
            os.replace(tmp, final)
        written = [final.name for _, final in staged]
        for name in FOG_FILES.values():         # an earlier bake's fog tables, overwritten by one without
            if name not in written:
                (directory / name).unlink(missing_ok=True)
        manifest.write(directory, key, written)
    except (OSError, RuntimeError, manifest.ManifestError) as exc:
        # OpenEXR reports a full disk as a RuntimeError. The old bake stays: nothing was renamed.
        raise LutError(f"cannot write tables to {directory}: {exc}") from exc
    finally:
        for tmp, _ in staged:
            if os.path.exists(tmp):
                os.unlink(tmp)


UNREADABLE = "unreadable files"


def _existing_key(directory: Path):
    """Whose bake the directory holds: its manifest's key, else the key in the header of any
    readable table; UNREADABLE when there are tables but none says; None when there are none."""
    try:
        return manifest.read(directory)["bake_key"]
    except manifest.ManifestError:
        pass
    present = [directory / name for name in ALL_FILES.values() if os.path.lexists(directory / name)]
    for path in present:
        try:
            key = read_header(path).get(PREFIX + "bake_key")
        except LutError:
            continue
        if key:
            return key
    return UNREADABLE if present else None


def _read_problem(path: Path) -> str:
    try:
        read_header(path)
    except LutError as exc:
        return str(exc).split(";")[0]
    return f"{path.name} is readable"


def _refuse_foreign_file(path: Path):
    """A file named like a table that lut_gen did not write belongs to someone else: never
    replace it. Ours, even damaged, is a regular file that starts with the EXR magic number and
    holds our header attributes near its start (or is empty: nothing to lose)."""
    if not os.path.lexists(path):
        return
    try:
        manifest.regular_file_stat(path)
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except (manifest.ManifestError, OSError):
        head = None
    if head is not None and (head == b"" or (head.startswith(EXR_MAGIC) and PREFIX.encode() in head)):
        return
    raise LutError(f"{path} exists and was not written by lut_gen; move it away or choose another "
                   "directory (lut_gen never replaces it)")


def _remove_stale_temporaries(directory: Path):
    """Temporary files a killed bake left (".<table>.XXXX.tmp"); called under the directory lock,
    so no running bake owns them."""
    for filename in ALL_FILES.values():
        for stale in directory.glob(f".{filename}.*.tmp"):
            try:
                stale.unlink()
            except OSError:
                pass


