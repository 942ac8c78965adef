"""The small part of OpenEXR the add-on needs without the OpenEXR package (Blender's Python
has none): read a header's attributes and the first pixel of an uncompressed file, write an
uncompressed 32-bit float RGB scanline file.
Layout per the OpenEXR file-format document: magic, version, attributes, offset table,
one scanline per block with channels in name order (B, G, R)."""
from __future__ import annotations

import struct

import numpy as np

MAGIC = 20000630
VERSION = 2
FLOAT = 2


def _attribute(name: str, kind: str, payload: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(payload)) + payload


def encode_rgb_float(rgb_top_down: np.ndarray, strings: dict) -> bytes:
    """An uncompressed EXR of (height, width, 3) float32, row 0 at the top, with string attributes."""
    height, width, _ = rgb_top_down.shape
    channels = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", FLOAT, 0, 1, 1) for c in "BGR") + b"\0"
    box = struct.pack("<iiii", 0, 0, width - 1, height - 1)
    header = b"".join([
        _attribute("channels", "chlist", channels),
        _attribute("compression", "compression", b"\0"),
        _attribute("dataWindow", "box2i", box),
        _attribute("displayWindow", "box2i", box),
        _attribute("lineOrder", "lineOrder", b"\0"),
        _attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        _attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)),
        _attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)),
        *(_attribute(k, "string", str(v).encode()) for k, v in strings.items()),
    ]) + b"\0"
    start = 8 + len(header) + 8 * height
    line_bytes = width * 3 * 4
    offsets = struct.pack(f"<{height}Q", *(start + y * (8 + line_bytes) for y in range(height)))
    planar = np.ascontiguousarray(np.asarray(rgb_top_down, dtype="<f4")[:, :, ::-1].transpose(0, 2, 1))
    lines = b"".join(struct.pack("<ii", y, line_bytes) + planar[y].tobytes() for y in range(height))
    return struct.pack("<ii", MAGIC, VERSION) + header + offsets + lines


def _header(data: bytes):
    """({name: (kind, raw value)}, offset just past the header) of an EXR file's bytes."""
    if len(data) < 8 or struct.unpack("<i", data[:4])[0] != MAGIC:
        raise ValueError("not an OpenEXR file")
    pos, attributes = 8, {}
    while True:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        if not name:
            return attributes, end + 1
        type_end = data.index(b"\0", end + 1)
        kind = data[end + 1:type_end].decode()
        (size,) = struct.unpack("<i", data[type_end + 1:type_end + 5])
        value = data[type_end + 5:type_end + 5 + size]
        if len(value) < size:
            raise ValueError("header is truncated")
        attributes[name] = (kind, value)
        pos = type_end + 5 + size


def read_string_attributes(path) -> dict:
    """String attributes of an EXR header; ValueError when the file is not an EXR."""
    with open(path, "rb") as f:
        data = f.read(1 << 16)
    attributes, _ = _header(data)
    return {name: value.decode() for name, (kind, value) in attributes.items() if kind == "string"}


def _channel_types(chlist: bytes) -> list:
    """[(name, pixel type)] of a chlist attribute (1 half, 2 float), in file (name) order."""
    channels, at = [], 0
    while chlist[at] != 0:
        end = chlist.index(b"\0", at)
        channels.append((chlist[at:end].decode(), struct.unpack_from("<i", chlist, end + 1)[0]))
        at = end + 17                        # type, pLinear + 3 reserved, x and y sampling
    return channels


def read_first_pixel(path) -> float:
    """The first pixel of the first channel of an uncompressed scanline EXR (what a File Output
    node writes with codec None); ValueError for anything else."""
    with open(path, "rb") as f:
        data = f.read()
    try:
        attributes, end = _header(data)
        channels = _channel_types(attributes["channels"][1])
        compression = attributes["compression"][1][0]
    except (KeyError, IndexError, struct.error) as exc:
        raise ValueError(f"{path}: damaged EXR header ({exc})") from None
    if compression != 0 or not channels:
        raise ValueError(f"{path}: expected an uncompressed EXR with channels")
    pixels = struct.unpack_from("<Q", data, end)[0] + 8     # first chunk, past its y and byte count
    pixel_type = channels[0][1]
    if pixel_type == FLOAT:
        return float(struct.unpack_from("<f", data, pixels)[0])
    if pixel_type == 1:
        return float(struct.unpack_from("<e", data, pixels)[0])
    raise ValueError(f"{path}: unsupported pixel type {pixel_type}")
