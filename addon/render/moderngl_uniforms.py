"""moderngl's uniform writes: a program's uniforms packed as GLSL reads them, and sent only
when their bytes change (moderngl_backend.py uses one a program)."""
from __future__ import annotations

import struct

import numpy as np

from .device import Program


def _uniform_bytes(value: object, glsl_type: str = "") -> bytes | None:
    """Raw bytes for matrix and array uniforms (matrices column-major, as GLSL expects)."""
    arr = np.asarray(value)
    if glsl_type.startswith("mat") or (arr.ndim >= 2 and arr.shape[-2:] == (3, 3)):
        return np.ascontiguousarray(np.swapaxes(arr, -1, -2), dtype="f4").tobytes()
    if arr.ndim == 2:
        return np.ascontiguousarray(arr, dtype="f4").tobytes()
    return None


_INT = struct.Struct("i")
_FLOAT = struct.Struct("f")


class ProgramUniforms:
    """A program's uniforms and the bytes each was last given.

    A uniform keeps its value in the program between draws, so a value that did not
    change since the last write is not sent again (a steady frame sends few).
    """

    def __init__(self, prog, iface: Program) -> None:
        types = {u.name: u.glsl_type for u in iface.uniforms}
        # Only what can be written: moderngl lists attributes and blocks among the members.
        self._members = {name: (prog[name], types.get(name, "")) for name in prog
                         if hasattr(prog[name], "write")}
        self._last: dict[str, bytes] = {}
        self._scalars: dict[str, object] = {}  # the last scalar value, compared before packing

    def write(self, name: str, value: object) -> None:
        found = self._members.get(name)
        if found is None:
            return  # not declared, or optimised away by the GLSL compiler
        scalar = isinstance(value, (int, float, np.generic))
        if scalar:
            last = self._scalars.get(name)
            if last is not None and type(last) is type(value) and last == value:
                return  # most of a steady frame's uniforms: not packed again
            self._scalars[name] = value
        else:
            self._scalars.pop(name, None)
        member, glsl_type = found
        integer = glsl_type == "int"
        if scalar:
            raw = (_INT if integer else _FLOAT).pack(int(value) if integer else float(value))
        else:
            raw = _uniform_bytes(value, glsl_type)
            if raw is None:  # a vector, or an array of scalars
                raw = np.ascontiguousarray(value, dtype="i4" if integer else "f4").tobytes()
        if self._last.get(name) != raw:
            member.write(raw)
            self._last[name] = raw
