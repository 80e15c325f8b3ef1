"""core/png.py: PNG files written with zlib alone, read back pixel for pixel, and its colour maps."""
from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from addon.core.png import colormap, encode_png, to_uint8, write_png

CHANNELS = {0: 1, 2: 3, 6: 4}  # PNG colour type -> channels


def _unfilter(raw: np.ndarray, bpp: int) -> np.ndarray:
    """Undo the PNG row filters (0 none, 1 sub, 2 up, 3 average, 4 Paeth); core/png.py
    writes 0 only, matplotlib's writer picks others."""
    out = np.zeros((raw.shape[0], raw.shape[1] - 1), dtype=np.int64)
    for y, (kind, line) in enumerate(zip(raw[:, 0], raw[:, 1:].astype(np.int64))):
        up = out[y - 1] if y else np.zeros_like(line)
        if kind in (0, 2):
            out[y] = (line + (up if kind == 2 else 0)) % 256
            continue
        row = out[y]
        for i in range(len(line)):
            left = row[i - bpp] if i >= bpp else 0
            corner = up[i - bpp] if i >= bpp else 0
            if kind == 1:
                guess = left
            elif kind == 3:
                guess = (left + up[i]) // 2
            else:
                p = left + up[i] - corner
                guess = min((abs(p - left), 0, left), (abs(p - up[i]), 1, up[i]), (abs(p - corner), 2, corner))[2]
            row[i] = (line[i] + guess) % 256
    return out.astype(np.uint8)


def read_png(path: Path, ours: bool = True) -> np.ndarray:
    """A small reader of 8-bit, non-interlaced PNGs: (H, W, C) uint8, every chunk's CRC
    checked; `ours` (a file of core/png.py) also checks that no row is filtered."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,), kind = struct.unpack(">I", data[pos:pos + 4]), data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF, kind
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
        if kind == b"IEND":
            break
    assert pos == len(data) and header is not None
    width, height, depth, colour_type, _, _, interlace = header
    assert depth == 8 and interlace == 0
    channels = CHANNELS[colour_type]
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, 1 + width * channels)
    if ours:
        assert not raw[:, 0].any()  # filter 0 on every scanline
    return _unfilter(raw, channels).reshape(height, width, channels)


@pytest.mark.parametrize("shape", [(5, 7), (5, 7, 3), (5, 7, 4), (1, 1, 3)])
def test_uint8_images_come_back_exactly(tmp_path, shape):
    image = np.random.default_rng(1).integers(0, 256, size=shape, dtype=np.uint8)
    write_png(tmp_path / "a.png", image)
    back = read_png(tmp_path / "a.png")
    assert back.shape == (*shape[:2], 1 if len(shape) == 2 else shape[2])
    assert np.array_equal(back.reshape(shape), image)


def test_row_0_is_the_top_and_floats_are_clipped_and_rounded(tmp_path):
    image = np.zeros((4, 3, 3))
    image[0] = (1.0, 0.0, 0.0)  # the top row red
    image[3] = (-0.5, 2.0, np.nan)
    image[1, 0] = (0.5, 0.25, 1.0 / 255.0 * 0.49)
    write_png(tmp_path / "f.png", image)
    back = read_png(tmp_path / "f.png")
    assert back[0].tolist() == [[255, 0, 0]] * 3
    assert back[3].tolist() == [[0, 255, 0]] * 3  # clipped; NaN as 0
    assert back[1, 0].tolist() == [128, 64, 0]
    assert to_uint8(np.array([True, False])).tolist() == [255, 0]


def test_matplotlib_reads_the_same_pixels(tmp_path):
    mpimg = pytest.importorskip("matplotlib.image")
    rng = np.random.default_rng(2)
    for channels in (3, 4):
        image = rng.integers(0, 256, size=(9, 13, channels), dtype=np.uint8)
        write_png(tmp_path / "m.png", image)
        assert np.array_equal(np.round(mpimg.imread(tmp_path / "m.png") * 255).astype(np.uint8), image)


def test_a_wrong_shape_is_refused():
    for bad in (np.zeros((2, 2, 2)), np.zeros(3), np.zeros((0, 4, 3))):
        with pytest.raises(ValueError):
            encode_png(bad)


def test_colour_maps_end_where_the_published_maps_do():
    ends = {"viridis": ((0x44, 0x01, 0x54), (0xFD, 0xE7, 0x25)), "inferno": ((0, 0, 4), (0xFC, 0xFF, 0xA4)),
            "gray": ((0, 0, 0), (255, 255, 255))}
    for name, (low, high) in ends.items():
        rgb = colormap(np.array([[-1.0, 0.0], [10.0, 20.0]]), name, 0.0, 10.0)
        assert rgb.shape == (2, 2, 3)
        assert np.allclose(rgb[0, 0] * 255, low) and np.allclose(rgb[0, 1] * 255, low)  # below vmin: clipped
        assert np.allclose(rgb[1, 0] * 255, high) and np.allclose(rgb[1, 1] * 255, high)
    assert np.allclose(colormap(np.array([0.5]), "gray", 0.0, 1.0), 0.5)
    assert np.allclose(colormap(np.array([np.nan, 3.0]), "viridis", 2.0, 2.0) * 255, (0x44, 0x01, 0x54))
    with pytest.raises(ValueError, match="unknown colour map"):
        colormap(np.zeros(2), "jet", 0.0, 1.0)


def test_colour_maps_follow_matplotlibs_between_the_samples():
    matplotlib = pytest.importorskip("matplotlib")
    t = np.linspace(0.0, 1.0, 1001)
    for name in ("viridis", "inferno", "gray"):
        theirs = matplotlib.colormaps[name](t)[:, :3]
        assert np.abs(colormap(t, name, 0.0, 1.0) - theirs).max() < 7.5 / 255.0, name  # 17 samples a map


def test_a_colour_mapped_image_matches_matplotlibs_imsave(tmp_path):
    """compare.py's map images (origin='lower' before): the rows flipped, the map applied."""
    plt = pytest.importorskip("matplotlib.pyplot")
    data = np.random.default_rng(3).random((6, 8)) * 3.0
    plt.imsave(tmp_path / "theirs.png", data, cmap="inferno", origin="lower", vmin=0.0, vmax=3.0)
    write_png(tmp_path / "ours.png", colormap(data, "inferno", 0.0, 3.0)[::-1])
    theirs = read_png(tmp_path / "theirs.png", ours=False)[..., :3].astype(int)
    assert np.abs(theirs - read_png(tmp_path / "ours.png").astype(int)).max() <= 8
