"""The shared GLSL library against the numpy core, evaluated per texel on tiny targets.

A small harness program includes the library, reads inputs from a float texture
and writes results to another; the numpy functions in addon/core are the oracle.
"""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import frames, projection
from addon.render.moderngl_glsl import moderngl_sources
from addon.render.shaders import ProgramInterface, Uniform

pytestmark = pytest.mark.gl

HARNESS_VERTEX = "fullscreen.vert"


def _run(gl_backend, body: str, inputs: np.ndarray, tmp_path, uniforms=()) -> np.ndarray:
    """Evaluate `body` (GLSL using `vec4 inp` and setting `vec4 outp`) for each input row."""
    shader_dir = tmp_path / "gpu_shaders"
    (shader_dir / "lib").mkdir(parents=True, exist_ok=True)
    from addon.render.shaders import SHADER_DIR

    for name in ("projection.glsl", "layers.glsl"):
        (shader_dir / "lib" / name).write_text((SHADER_DIR / "lib" / name).read_text())
    (shader_dir / HARNESS_VERTEX).write_text((SHADER_DIR / HARNESS_VERTEX).read_text())
    (shader_dir / "harness.frag").write_text(
        '#include "lib/projection.glsl"\n#include "lib/layers.glsl"\n'
        "void main() {\n  vec4 inp = texelFetch(ow_input, ivec2(gl_FragCoord.xy), 0);\n"
        "  vec4 outp = vec4(0.0);\n" + body + "\n  ow_out = outp;\n}\n"
    )
    iface = ProgramInterface(
        name="harness", vertex_file=HARNESS_VERTEX, fragment_file="harness.frag",
        vertex_in=(("vec2", "ow_corner"),), fragment_out=(("vec4", "ow_out"),),
        uniforms=tuple(Uniform(t, n) for t, n, _ in uniforms), samplers=("ow_input",),
    )
    vs, fs = moderngl_sources(iface, shader_dir)
    with gl_backend.ctx:  # other contexts may have been current (the CLI tests make their own)
        return _evaluate(gl_backend.ctx, vs, fs, inputs, uniforms)


def _evaluate(ctx, vs, fs, inputs, uniforms):
    """Run the harness once per input column. `inputs` is (n, k <= 4), one texel per
    column, or (rows, n, 4), a column of `rows` texels each; one RGBA result per column."""
    prog = ctx.program(vertex_shader=vs, fragment_shader=fs)
    for _, name, value in uniforms:
        prog[name].value = value
    if inputs.ndim == 3:
        data = np.ascontiguousarray(inputs, dtype="f4")
    else:
        data = np.zeros((1, len(inputs), 4), dtype="f4")
        data[0, :, : inputs.shape[1]] = inputs
    n = data.shape[1]
    tex_in = ctx.texture((n, data.shape[0]), 4, data.tobytes(), dtype="f4")
    tex_out = ctx.texture((n, 1), 4, dtype="f4")
    fbo = ctx.framebuffer(color_attachments=[tex_out])
    vbo = ctx.buffer(np.array([[-1, -1], [3, -1], [-1, 3]], dtype="f4").tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "2f", "ow_corner")])
    try:
        tex_in.use(0)
        prog["ow_input"].value = 0
        fbo.use()
        fbo.viewport = (0, 0, n, 1)
        vao.render()
        return np.frombuffer(tex_out.read(), dtype="f4").reshape(n, 4).astype(np.float64)
    finally:
        for obj in (vao, vbo, fbo, tex_out, tex_in, prog):
            obj.release()


def _random_dirs(rng, n, half=None):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if half == "front":
        d[:, 2] = np.abs(d[:, 2])
    return d


def test_paraboloid_projection_matches_numpy(gl_backend, tmp_path):
    """ow_paraboloid_project and _unproject agree with the numpy core on random rays."""
    rng = np.random.default_rng(1)
    dirs = _random_dirs(rng, 200, "front") * rng.uniform(0.01, 100.0, size=(200, 1))
    got = _run(gl_backend, "outp.xy = ow_paraboloid_project(inp.xyz);", dirs, tmp_path)
    assert np.allclose(got[:, :2], projection.paraboloid_project(dirs), atol=2e-6)
    xy = rng.uniform(-0.7, 0.7, size=(200, 2))
    got = _run(gl_backend, "outp.xyz = ow_paraboloid_unproject(inp.xy);", xy, tmp_path)
    assert np.allclose(got[:, :3], projection.paraboloid_unproject(xy), atol=2e-6)


def test_cube_projection_and_texel_angle_match_numpy(gl_backend, tmp_path):
    """Cube projection and the texel-angle bound agree with the numpy core."""
    rng = np.random.default_rng(2)
    pts = np.column_stack([rng.uniform(-1, 1, 100), rng.uniform(-1, 1, 100), np.ones(100)]) * rng.uniform(0.1, 50, (100, 1))
    got = _run(gl_backend, "outp.xy = ow_cube_project(inp.xyz);", pts, tmp_path)
    assert np.allclose(got[:, :2], projection.cube_project(pts), atol=2e-6)
    xy = rng.uniform(-1, 1, size=(100, 2))
    for kind in (projection.PARABOLOID, projection.CUBE):
        got = _run(gl_backend, f"outp.x = ow_texel_angle({kind}, inp.xy, 512.0);", xy, tmp_path)
        assert np.allclose(got[:, 0], projection.texel_angle(kind, xy, 512), rtol=1e-5)


@pytest.mark.parametrize("param", ["dpsm", "cube"])
def test_layer_choice_matches_numpy(gl_backend, tmp_path, param):
    """ow_pick_slot picks the same layer as frames.pick_slot, including axis-aligned ties."""
    rng = np.random.default_rng(3)
    dirs = np.concatenate([_random_dirs(rng, 300), np.eye(3), -np.eye(3), [[1, 1, 0], [0, -1, 1], [1, 1, 1]]])
    code = 0 if param == "dpsm" else 1
    got = _run(gl_backend, f"outp.x = float(ow_pick_slot({code}, inp.xyz));", dirs, tmp_path)
    assert np.array_equal(got[:, 0].astype(int), frames.pick_slot(param, dirs))


def test_unfold_projection_matches_numpy(gl_backend, tmp_path):
    """ow_unfold_project/_unproject and the unfold texel angle agree with the numpy core,
    over the whole sphere (both hemispheres) and both poles."""
    rng = np.random.default_rng(4)
    dirs = np.concatenate([_random_dirs(rng, 300), [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]])
    pts = dirs * rng.uniform(0.01, 100.0, size=(len(dirs), 1))
    got = _run(gl_backend, "outp.xy = ow_unfold_project(inp.xyz);", pts, tmp_path)
    assert np.allclose(got[:, :2], projection.unfold_project(pts), atol=3e-6)
    xy = projection.unfold_project(dirs[:-3])
    got = _run(gl_backend, "outp.xyz = ow_unfold_unproject(inp.xy);", xy, tmp_path)
    assert np.allclose(got[:, :3], projection.unfold_unproject(xy), atol=3e-6)
    got = _run(gl_backend, f"outp.x = ow_texel_angle({projection.UNFOLD}, inp.xy, 512.0); outp.y = inp.x;", xy,
               tmp_path)  # (outp.y keeps the input sampler alive: the unfold bound is constant)
    assert np.allclose(got[:, 0], projection.texel_angle(projection.UNFOLD, xy, 512), rtol=1e-5)


def test_unfold_layer_choice_is_the_nearer_pole(gl_backend, tmp_path):
    """ow_pick_slot for unfold (code 3) is the nearer pole, as frames.pick_slot says."""
    rng = np.random.default_rng(5)
    dirs = np.concatenate([_random_dirs(rng, 300), np.eye(3), -np.eye(3)])
    got = _run(gl_backend, "outp.x = float(ow_pick_slot(3, inp.xyz));", dirs, tmp_path)
    assert np.array_equal(got[:, 0].astype(int), frames.pick_slot("unfold", dirs))
