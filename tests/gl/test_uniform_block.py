"""The std140 uniform block (render/shaders/uniform_block.py) against the GLSL compiler:
a block of every type and array kind the programs declare, packed on the host, read back
member by member by a shader; the offsets against std140's rules worked by hand; and the
block state's persistence and changed spans."""
from __future__ import annotations

import numpy as np
import pytest

from addon.render.shaders import Uniform
from addon.render.shaders.interfaces import uniform_list
from addon.render.shaders.uniform_block import BlockState, UniformBlock, _block, _span
from tests.support import glsl

pytestmark = pytest.mark.gl

UNIFORMS = uniform_list("float a", "vec3 b", "int c", "mat3 d", "vec2 e", "mat3 f[2]", "vec4 g[3]", "float h[3]",
                        "int i[2]", "mat4 j", "vec3 k[2]", "ivec2 l")
RNG = np.random.default_rng(5)
VALUES = {
    "a": 1.5, "b": RNG.normal(size=3), "c": -7, "d": RNG.normal(size=(3, 3)), "e": RNG.normal(size=2),
    "f": RNG.normal(size=(2, 3, 3)), "g": RNG.normal(size=(3, 4)), "h": RNG.normal(size=3), "i": [11, -4],
    "j": RNG.normal(size=(4, 4)), "k": RNG.normal(size=(2, 3)), "l": [3, 9],
}


def _reads() -> list[tuple[str, float]]:
    """(GLSL expression, expected value) for every component of every member."""
    out: list[tuple[str, float]] = [("a", VALUES["a"]), ("float(c)", VALUES["c"])]
    out += [(f"b[{r}]", VALUES["b"][r]) for r in range(3)]
    out += [(f"e[{r}]", VALUES["e"][r]) for r in range(2)]
    # GLSL indexes a matrix [column][row]; numpy's value is [row][column].
    out += [(f"d[{c}][{r}]", VALUES["d"][r, c]) for c in range(3) for r in range(3)]
    out += [(f"f[{n}][{c}][{r}]", VALUES["f"][n, r, c]) for n in range(2) for c in range(3) for r in range(3)]
    out += [(f"g[{n}][{r}]", VALUES["g"][n, r]) for n in range(3) for r in range(4)]
    out += [(f"h[{n}]", VALUES["h"][n]) for n in range(3)]
    out += [(f"float(i[{n}])", VALUES["i"][n]) for n in range(2)]
    out += [(f"j[{c}][{r}]", VALUES["j"][r, c]) for c in range(4) for r in range(4)]
    out += [(f"k[{n}][{r}]", VALUES["k"][n, r]) for n in range(2) for r in range(3)]
    out += [(f"float(l[{r}])", VALUES["l"][r]) for r in range(2)]
    return out


def test_every_member_reads_back_in_glsl(gl_backend):
    reads = _reads()
    cases = "\n".join(f"  if (index == {n}) value = {expr};" for n, (expr, _) in enumerate(reads))
    body = ("void main() {\n  int index = int(gl_FragCoord.x);\n  float value = -999.0;\n" + cases
            + "\n  ow_out = vec4(value + texelFetch(ow_input, ivec2(gl_FragCoord.xy), 0).x, 0.0, 0.0, 1.0);\n}\n")
    vs, fs = glsl.program("block_harness", body, uniforms=UNIFORMS)
    inputs = np.zeros((len(reads), 1))
    with gl_backend.ctx:
        block = glsl.uniform_buffer(gl_backend.ctx, "block_harness", UNIFORMS, VALUES)  # bound for the draw
        try:
            got = glsl.evaluate(gl_backend.ctx, vs, fs, inputs)[:, 0]
        finally:
            block.release()
    want = np.array([value for _, value in reads], dtype=np.float32)
    np.testing.assert_array_equal(got.astype(np.float32), want)


def test_offsets_follow_std140():
    block = _block("offsets", UNIFORMS)
    offsets = {m.uniform.name: (m.offset, m.stride) for m in block.members}
    # a@0; b (vec3) aligns to 16; c packs into b's last word; d (mat3) at 32, 3 columns of 16;
    # e (vec2) at 80; f (mat3[2]) aligns to 16: 96, 48 a matrix; g (vec4[3]) at 192; h
    # (float[3]) at 240, 16 an element; i (int[2]) at 288; j (mat4) at 320; k (vec3[2]) at
    # 384, 16 an element; l (ivec2) at 416; the block rounds 424 up to 432.
    assert offsets == {"a": (0, 0), "b": (16, 0), "c": (28, 0), "d": (32, 0), "e": (80, 0), "f": (96, 48),
                       "g": (192, 16), "h": (240, 16), "i": (288, 16), "j": (320, 0), "k": (384, 16),
                       "l": (416, 0)}
    assert block.size == 432


def test_state_keeps_values_and_reports_the_changed_span():
    block = _block("state", uniform_list("float a", "vec4 b", "mat3 c"))
    state = BlockState(block)
    assert state.take_changed() == (0, bytes(block.size))  # the whole block, first
    assert state.take_changed() is None
    assert state.update({"a": 2.0}) and state.take_changed() == (0, np.float32(2.0).tobytes())
    assert not state.update({"a": 2.0}) and state.take_changed() is None  # same value: nothing
    state.update({"b": [1, 2, 3, 4]})
    offset, raw = state.take_changed()
    assert offset == 16 and np.array_equal(np.frombuffer(raw, np.float32), [1, 2, 3, 4])
    # A draw naming only `c` keeps `a` and `b`, as a GL program keeps its uniforms.
    state.update({"c": np.eye(3)})
    words = np.frombuffer(state.data, np.float32)
    assert words[0] == 2.0 and np.array_equal(words[4:8], [1, 2, 3, 4])
    assert np.array_equal(words[8:20].reshape(3, 4)[:, :3], np.eye(3)) and not words[8:20].reshape(3, 4)[:, 3].any()
    assert not state.update({"ow_edge_pass": 1})  # another program's uniform: not this block's


def test_a_short_array_writes_its_first_elements_and_a_wrong_size_is_refused():
    block = _block("short", (Uniform("vec4", "v", 4),))
    state = BlockState(block)
    state.update({"v": [[1, 1, 1, 1], [2, 2, 2, 2]]})
    words = np.frombuffer(state.data, np.float32).reshape(4, 4)
    assert np.array_equal(words[:2], [[1] * 4, [2] * 4]) and not words[2:].any()
    with pytest.raises(ValueError, match="cannot take 5 values"):
        state.update({"v": [1, 2, 3, 4, 5]})
    with pytest.raises(ValueError, match="cannot take"):
        state.update({"v": np.zeros((5, 4))})


def test_every_program_lays_out():
    """Every program and variant a backend may build has a block (the types all lay out)."""
    from addon.render.shaders import PROGRAMS, VARIANT_PROGRAMS

    for iface in (*PROGRAMS, *VARIANT_PROGRAMS):
        block = UniformBlock.of(iface)
        assert len(block.members) == len(iface.uniforms) and block.size % 16 == 0
        ends = sorted((m.offset, m.offset + _span(m, m.count)) for m in block.members)
        assert all(a[1] <= b[0] for a, b in zip(ends, ends[1:])), iface.name  # no two members overlap


def test_a_name_no_program_declares_is_refused_by_name(gl_backend):
    """A frame's shared dictionaries carry other programs' uniforms, which a program skips;
    a name no program declares (a typo) is refused with its name, on the block and on the
    device, instead of being dropped."""
    from addon.core.errors import BackendError
    from addon.render.shaders import EDGE_PROGRAM, FOOTPRINT_PROGRAM

    state = BlockState(UniformBlock.of(EDGE_PROGRAM))
    other = next(u.name for u in FOOTPRINT_PROGRAM.uniforms if UniformBlock.of(EDGE_PROGRAM).member(u.name) is None)
    state.update({other: 0})  # another program's uniform: skipped
    with pytest.raises(BackendError, match="ow_layer_rott"):
        state.update({"ow_layer_rott": np.eye(3)})
    with pytest.raises(BackendError, match="ow_no_such_uniform"):
        gl_backend.device.draw(EDGE_PROGRAM, {"ow_no_such_uniform": 1.0}, gl_backend.textures)
