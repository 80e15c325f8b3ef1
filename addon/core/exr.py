"""A small OpenEXR reader in numpy: the channels of the scanline files Blender writes.

Why: the Cycles reference and the EEVEE row read Blender's multilayer EXR output, and a
stock Blender's Python carries numpy but neither the `OpenEXR` nor the `OpenImageIO`
module (Debian's Blender 5.2 has none; the PyPI `bpy` has no `OpenEXR`). Blender writes
scanline images, single- or multi-part, with 32-bit float (or half) channels and the
NONE, ZIPS or ZIP codec (the capture asks for ZIP). Those are what this reads; anything
else (tiled or deep images, the lossy codecs) is refused with `ExrError` naming it.

The layout followed is OpenEXR's file format (openexr.com, "OpenEXR File Layout"): a
magic number and version, headers of typed attributes, a chunk offset table per part,
then chunks of scanlines holding each channel's row in the channel list's order.
"""
from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import OmniWarpError

MAGIC = 20000630
_TILED = 0x200
_MULTIPART = 0x1000
_DEEP = 0x800
_NONE, _RLE, _ZIPS, _ZIP = 0, 1, 2, 3
_LINES_PER_CHUNK = {_NONE: 1, _ZIPS: 1, _ZIP: 16}
_CODEC_NAMES = {0: "NONE", 1: "RLE", 2: "ZIPS", 3: "ZIP", 4: "PIZ", 5: "PXR24", 6: "B44", 7: "B44A", 8: "DWAA",
                9: "DWAB", 10: "HTJ2K256", 11: "HTJ2K32"}
_PIXEL_DTYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}


class ExrError(OmniWarpError):
    """An EXR file this reader cannot read: damaged, or a kind Blender does not write."""


@dataclass(frozen=True)
class _Part:
    channels: tuple[tuple[str, np.dtype], ...]  # in the file's (sorted) order
    x_min: int
    y_min: int
    width: int
    height: int
    compression: int


class _Cursor:
    """Reads little-endian values from a bytes object, with bounds checks."""

    def __init__(self, data: bytes, offset: int = 0) -> None:
        self.data, self.at = data, offset

    def take(self, size: int) -> bytes:
        if size < 0 or self.at + size > len(self.data):
            raise ExrError("the file ends inside its header or a chunk")
        chunk = self.data[self.at:self.at + size]
        self.at += size
        return chunk

    def unpack(self, fmt: str) -> tuple:
        return struct.unpack("<" + fmt, self.take(struct.calcsize("<" + fmt)))

    def cstring(self) -> str:
        end = self.data.find(b"\0", self.at)
        if end < 0:
            raise ExrError("the file ends inside its header")
        text = self.data[self.at:end].decode("latin-1")
        self.at = end + 1
        return text


def _channel_list(raw: bytes) -> tuple[tuple[str, np.dtype], ...]:
    cursor, out = _Cursor(raw), []
    while True:
        name = cursor.cstring()
        if not name:
            return tuple(out)
        pixel_type, _linear, _x_sampling, y_sampling = cursor.unpack("iB3xii")
        if pixel_type not in _PIXEL_DTYPES:
            raise ExrError(f"channel {name!r} has an unknown pixel type {pixel_type}")
        if _x_sampling != 1 or y_sampling != 1:
            raise ExrError(f"channel {name!r} is subsampled, which Blender does not write")
        out.append((name, _PIXEL_DTYPES[pixel_type]))


def _header(cursor: _Cursor) -> _Part | None:
    """One part's header, or None at the empty header that ends a multi-part list."""
    attributes: dict[str, bytes] = {}
    while True:
        name = cursor.cstring()
        if not name:
            break
        cursor.cstring()  # the attribute's type name: each attribute read here has one type
        (size,) = cursor.unpack("i")
        attributes[name] = cursor.take(size)
    if not attributes:
        return None
    for key in ("channels", "compression", "dataWindow"):
        if key not in attributes:
            raise ExrError(f"a header lacks its {key!r} attribute")
    part_type = attributes.get("type", b"scanlineimage\0").rstrip(b"\0")
    if part_type != b"scanlineimage":
        raise ExrError(f"a part is a {part_type.decode('latin-1')}; only scanline images are read")
    compression = attributes["compression"][0]
    if compression not in _LINES_PER_CHUNK:
        raise ExrError(f"codec {_CODEC_NAMES.get(compression, compression)} is not read "
                       "(Blender's NONE, ZIPS and ZIP are)")
    x_min, y_min, x_max, y_max = struct.unpack("<4i", attributes["dataWindow"])
    if x_max < x_min or y_max < y_min:
        raise ExrError("the data window is empty")
    return _Part(_channel_list(attributes["channels"]), x_min, y_min, x_max - x_min + 1, y_max - y_min + 1,
                 compression)


def _unzip(packed: bytes, expected: int) -> bytes:
    """ZIP(S) chunk data: zlib, then undo the byte predictor and the two-halves interleave."""
    if len(packed) >= expected:
        return packed  # the writer keeps a chunk raw where compressing would not shrink it
    try:
        data = np.frombuffer(zlib.decompress(packed), dtype=np.uint8)
    except zlib.error as exc:
        raise ExrError(f"a ZIP chunk does not decompress: {exc}") from None
    if data.size != expected:
        raise ExrError(f"a ZIP chunk holds {data.size} bytes, {expected} expected")
    # Predictor: each byte was stored as the difference to the previous one, plus 128.
    deltas = data.astype(np.int64)
    deltas[1:] -= 128
    restored = (np.cumsum(deltas) & 0xFF).astype(np.uint8)
    out = np.empty_like(restored)
    half = (expected + 1) // 2
    out[0::2] = restored[:half]
    out[1::2] = restored[half:]
    return out.tobytes()


def _read_part(data: bytes, part: _Part, offsets: np.ndarray, multipart: bool,
               index: int) -> dict[str, np.ndarray]:
    width = part.width
    row_bytes = sum(dtype.itemsize for _, dtype in part.channels) * width
    planes = {name: np.empty((part.height, width), dtype=dtype) for name, dtype in part.channels}
    for offset in offsets:
        cursor = _Cursor(data, int(offset))
        if multipart:
            (owner,) = cursor.unpack("i")
            if owner != index:
                raise ExrError(f"a chunk of part {index} names part {owner}")
        y, size = cursor.unpack("ii")
        first = y - part.y_min
        lines = min(_LINES_PER_CHUNK[part.compression], part.height - first)
        if first < 0 or lines <= 0:
            raise ExrError(f"a chunk starts at line {y}, outside the data window")
        raw = cursor.take(size)
        if part.compression != _NONE:
            raw = _unzip(raw, row_bytes * lines)
        if len(raw) != row_bytes * lines:
            raise ExrError(f"a chunk holds {len(raw)} bytes, {row_bytes * lines} expected")
        at = 0
        for line in range(first, first + lines):
            for name, dtype in part.channels:
                step = dtype.itemsize * width
                planes[name][line] = np.frombuffer(raw, dtype=dtype, count=width, offset=at)
                at += step
    return planes


def read_channels(path: str | Path) -> dict[str, np.ndarray]:
    """Every channel of a scanline EXR (every part) by its full name, as (H, W) float32
    arrays with row 0 at the top of the image (the data window's first line)."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise ExrError(f"cannot read {path}: {exc.strerror or exc}") from None
    cursor = _Cursor(data)
    magic, version = cursor.unpack("iI")
    if magic != MAGIC:
        raise ExrError(f"{path} is not an OpenEXR file")
    if version & (_TILED | _DEEP):
        raise ExrError(f"{path} is a tiled or deep EXR; only scanline images are read")
    multipart = bool(version & _MULTIPART)
    parts: list[_Part] = []
    while True:
        part = _header(cursor)
        if part is None:
            if not multipart:
                raise ExrError(f"{path} has an empty header")
            break
        parts.append(part)
        if not multipart:
            break
    tables = []
    for part in parts:
        count = -(-part.height // _LINES_PER_CHUNK[part.compression])
        tables.append(np.frombuffer(cursor.take(8 * count), dtype="<u8"))
    channels: dict[str, np.ndarray] = {}
    try:
        for index, (part, table) in enumerate(zip(parts, tables)):
            for name, plane in _read_part(data, part, table, multipart, index).items():
                channels[name] = plane.astype(np.float32, copy=False)
    except (ValueError, struct.error) as exc:
        raise ExrError(f"{path} is damaged: {exc}") from None
    return channels
