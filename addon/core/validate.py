"""Checks of settings that cannot be drawn: NaN, infinite or out-of-range numbers.

Blender stores an infinite float property as FLT_MAX (3.4e38) and keeps NaN, so a
value set from Python can be either; both are refused here with the field's name,
instead of a silent result (every pixel shadowed, or 0 evaluated pixels).
"""
from __future__ import annotations

import math

import numpy as np

from .errors import InputError

# Beyond this a coordinate or setting counts as non-finite (Blender's FLT_MAX for inf);
# the same bound the geometry sanitiser uses for vertices.
HUGE = 1e15


def finite_number(field: str, value: float, low: float | None = None, high: float | None = None) -> float:
    """`value` as a float, finite and within [low, high]; InputError naming `field` otherwise."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{field} {value!r} is not a number") from None
    if low is not None and high is not None:
        bounds = f" in [{low:g}, {high:g}]"
    elif low is not None or high is not None:
        bounds = f" >= {low:g}" if low is not None else f" <= {high:g}"
    else:
        bounds = ""
    if not math.isfinite(number) or abs(number) > HUGE:
        raise InputError(f"{field} is {number:g}: it must be a finite number{bounds}")
    if (low is not None and number < low) or (high is not None and number > high):
        raise InputError(f"{field} is {number:g}: it must be{bounds}")
    return number


def finite_matrix(field: str, matrix, shape: tuple[int, ...] = (4, 4)) -> np.ndarray:
    """`matrix` as float64 of `shape`, every entry finite; InputError naming `field` otherwise."""
    array = np.asarray(matrix, dtype=np.float64)
    if array.shape != shape:
        raise InputError(f"{field} has shape {array.shape}, expected {shape}")
    bad = ~np.isfinite(array) | (np.abs(np.where(np.isfinite(array), array, 0.0)) > HUGE)
    if bad.any():
        raise InputError(f"{field} is not finite ({_describe(array)}); fix the object's transform")
    return array


def _describe(matrix: np.ndarray) -> str:
    """The translation column of a 4x4 (what a user sees as the location), else the values."""
    if matrix.shape == (4, 4):
        return "location " + ", ".join(f"{v:g}" for v in matrix[:3, 3])
    return ", ".join(f"{v:g}" for v in matrix.ravel()[:6])
