"""GPU constants have one source: the host emits them into every program's header."""
from __future__ import annotations

import re

import numpy as np
import pytest

from addon.core import footprint, projection
from addon.render.shaders import PARAM_CODES, SHADER_DIR, SHARED_DEFINES, SLOTS, ComputeInterface
from tests.support import glsl

pytestmark = pytest.mark.gl

_NAMES = sorted(SHARED_DEFINES)


def test_no_shader_file_spells_out_a_shared_constant():
    for path in sorted(SHADER_DIR.rglob("*.*")):
        text = path.read_text(encoding="utf-8")
        for name in _NAMES:
            assert not re.search(rf"#define\s+{name}\b|const\s+\w+\s+{name}\b", text), (path.name, name)


def test_a_compiled_shader_sees_the_hosts_values(gl_backend):
    """A compute shader built from the generated header writes every shared constant out."""
    body = "void main()\n{\n" + "".join(
        f"  imageStore(ow_out, ivec2({i}, 0), uvec4(floatBitsToUint(float({name}))));\n"
        for i, name in enumerate(_NAMES)) + "}\n"
    iface = ComputeInterface(name="shared", compute_file=glsl.TEST_SOURCE, images=(("r32ui", "ow_out"),), local_size=1)
    ctx = gl_backend.ctx
    with ctx:
        program = ctx.compute_shader(glsl.compute_source(iface, body))
        out = ctx.texture((len(_NAMES), 1), 1, dtype="u4")
        out.bind_to_image(0, read=False, write=True)
        program.run(1)
        ctx.memory_barrier()
        got = dict(zip(_NAMES, np.frombuffer(out.read(), dtype="u4").view(np.float32)))
        out.release()
        program.release()
    for name, code in PARAM_CODES.items():
        assert got[f"OW_PARAM_{name.upper()}"] == code
    assert got["OW_KIND_PARABOLOID"] == projection.PARABOLOID and got["OW_KIND_CUBE"] == projection.CUBE
    assert got["OW_KIND_UNFOLD"] == projection.UNFOLD and got["OW_SLOTS"] == SLOTS
    assert got["OW_EDGE_ON"] == np.float32(footprint.GPU_EDGE_ON)
