"""EXR files of a bake: one file per table, the header carrying params, layout and hashes.

Files (all RGB 32-bit float, rows stored top to bottom as EXR does; the arrays here are
flipped so that row 0 is the bottom row, as Blender's image.pixels has it):

    single_scattering.exr        4D atlas (see atlas.py), Rayleigh single scattering / Rayleigh phase
    single_mie_scattering.exr    4D atlas, Mie single scattering without its phase function
    higher_order_scattering.exr  4D atlas, orders 2..N / Rayleigh phase
    multiple_scattering.exr      4D atlas, single + higher
    (all four divided by the ground-ray scale, lut_gen.tables.lookup)
    optical_depth.exr            (height x cos zenith): R, G, B = Rayleigh, Mie, ozone net density (m)
    ambient_skylight.exr         1 row: irradiance per unit sun against cos sun zenith

and, for a bake with fog only (FOG_FILES; the manifest lists them):

    single_fog_scattering.exr    4D atlas, fog single scattering without its phase function
    fog_optical_depth.exr        like optical_depth.exr, R = the fog's net density divided by the
                                 density at the ray's lowest point (lut_gen.tables.optical_depth)

Writes are atomic per file (temporary name + rename) and a directory that holds a different
bake is never overwritten unless asked. Every read checks format, layout version, that all
files come from the same bake, and the pixel hash.
"""
from __future__ import annotations

import hashlib
import json
import os
import struct
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Optional

import numpy as np

from ..tables import atlas
from . import exr_min, manifest
from .dir_lock import LOCK_NAME, locked
from .atomic import atomic_path, default_mode
from ..model.atmosphere import AtmosphereParams
from ..tables.lookup import Luts

# Bump when the meaning or packing of the stored data changes; old caches then read as stale.
# 2: single Mie scattering apart, ground-ray scale, spectral params.
LAYOUT_VERSION = 2
# Bump when the baker's numerics change (the same params then give different tables).
BAKER_VERSION = 11  # 5: exponential optical-depth segments, columns below the first row; 6: the orders' geometric tail; 7: fog; 8: the fog's ground-ray length; 9: fog nodes by opacity, the late orders on a coarser grid; 10: single scattering by parabolas between its nodes, its spectra log-linear between wavelengths; 11: the sun's net density near a point's horizon from the horizon band, the Earth's shadow exact under the table's first row

FILES = {
    "single": "single_scattering.exr",
    "single_mie": "single_mie_scattering.exr",
    "higher": "higher_order_scattering.exr",
    "multiple": "multiple_scattering.exr",
    "optical_depth": "optical_depth.exr",
    "ambient": "ambient_skylight.exr",
}
FOG_FILES = {
    "single_fog": "single_fog_scattering.exr",
    "fog_optical_depth": "fog_optical_depth.exr",
}
ALL_FILES = {**FILES, **FOG_FILES}
PREFIX = "ols."
EXR_MAGIC = b"\x76\x2f\x31\x01"


class LutError(Exception):
    """A bake directory or file that cannot be used, with a message that says why and what to do."""


def bake_key(params: AtmosphereParams, dims, optical_depth_dims, ambient_size: int, orders) -> str:
    """Hash of everything that determines a bake's content: the cache key."""
    doc = {"layout": LAYOUT_VERSION, "baker": BAKER_VERSION, "params": params.to_dict(),
           "dims": list(dims), "optical_depth": list(optical_depth_dims), "ambient": ambient_size,
           "orders": orders}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:32]


def luts_key(luts: Luts) -> str:
    return bake_key(luts.params, luts.dims, luts.optical_depth.shape[:2], luts.ambient.shape[0], luts.orders)


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


def _require_openexr():
    try:
        import OpenEXR
    except ImportError as exc:  # Blender's Python has no OpenEXR; the add-on loads images itself
        raise LutError("the OpenEXR package is missing: pip install OpenEXR (scripts/bootstrap.sh does)") from exc
    return OpenEXR


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


def bake_files(directory) -> list:
    """The file names of the bake in ``directory``: FILES, and FOG_FILES where its manifest
    lists them (a bake with fog)."""
    try:
        listed = manifest.read(directory)["files"]
    except (manifest.ManifestError, OSError, KeyError, TypeError):
        listed = {}
    return list(FILES.values()) + [name for name in FOG_FILES.values() if name in listed]


def _content_hash(image: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(image, dtype=np.float32).tobytes()).hexdigest()[:32]


def read_key(directory) -> Optional[str]:
    """Bake key of the bake stored in ``directory``, None when it holds none (no multiple file)."""
    path = Path(directory) / FILES["multiple"]
    if not path.exists():
        return None
    return _read_header(path).get(PREFIX + "bake_key")


_header_key_cache = {}


def _exists(path: Path) -> bool:
    """Path.exists, False where the folder cannot be searched (PermissionError otherwise)."""
    try:
        return path.exists()
    except OSError:
        return False


def _header_key(path: Path) -> Optional[str]:
    """The bake key in the header of table ``path`` (pure Python, cached like the hashes)."""
    stamp = manifest.file_stamp(path)
    if stamp not in _header_key_cache:
        _header_key_cache[stamp] = _read_header(path).get(PREFIX + "bake_key")
    return _header_key_cache[stamp]


def verify_bake(directory, key: Optional[str] = None) -> str:
    """The bake key of ``directory`` when it holds one whole, undamaged bake (lut_gen.store.manifest:
    every file present and hashing to the manifest written after the bake's last rename, and
    each file's own header naming that bake: a manifest written over files of several bakes
    fails too); ``key``: and that it is this bake. Raises LutError naming the file and the fix."""
    try:
        names = bake_files(directory)
        found = manifest.verify(directory, names, key)
        for filename in names:
            if _header_key(Path(directory) / filename) != found:
                raise manifest.ManifestError(f"{Path(directory) / filename} comes from another bake than its "
                                             f"manifest's ({found[:8]}): the directory mixes files of different bakes")
        return found
    except manifest.ManifestError as exc:
        if not _exists(Path(directory) / manifest.MANIFEST) and _exists(Path(directory) / FILES["multiple"]):
            reason = (f"{directory} has no bake manifest: the bake there was interrupted, or made by an older "
                      "version")
        else:
            reason = str(exc)
        raise LutError(f"{reason}; bake the tables again (Bake Tables in Blender, or python -m lut_gen bake "
                       f"--out {directory})") from None


def is_intact(directory, key: str) -> bool:
    """Whether ``directory`` holds bake ``key``, whole and undamaged (see verify_bake)."""
    try:
        verify_bake(directory, key)
    except LutError:
        return False
    return True


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
        header = _header_or_empty(directory / FILES["multiple"])
        if header:
            if can_overwrite:
                _check_layout(directory, header)
                _check_baker(directory, header, "choose another directory, or pass --overwrite to replace them")
            else:
                _check_layout(directory, header, f"re-bake into an empty {option} directory, or delete them")
                _check_baker(directory, header, f"re-bake into an empty {option} directory, or delete them")
        raise LutError(f"{directory} holds a different bake ({existing}); " + _remedy("it", option, can_overwrite))
    return directory


def read_header_params(directory):
    """(AtmosphereParams, dims) of the bake in ``directory`` from a header alone (cheap)."""
    header = _read_header(Path(directory) / FILES["multiple"])
    _check_layout(directory, header)
    try:
        params = AtmosphereParams.from_dict(json.loads(header[PREFIX + "params"])).validate()
        return params, tuple(json.loads(header[PREFIX + "dims"]))
    except (KeyError, ValueError, TypeError, RecursionError) as exc:
        raise LutError(f"{directory} has an invalid header ({exc}); re-bake it") from exc


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
    common = {
        PREFIX + "layout_version": str(LAYOUT_VERSION),
        PREFIX + "baker_version": str(BAKER_VERSION),
        PREFIX + "bake_key": key,
        PREFIX + "params": json.dumps(luts.params.to_dict(), sort_keys=True),
        PREFIX + "dims": json.dumps(list(luts.dims)),
        PREFIX + "orders": str(luts.orders),
        PREFIX + "orders_used": str(luts.orders_used),
        PREFIX + "storage": ("scattering tables hold linear Rec.709 radiance per unit sun divided by the Rayleigh "
                             "phase (single Mie: by nothing) and by the ground-ray scale"),
    }
    staged = []
    try:
        for name, image in _images(luts).items():
            header = dict(common)
            header.update({PREFIX + "table": name, PREFIX + "content_sha256": _content_hash(image),
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


def _check_layout(directory, header: dict, remedy: str = "re-bake into an empty directory, or pass --overwrite "
                                                          "to replace them"):
    version = header.get(PREFIX + "layout_version")
    if version != str(LAYOUT_VERSION):
        raise LutError(f"{directory} holds tables of layout version {version}; this version reads layout "
                       f"{LAYOUT_VERSION} (spectral tables with single Mie scattering apart): {remedy}")


# The first baker whose bakes hold the fog tables (FOG_FILES) where their params have fog.
FIRST_FOG_BAKER = 7


def _check_baker(directory, header: dict, remedy: str = "re-bake it (python -m lut_gen bake --out DIR "
                                                         "--overwrite, or Bake Tables in Blender)"):
    """A bake by another baker version holds other numbers for the same params (its key differs):
    say so, rather than that its header does not match its tables."""
    version = header.get(PREFIX + "baker_version")
    if version == str(BAKER_VERSION):
        return
    older = version is not None and version.isdigit() and int(version) < FIRST_FOG_BAKER
    what = " (the layout before fog: no fog tables)" if older else ""
    raise LutError(f"{directory} holds tables of baker version {version}{what}; this version reads baker "
                   f"{BAKER_VERSION}: {remedy}")


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
            key = _read_header(path).get(PREFIX + "bake_key")
        except LutError:
            continue
        if key:
            return key
    return UNREADABLE if present else None


def _read_problem(path: Path) -> str:
    try:
        _read_header(path)
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


def _header_or_empty(path: Path) -> dict:
    try:
        return _read_header(path)
    except LutError:
        return {}


def _read_header(path: Path) -> dict:
    """String attributes of the header (pure Python: also works in Blender, without OpenEXR)."""
    try:
        manifest.regular_file_stat(path)
        return exr_min.read_string_attributes(path)
    except manifest.ManifestError as exc:
        raise LutError(f"{exc}; re-bake with python -m lut_gen bake") from None
    except (OSError, ValueError, IndexError, struct.error) as exc:
        raise LutError(f"{path} is not a readable EXR file ({exc}); re-bake with python -m lut_gen bake") from exc


def _read_image(path: Path):
    OpenEXR = _require_openexr()
    try:
        manifest.regular_file_stat(path)
    except manifest.ManifestError as exc:
        raise LutError(f"{exc}; re-bake with python -m lut_gen bake --out {path.parent}") from None
    try:
        with OpenEXR.File(str(path)) as exr:
            header = dict(exr.header())
            channels = exr.channels()
            pixels = channels["RGB"].pixels if "RGB" in channels else None
    except Exception as exc:
        raise LutError(f"{path} is corrupt or truncated ({exc}); re-bake with python -m lut_gen bake") from exc
    if pixels is None:
        raise LutError(f"{path} has no RGB channels; it was not written by lut_gen")
    return header, np.asarray(pixels, dtype=np.float32)[::-1]


def load(directory, *, params: Optional[AtmosphereParams] = None) -> Luts:
    """Read a bake written by ``save``. ``params``: fail unless the bake was made with them."""
    directory = Path(directory)
    if not directory.is_dir():
        raise LutError(f"{directory} is not a directory of baked tables; bake one with python -m lut_gen bake --out {directory}")
    verify_bake(directory)
    images, headers = {}, {}
    present = bake_files(directory)
    for name, filename in ALL_FILES.items():
        if filename in present:
            headers[name], images[name] = _read_image(directory / filename)
    first = headers["multiple"]
    _check_layout(directory, first)
    _check_baker(directory, first)
    keys = {name: h.get(PREFIX + "bake_key") for name, h in headers.items()}
    if len(set(keys.values())) != 1:
        raise LutError(f"{directory} mixes files of different bakes ({keys}); re-bake it")
    for name, image in images.items():
        if headers[name].get(PREFIX + "content_sha256") != _content_hash(image):
            raise LutError(f"{directory / ALL_FILES[name]} does not match its content hash (damaged file); re-bake it")
    try:
        stored = AtmosphereParams.from_dict(json.loads(first[PREFIX + "params"])).validate()
        dims = tuple(json.loads(first[PREFIX + "dims"]))
        orders = first[PREFIX + "orders"]
        orders = int(orders) if orders.isdigit() else orders
        optical_depth = images["optical_depth"].transpose(1, 0, 2)
        if stored.has_fog != ("single_fog" in images and "fog_optical_depth" in images):
            raise LutError(f"{directory} lacks the fog tables its header asks for ({', '.join(FOG_FILES.values())}); "
                           "re-bake it")
        fog_column = (images["fog_optical_depth"].transpose(1, 0, 2)[..., :1] if stored.has_fog
                      else np.zeros_like(optical_depth[..., :1]))
        luts = Luts(params=stored,
                    single=atlas.unpack(images["single"], dims),
                    single_mie=atlas.unpack(images["single_mie"], dims),
                    single_fog=atlas.unpack(images["single_fog"], dims) if stored.has_fog else None,
                    higher=atlas.unpack(images["higher"], dims),
                    multiple=atlas.unpack(images["multiple"], dims),
                    optical_depth=np.ascontiguousarray(np.concatenate([optical_depth, fog_column], axis=-1)),
                    ambient=np.ascontiguousarray(images["ambient"][0]),
                    orders=orders, orders_used=int(first.get(PREFIX + "orders_used", orders)))
    except (KeyError, ValueError, TypeError, RecursionError) as exc:
        raise LutError(f"{directory} has an invalid header ({exc}); re-bake it") from exc
    problem = luts.value_problem()
    if problem:
        raise LutError(f"{directory}: {problem}; re-bake it")
    if luts_key(luts) != keys["multiple"]:
        raise LutError(f"{directory}: header does not match the stored tables; re-bake it")
    if params is not None and params.validate() != stored:
        diff = [k for k, v in params.to_dict().items() if stored.to_dict().get(k) != v]
        raise LutError(f"{directory} was baked with other atmosphere parameters ({', '.join(diff)} differ)")
    return luts
