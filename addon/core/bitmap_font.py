"""A built-in 5x8 bitmap font for the printable ASCII characters, for raster_plot.py.

Each glyph is 8 rows of 5 pixels, written as 16 hex digits: one byte a row from the
top, bit 4 the left-most pixel. Rows 0-6 hold capitals and digits (the baseline is
under row 6); row 7 is for descenders (g, j, p, q, y, the comma). A character has a
cell 6 pixels wide (one blank column) and lines are 10 pixels apart, both times the
scale. A character not in the table is drawn as '?'.
"""
from __future__ import annotations

import numpy as np

GLYPH_WIDTH, GLYPH_HEIGHT = 5, 8
ADVANCE, LINE_HEIGHT = GLYPH_WIDTH + 1, GLYPH_HEIGHT + 2

GLYPHS: dict[str, str] = {
    " ": "0000000000000000", "!": "0404040404000400", '"': "0a0a000000000000", "#": "0a0a1f0a1f0a0a00",
    "$": "040f140e051e0400", "%": "1819020408130300", "&": "0c12140815120d00", "'": "0404080000000000",
    "(": "0204080808040200", ")": "0804020202040800", "*": "0004150e15040000", "+": "0004041f04040000",
    ",": "00000000000c0408", "-": "0000001f00000000", ".": "00000000000c0c00", "/": "0001020408100000",
    "0": "0e11131519110e00", "1": "040c040404040e00", "2": "0e11010204081f00", "3": "1f02040201110e00",
    "4": "02060a121f020200", "5": "1f101e0101110e00", "6": "0608101e11110e00", "7": "1f01020408080800",
    "8": "0e11110e11110e00", "9": "0e11110f01020c00", ":": "000c0c000c0c0000", ";": "000c0c000c040800",
    "<": "0204081008040200", "=": "00001f001f000000", ">": "0804020102040800", "?": "0e11010204000400",
    "@": "0e11010d15150e00", "A": "0e1111111f111100", "B": "1e11111e11111e00", "C": "0e11101010110e00",
    "D": "1c12111111121c00", "E": "1f10101e10101f00", "F": "1f10101e10101000", "G": "0e11101711110f00",
    "H": "1111111f11111100", "I": "0e04040404040e00", "J": "0702020202120c00", "K": "1112141814121100",
    "L": "1010101010101f00", "M": "111b151511111100", "N": "1111191513111100", "O": "0e11111111110e00",
    "P": "1e11111e10101000", "Q": "0e11111115120d00", "R": "1e11111e14121100", "S": "0f10100e01011e00",
    "T": "1f04040404040400", "U": "1111111111110e00", "V": "11111111110a0400", "W": "1111111515150a00",
    "X": "11110a040a111100", "Y": "1111110a04040400", "Z": "1f01020408101f00", "[": "0e08080808080e00",
    "\\": "0010080402010000", "]": "0e02020202020e00", "^": "040a110000000000", "_": "000000000000001f",
    "`": "0804000000000000", "a": "00000e010f110f00", "b": "1010161911111e00", "c": "00000e1010110e00",
    "d": "01010d1311110f00", "e": "00000e111f100e00", "f": "0609081c08080800", "g": "00000f11110f010e",
    "h": "1010161911111100", "i": "04000c0404040e00", "j": "020006020202120c", "k": "1010121418141200",
    "l": "0c04040404040e00", "m": "00001a1515111100", "n": "0000161911111100", "o": "00000e1111110e00",
    "p": "00001e11111e1010", "q": "00000f11110f0101", "r": "0000161910101000", "s": "00000f100e011e00",
    "t": "08081c0808090600", "u": "0000111111130d00", "v": "00001111110a0400", "w": "0000111115150a00",
    "x": "0000110a040a1100", "y": "00001111110f010e", "z": "00001f0204081f00", "{": "0204040804040200",
    "|": "0404040404040400", "}": "0804040204040800", "~": "0000081502000000",
}

_MASKS: dict[str, np.ndarray] = {}


def glyph(char: str) -> np.ndarray:
    """(8, 5) bool: the pixels of `char` ('?' for a character the font lacks)."""
    mask = _MASKS.get(char)
    if mask is None:
        digits = GLYPHS.get(char, GLYPHS["?"])
        rows = [int(digits[i:i + 2], 16) for i in range(0, 2 * GLYPH_HEIGHT, 2)]
        mask = np.array([[(row >> (GLYPH_WIDTH - 1 - col)) & 1 for col in range(GLYPH_WIDTH)] for row in rows], bool)
        _MASKS[char] = mask
    return mask


def text_size(text: str, scale: int = 1) -> tuple[int, int]:
    """(width, height) in pixels of one line of `text`, without the last blank column."""
    return max(len(text) * ADVANCE - 1, 0) * scale, GLYPH_HEIGHT * scale


def text_mask(text: str, scale: int = 1) -> np.ndarray:
    """(height, width) bool: one line of `text`, each font pixel `scale` x `scale`."""
    width, _ = text_size(text, 1)
    mask = np.zeros((GLYPH_HEIGHT, max(width, 0)), bool)
    for i, char in enumerate(text):
        x = i * ADVANCE
        mask[:, x:x + GLYPH_WIDTH] = glyph(char)
    return np.kron(mask, np.ones((scale, scale), bool)) if scale > 1 else mask
