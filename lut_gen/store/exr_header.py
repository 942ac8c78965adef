"""The EXR files of a bake and the header each carries: file names, layout and baker versions,
the bake key, the params and dims, read without OpenEXR (Blender's Python has none).

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

exr_write writes them, exr_read verifies and loads them.
"""
from __future__ import annotations

import hashlib
import json
import struct
from pathlib import Path
from typing import Optional

import numpy as np

from . import exr_min, manifest
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


def header_attributes(luts: Luts, key: str) -> dict:
    """The header attributes every table file of bake ``key`` carries (exr_write adds each
    file's own: its table, content hash and shape)."""
    return {
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


def content_hash(image: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(image, dtype=np.float32).tobytes()).hexdigest()[:32]


def read_key(directory) -> Optional[str]:
    """Bake key of the bake stored in ``directory``, None when it holds none (no multiple file)."""
    path = Path(directory) / FILES["multiple"]
    if not path.exists():
        return None
    return read_header(path).get(PREFIX + "bake_key")


_header_key_cache = {}


def header_key(path: Path) -> Optional[str]:
    """The bake key in the header of table ``path`` (pure Python, cached like the hashes)."""
    stamp = manifest.file_stamp(path)
    if stamp not in _header_key_cache:
        _header_key_cache[stamp] = read_header(path).get(PREFIX + "bake_key")
    return _header_key_cache[stamp]


def read_header_params(directory):
    """(AtmosphereParams, dims) of the bake in ``directory`` from a header alone (cheap)."""
    header = read_header(Path(directory) / FILES["multiple"])
    check_layout(directory, header)
    try:
        params = AtmosphereParams.from_dict(json.loads(header[PREFIX + "params"])).validate()
        return params, tuple(json.loads(header[PREFIX + "dims"]))
    except (KeyError, ValueError, TypeError, RecursionError) as exc:
        raise LutError(f"{directory} has an invalid header ({exc}); re-bake it") from exc


def check_layout(directory, header: dict, remedy: str = "re-bake into an empty directory, or pass --overwrite "
                                                         "to replace them"):
    version = header.get(PREFIX + "layout_version")
    if version != str(LAYOUT_VERSION):
        raise LutError(f"{directory} holds tables of layout version {version}; this version reads layout "
                       f"{LAYOUT_VERSION} (spectral tables with single Mie scattering apart): {remedy}")


# The first baker whose bakes hold the fog tables (FOG_FILES) where their params have fog.
FIRST_FOG_BAKER = 7


def check_baker(directory, header: dict, remedy: str = "re-bake it (python -m lut_gen bake --out DIR "
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


def header_or_empty(path: Path) -> dict:
    try:
        return read_header(path)
    except LutError:
        return {}


def read_header(path: Path) -> dict:
    """String attributes of the header (pure Python: also works in Blender, without OpenEXR)."""
    try:
        manifest.regular_file_stat(path)
        return exr_min.read_string_attributes(path)
    except manifest.ManifestError as exc:
        raise LutError(f"{exc}; re-bake with python -m lut_gen bake") from None
    except (OSError, ValueError, IndexError, struct.error) as exc:
        raise LutError(f"{path} is not a readable EXR file ({exc}); re-bake with python -m lut_gen bake") from exc
