"""Minimal PNG writer (8-bit RGB), so previews need nothing beyond numpy."""
from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from .atomic import atomic_path


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png(rgb8: np.ndarray, software: str | None = None) -> bytes:
    """(height, width, 3) uint8, row 0 at the top; ``software`` goes into a tEXt chunk."""
    if rgb8.dtype != np.uint8 or rgb8.ndim != 3 or rgb8.shape[2] != 3:
        raise ValueError("encode_png needs a (height, width, 3) uint8 array")
    h, w, _ = rgb8.shape
    raw = np.concatenate([np.zeros((h, 1), np.uint8), rgb8.reshape(h, w * 3)], axis=1).tobytes()
    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    text = _chunk(b"tEXt", b"Software\x00" + software.encode("latin-1")) if software else b""
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) + text + _chunk(b"IDAT", zlib.compress(raw, 6))
            + _chunk(b"IEND", b""))


def written_by(path, software: str) -> bool:
    """True when ``path`` is a PNG whose tEXt "Software" chunk is ``software``."""
    try:
        data = Path(path).read_bytes()[:4096]
    except OSError:
        return False
    return data.startswith(b"\x89PNG") and b"tEXtSoftware\x00" + software.encode("latin-1") in data


def write_png(path, rgb8: np.ndarray, software: str | None = None) -> Path:
    """Write atomically (temporary file + rename)."""
    path = Path(path)
    data = encode_png(rgb8, software)
    with atomic_path(path, mode=0o644) as tmp:
        Path(tmp).write_bytes(data)
    return path


def to_srgb8(linear: np.ndarray) -> np.ndarray:
    c = np.clip(np.nan_to_num(linear, nan=0.0), 0.0, 1.0)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)
