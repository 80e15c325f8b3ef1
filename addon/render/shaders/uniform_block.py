"""A program's uniforms as one std140 uniform block: the layout, its GLSL, and the packing.

Why a block and not loose uniforms: Blender's `gpu` module turns a create-info's loose
uniforms into push constants, and where they pass the device's push-constant limit (128
bytes on Mesa's lavapipe, 256 on many GPUs; our programs declare up to ~800) its Vulkan
backend moves them into a uniform buffer it fills itself, copying a `mat3` as 9 packed
floats where std140 wants three 16-byte columns. The rotations arrive scrambled and the
maps come out blank (docs/versions.md). A block the project packs itself has one layout
on every backend: Blender gets it as a `GPUUniformBuf`, moderngl as a uniform buffer.

The layout follows GLSL's std140 rules (OpenGL 4.5 spec, 7.6.2.2): scalars align to 4,
vec2 to 8, vec3 and vec4 to 16; a matrix is an array of its columns; every array element
(and so every matrix column) is rounded up to 16 bytes; the block to 16.

`UniformBlock.of(iface)` is cached per interface. `BlockState` keeps a program's current
values as bytes, as a GL program keeps its uniforms between draws: a draw writes the
values it gives, the others stay.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ...core.errors import BackendError
from .interfaces import ComputeInterface, ProgramInterface, Uniform

# (components per column, columns, integer) of each GLSL type a program declares.
_SHAPES = {
    "float": (1, 1, False), "vec2": (2, 1, False), "vec3": (3, 1, False), "vec4": (4, 1, False),
    "int": (1, 1, True), "ivec2": (2, 1, True), "ivec3": (3, 1, True), "ivec4": (4, 1, True),
    "bool": (1, 1, True), "mat3": (3, 3, False), "mat4": (4, 4, False),
}
_ALIGN = {1: 4, 2: 8, 3: 16, 4: 16}
# The GLSL name every backend gives the block's instance (Blender) and type prefix.
INSTANCE = "ow_u"
MEMBER_PREFIX = "u_"


def _round_up(value: int, step: int) -> int:
    return -(-value // step) * step


@dataclass(frozen=True)
class Member:
    """One uniform's place in the block."""

    uniform: Uniform
    offset: int  # bytes from the block's start
    stride: int  # bytes between array elements (0 when not an array)
    column_stride: int  # bytes between a matrix's columns (16); 0 for vectors and scalars
    components: int
    columns: int
    integer: bool

    @property
    def count(self) -> int:
        return max(1, self.uniform.array)


@dataclass(frozen=True)
class UniformBlock:
    """The std140 layout of one program's uniforms."""

    type_name: str
    members: tuple[Member, ...]
    size: int  # bytes, a multiple of 16

    @classmethod
    def of(cls, iface: ProgramInterface | ComputeInterface) -> "UniformBlock":
        return _block(iface.name, tuple(iface.uniforms))

    def member(self, name: str) -> Member | None:
        return self._by_name.get(name)

    @functools.cached_property
    def _by_name(self) -> dict[str, Member]:
        return {m.uniform.name: m for m in self.members}

    def glsl_struct(self) -> str:
        """The block's members as a GLSL struct (Blender's create-info typedef), each named
        with MEMBER_PREFIX so the bodies' bare names can be macros of INSTANCE's members."""
        lines = [f"struct {self.type_name} {{"]
        lines += [f"  {_decl(m.uniform, MEMBER_PREFIX)}" for m in self.members]
        return "\n".join(lines) + "\n};\n"

    def glsl_block(self) -> str:
        """The block for plain GLSL (moderngl): no instance name, so members keep their bare names."""
        lines = [f"layout(std140) uniform {self.type_name} {{"]
        lines += [f"  {_decl(m.uniform, '')}" for m in self.members]
        return "\n".join(lines) + "\n};"

    def member_defines(self) -> dict[str, str]:
        """`name` -> `INSTANCE.u_name` for a backend that reaches members through an instance."""
        return {m.uniform.name: f"{INSTANCE}.{MEMBER_PREFIX}{m.uniform.name}" for m in self.members}

    def pack_member(self, member: Member, value: Any) -> bytes:
        """One member's bytes as std140 lays them out (padding between columns and elements
        zero). Matrices are given as (rows, columns) arrays, as numpy writes them. An array
        may be given fewer elements than it declares: the first ones are written."""
        dtype = np.int32 if member.integer else np.float32
        arr = np.asarray(value, dtype=np.float64 if not member.integer else np.int64)
        per_element = member.components * member.columns
        given = arr.size // per_element
        if arr.size != given * per_element or not 1 <= given <= member.count:
            raise ValueError(f"uniform {member.uniform.name} ({member.uniform.glsl_type}"
                             f"{f'[{member.uniform.array}]' if member.uniform.array else ''}) "
                             f"cannot take {arr.size} values")
        elements = arr.reshape((given, member.components, member.columns) if member.columns > 1
                               else (given, member.components))
        # Every array element, and every matrix column, fills 16 bytes: its stride.
        if member.columns > 1:
            padded = np.zeros((given, member.columns, 4), dtype=dtype)
            padded[:, :, :member.components] = np.swapaxes(elements, 1, 2)  # columns, as GLSL stores them
        elif member.uniform.array:
            padded = np.zeros((given, 4), dtype=dtype)
            padded[:, :member.components] = elements
        else:
            padded = elements.astype(dtype)
        return padded.tobytes()[:_span(member, given)]


def _decl(uniform: Uniform, prefix: str) -> str:
    return f"{uniform.glsl_type} {prefix}{uniform.name}{f'[{uniform.array}]' if uniform.array else ''};"


def _span(member: Member, given: int) -> int:
    """Bytes from a member's first to its last written byte (of `given` elements), padding
    inside included."""
    if member.uniform.array:
        return member.stride * (given - 1) + _element_size(member)
    return _element_size(member)


def _element_size(member: Member) -> int:
    if member.columns > 1:
        return member.column_stride * (member.columns - 1) + 4 * member.components
    return 4 * member.components


@functools.lru_cache(maxsize=None)
def _block(name: str, uniforms: tuple[Uniform, ...]) -> UniformBlock:
    offset, members = 0, []
    for uniform in uniforms:
        try:
            components, columns, integer = _SHAPES[uniform.glsl_type]
        except KeyError:
            raise ValueError(f"{name}: uniform {uniform.name} has type {uniform.glsl_type}, "
                             "which the uniform block does not lay out") from None
        if columns > 1 or uniform.array:
            align = 16
        else:
            align = _ALIGN[components]
        column_stride = 16 if columns > 1 else 0
        element = column_stride * columns if columns > 1 else 4 * components
        stride = _round_up(element, 16) if uniform.array else 0
        offset = _round_up(offset, align)
        members.append(Member(uniform, offset, stride, column_stride, components, columns, integer))
        offset += stride * uniform.array if uniform.array else element
    type_name = "OwBlock_" + "".join(c if c.isalnum() else "_" for c in name)
    return UniformBlock(type_name, tuple(members), max(16, _round_up(offset, 16)))


class BlockState:
    """A program's current uniform values as its block's bytes.

    `update` writes the given values (skipping a member whose bytes did not change) and
    says whether anything changed; `data` is the whole block. Values a draw does not give
    keep what an earlier draw gave, as a GL program's uniforms do.
    """

    def __init__(self, block: UniformBlock) -> None:
        self.block = block
        self._data = bytearray(block.size)
        self._last: dict[str, object] = {}  # the last scalar given, compared before packing
        self._dirty: tuple[int, int] | None = (0, block.size)  # bytes changed since `take_changed`

    def update(self, values: Mapping[str, Any]) -> bool:
        changed = False
        for name, value in values.items():
            member = self.block.member(name)
            if member is None:
                # A frame's shared dictionaries carry other programs' uniforms too; a name
                # no program declares is refused, so that a typo is not silently dropped.
                if name not in _known_names():
                    raise BackendError(f"{self.block.type_name.removeprefix('OwBlock_')}: no program declares a uniform named {name!r}")
                continue
            scalar = isinstance(value, (int, float, np.generic))
            if scalar:
                last = self._last.get(name)
                if last is not None and type(last) is type(value) and last == value:
                    continue
                self._last[name] = value
            else:
                self._last.pop(name, None)
            raw = self.block.pack_member(member, value)
            end = member.offset + len(raw)
            if self._data[member.offset:end] != raw:
                self._data[member.offset:end] = raw
                changed = True
                low, high = self._dirty or (member.offset, end)
                self._dirty = (min(low, member.offset), max(high, end))
        return changed

    def take_changed(self) -> tuple[int, bytes] | None:
        """(offset, bytes) of the span changed since the last call (the whole block at
        first), or None: what a backend that can write part of a buffer sends."""
        if self._dirty is None:
            return None
        low, high = self._dirty
        self._dirty = None
        return low, bytes(self._data[low:high])

    @property
    def data(self) -> bytes:
        return bytes(self._data)


@functools.cache
def _known_names() -> frozenset[str]:
    from .programs import KNOWN_KEYS  # every program: built after this module

    return KNOWN_KEYS
