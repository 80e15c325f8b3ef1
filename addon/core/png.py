"""PNG files from numpy arrays, with zlib and struct only, and three colour maps.

Every image the extension writes goes through here (the mismatch and map images, the
preview and, where matplotlib is missing, the plots): a stock Blender's Python has
numpy but no matplotlib. `write_png` takes (H, W) grey, (H, W, 3) RGB or (H, W, 4)
RGBA, floats in [0, 1] (clipped; NaN as 0) or uint8, row 0 at the top of the picture
(as matplotlib's `imsave` with its default origin). `colormap` turns values into RGB
with 'viridis', 'inferno' or 'gray', as matplotlib's maps of those names do (within 7
levels of 255: each is 17 samples of the published map, linearly interpolated).
"""
from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_COLOUR_TYPE = {1: 0, 3: 2, 4: 6}  # channels -> PNG colour type (grey, RGB, RGBA)

# Each map at 0, 1/16, ..., 1 (sRGB, 8 bits a channel); between them, linear.
_MAPS = {
    "viridis": "440154 48186a 472d7b 424086 3b528b 33638d 2c728e 26828e 21918c "
               "1fa088 28ae80 3fbc73 5ec962 84d44b addc30 d8e219 fde725",
    "inferno": "000004 0b0724 210c4a 3d0965 57106e 71196e 8a226a a32c61 bc3754 "
               "d24644 e45a31 f1731d f98e09 fcac11 f9cb35 f2ea69 fcffa4",
    "gray": "000000 ffffff",
}


def _control_points(name: str) -> np.ndarray:
    """(N, 3) floats in [0, 1]: the map's samples, evenly spaced from 0 to 1."""
    try:
        table = _MAPS[name]
    except KeyError:
        raise ValueError(f"unknown colour map {name!r}; known: {', '.join(sorted(_MAPS))}") from None
    return np.array([[int(h[i:i + 2], 16) for i in (0, 2, 4)] for h in table.split()], dtype=np.float64) / 255.0


def colormap(values: np.ndarray, name: str, vmin: float, vmax: float) -> np.ndarray:
    """(…, 3) float RGB in [0, 1]: `values` scaled from [vmin, vmax] to [0, 1] (clipped;
    NaN and an empty range as vmin) and looked up in the map `name`."""
    points = _control_points(name)
    v = np.asarray(values, dtype=np.float64)
    span = float(vmax) - float(vmin)
    t = (v - float(vmin)) / span if span > 0 else np.zeros_like(v)
    t = np.clip(np.nan_to_num(t, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    grid = np.linspace(0.0, 1.0, len(points))
    return np.stack([np.interp(t, grid, points[:, c]) for c in range(3)], axis=-1)


def to_uint8(image: np.ndarray) -> np.ndarray:
    """The image as uint8: uint8 kept, bool as 0/255, anything else read as floats in
    [0, 1] (clipped, NaN as 0) and rounded to the nearest level."""
    a = np.asarray(image)
    if a.dtype == np.uint8:
        return a
    if a.dtype == np.bool_:
        return a.astype(np.uint8) * 255
    f = np.nan_to_num(a.astype(np.float64), nan=0.0, posinf=1.0, neginf=0.0)
    return np.round(np.clip(f, 0.0, 1.0) * 255.0).astype(np.uint8)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png(image: np.ndarray) -> bytes:
    """The bytes of a PNG file (8 bits a channel, no interlace) holding `image`."""
    a = to_uint8(image)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in _COLOUR_TYPE or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"a PNG needs an (H, W), (H, W, 3) or (H, W, 4) image, not shape {np.shape(image)}")
    height, width, channels = a.shape
    header = struct.pack(">IIBBBBB", width, height, 8, _COLOUR_TYPE[channels], 0, 0, 0)
    # Each scanline starts with its filter byte (0: none); zlib does the rest.
    raw = np.concatenate([np.zeros((height, 1), np.uint8), np.ascontiguousarray(a).reshape(height, -1)], axis=1)
    return (_SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(raw.tobytes(), 6))
            + _chunk(b"IEND", b""))


def write_png(path: str | Path, image: np.ndarray) -> None:
    """Write `image` (row 0 at the top) to `path` as a PNG."""
    Path(path).write_bytes(encode_png(image))
