"""Reading a bake back: verify_bake checks a directory against its manifest (every file present,
hashing as listed, and its own header naming the manifest's bake); load then also checks each
file's layout and baker versions, its pixel hash, and that no table holds NaN or negative
values, and returns the Luts."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import numpy as np

from ..tables import atlas
from . import manifest
from .exr_header import (ALL_FILES, FILES, FOG_FILES, PREFIX, LutError, check_baker, check_layout, content_hash,
                         header_key, luts_key)
from ..model.atmosphere import AtmosphereParams
from ..tables.lookup import Luts


def bake_files(directory) -> list:
    """The file names of the bake in ``directory``: FILES, and FOG_FILES where its manifest
    lists them (a bake with fog)."""
    try:
        listed = manifest.read(directory)["files"]
    except (manifest.ManifestError, OSError, KeyError, TypeError):
        listed = {}
    return list(FILES.values()) + [name for name in FOG_FILES.values() if name in listed]


def _exists(path: Path) -> bool:
    """Path.exists, False where the folder cannot be searched (PermissionError otherwise)."""
    try:
        return path.exists()
    except OSError:
        return False


def verify_bake(directory, key: Optional[str] = None) -> str:
    """The bake key of ``directory`` when it holds one whole, undamaged bake (lut_gen.store.manifest:
    every file present and hashing to the manifest written after the bake's last rename, and
    each file's own header naming that bake: a manifest written over files of several bakes
    fails too); ``key``: and that it is this bake. Raises LutError naming the file and the fix."""
    try:
        names = bake_files(directory)
        found = manifest.verify(directory, names, key)
        for filename in names:
            if header_key(Path(directory) / filename) != found:
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


def _require_openexr():
    try:
        import OpenEXR
    except ImportError as exc:  # Blender's Python has no OpenEXR; the add-on loads images itself
        raise LutError("the OpenEXR package is missing: pip install OpenEXR (scripts/bootstrap.sh does)") from exc
    return OpenEXR


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
    check_layout(directory, first)
    check_baker(directory, first)
    keys = {name: h.get(PREFIX + "bake_key") for name, h in headers.items()}
    if len(set(keys.values())) != 1:
        raise LutError(f"{directory} mixes files of different bakes ({keys}); re-bake it")
    for name, image in images.items():
        if headers[name].get(PREFIX + "content_sha256") != content_hash(image):
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
    if params is not None and params != stored:
        diff = [k for k, v in params.to_dict().items() if stored.to_dict().get(k) != v]
        raise LutError(f"{directory} was baked with other atmosphere parameters ({', '.join(diff)} differ)")
    return luts
