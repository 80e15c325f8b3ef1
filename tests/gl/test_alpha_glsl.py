"""gpu_shaders/lib/alpha.glsl against its numpy oracle (addon/core/alpha.py AlphaMap.sample).

A harness fragment program takes one UV per texel column and writes the alpha there,
for every interpolation and extension, on a small random image with a transfer curve.
"""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.alpha import EXTENSIONS, INTERPOLATIONS, TRANSFER_SIZE, AlphaMap
from addon.render.shaders import Uniform
from tests.support import glsl

pytestmark = pytest.mark.gl

HARNESS = """#include "lib/alpha.glsl"
void main() {
  vec2 uv = texelFetch(ow_input, ivec2(int(gl_FragCoord.x), 0), 0).xy;
  ow_out = vec4(ow_alpha_at(uv), 0.0, 0.0, 1.0);
}
"""


def _glsl_alpha(gl_backend, amap: AlphaMap, uv: np.ndarray) -> np.ndarray:
    vs, fs = glsl.program("alpha_harness", HARNESS, uniforms=(Uniform("int", "ow_alpha_mode"),),
                          samplers=("ow_input", "ow_alpha_image", "ow_alpha_transfer"))
    ctx = gl_backend.ctx
    with ctx:
        prog = ctx.program(vertex_shader=vs, fragment_shader=fs)
        data = np.zeros((1, len(uv), 4), dtype="f4")
        data[0, :, :2] = uv
        table = amap.transfer_table()
        textures = [ctx.texture((len(uv), 1), 4, data.tobytes(), dtype="f4"),
                    ctx.texture(amap.image.shape[::-1], 1, amap.image.tobytes(), dtype="f4"),
                    ctx.texture((len(table), 1), 1, table.tobytes(), dtype="f4")]
        out = ctx.texture((len(uv), 1), 4, dtype="f4")
        fbo = ctx.framebuffer(color_attachments=[out])
        vbo = ctx.buffer(np.array([[-1, -1], [3, -1], [-1, 3]], dtype="f4").tobytes())
        vao = ctx.vertex_array(prog, [(vbo, "2f", "ow_corner")])
        try:
            for unit, (texture, name) in enumerate(zip(textures, ("ow_input", "ow_alpha_image", "ow_alpha_transfer"))):
                texture.filter = (gl_backend._mgl.NEAREST, gl_backend._mgl.NEAREST)
                texture.use(unit)
                prog[name].value = unit
            block = glsl.uniform_buffer(ctx, "alpha_harness", (Uniform("int", "ow_alpha_mode"),),
                                        {"ow_alpha_mode": amap.mode})
            textures.append(block)  # released with them
            fbo.use()
            fbo.viewport = (0, 0, len(uv), 1)
            vao.render()
            return np.frombuffer(out.read(), dtype="f4").reshape(-1, 4)[:, 0].astype(np.float64)
        finally:
            for obj in (vao, vbo, fbo, out, *textures, prog):
                obj.release()


@pytest.mark.parametrize("interpolation", INTERPOLATIONS)
@pytest.mark.parametrize("extension", EXTENSIONS)
def test_alpha_lookup_matches_numpy(gl_backend, interpolation, extension):
    rng = np.random.default_rng(7)
    image = rng.uniform(0.0, 1.0, size=(5, 7)).astype(np.float32)
    transfer = np.linspace(0.0, 1.0, TRANSFER_SIZE) ** 2  # a curve, so the table is read
    amap = AlphaMap("m", image, interpolation, extension, transfer)
    # UVs inside, outside and far outside the square; none on a texel boundary, where
    # closest lookup may round either way.
    uv = rng.uniform(-2.3, 3.1, size=(400, 2))
    cell = np.array([7.0, 5.0])
    uv += np.where(np.abs((uv * cell) - np.round(uv * cell)) < 1e-3, 2e-3, 0.0) / cell
    expected = amap.sample(uv)
    got = _glsl_alpha(gl_backend, amap, uv)
    assert np.max(np.abs(got - expected)) < 2e-4, (interpolation, extension)
    if extension == "clip":
        outside = np.any((uv < 0.0) | (uv > 1.0), axis=1) & (interpolation == "closest")
        assert np.all(got[outside] == 0.0)
