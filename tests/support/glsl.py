"""The one GLSL test harness: a small test shader compiled through the shader loader.

A test writes a fragment (or compute) body that includes the shipped `lib/*.glsl` files;
the loader resolves those includes in `gpu_shaders/` (its include path), so no test copies
a shader file. `evaluate` runs a fragment harness once per input column on a tiny target.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from addon.render.backends.moderngl.glsl import compute_header, glsl_header
from addon.render.backends.moderngl.uniforms import BLOCK_BINDING
from addon.render.shaders import SHADER_DIR, ComputeInterface, ProgramInterface, Uniform, expand_source, load_source
from addon.render.shaders.uniform_block import BlockState, UniformBlock

VERTEX = "fullscreen.vert"  # a triangle over the whole target, `ow_corner` its corners
TEST_SOURCE = "<test shader>"  # the file name a harness interface gives its own stage


def _expand(text: str) -> str:
    return expand_source(text, SHADER_DIR, include_path=(SHADER_DIR,))


def sources(iface: ProgramInterface, fragment: str) -> tuple[str, str]:
    """moderngl's vertex and fragment sources of `iface`: its shipped vertex stage, and the
    test's fragment text with its includes resolved through the loader."""
    vertex = glsl_header(iface, "vertex") + load_source(iface.vertex_file)
    return vertex, glsl_header(iface, "fragment") + _expand(fragment)


def program(name: str, fragment: str, uniforms: Iterable[Uniform] = (), samplers: Sequence[str] = ("ow_input",),
            outputs: Sequence[tuple[str, str]] = (("vec4", "ow_out"),)) -> tuple[str, str]:
    """The sources of a full-screen test program: `fragment` (it may include lib/ files)
    writes `outputs`, and reads the declared uniforms and samplers."""
    iface = ProgramInterface(name=name, vertex_file=VERTEX, fragment_file=TEST_SOURCE,
                             vertex_in=(("vec2", "ow_corner"),), fragment_out=tuple(outputs),
                             uniforms=tuple(uniforms), samplers=tuple(samplers))
    return sources(iface, fragment)


def uniform_buffer(ctx, name: str, uniforms: Iterable[Uniform], values: dict):
    """A harness's uniform block (the program `name` declared with `uniforms`) holding
    `values`, bound where the program reads it; the caller releases it."""
    iface = ProgramInterface(name=name, vertex_file=VERTEX, fragment_file=TEST_SOURCE, vertex_in=(),
                             fragment_out=(), uniforms=tuple(uniforms))
    state = BlockState(UniformBlock.of(iface))
    state.update(values)
    buffer = ctx.buffer(state.data)
    buffer.bind_to_uniform_block(BLOCK_BINDING)
    return buffer


def without_blocks(text: str, directive: str, define: str) -> str:
    """`text` without its `#ifdef define` (or `#ifndef define`, as `directive` says) blocks,
    nested conditionals inside them included: what a variant defining (or not) `define`
    leaves of a source."""
    out, depth = [], 0
    for line in text.splitlines(keepends=True):
        word = line.strip().split()[0] if line.strip() else ""
        if depth:
            depth += 1 if word in ("#ifdef", "#ifndef", "#if") else -1 if word == "#endif" else 0
            continue
        if line.strip() == f"{directive} {define}":
            depth = 1
            continue
        out.append(line)
    return "".join(out)


def compute_source(iface: ComputeInterface, body: str) -> str:
    """moderngl's source of a compute test program: `iface`'s header and the test's body."""
    return compute_header(iface) + _expand(body)


def evaluate(ctx, vs: str, fs: str, inputs: np.ndarray, uniforms=(), name: str = "harness",
             tables: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """Run a harness once per input column: it reads `ow_input` and writes `ow_out`.
    `inputs` is (n, k <= 4), one texel per column, or (rows, n, 4), a column of `rows`
    texels each; `uniforms` are (type, name, value), as `program` declared them (in its
    order); `tables` are further RGBA32F samplers, (rows, width, 4) each, by name. One RGBA
    result per column."""
    with ctx:  # other contexts may have been current (the CLI tests make their own)
        prog = ctx.program(vertex_shader=vs, fragment_shader=fs)
        block = uniform_buffer(ctx, name, [Uniform(t, n) for t, n, _ in uniforms],
                               {n: v for _, n, v in uniforms}) if uniforms else None
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
        extra = []
        try:
            tex_in.use(0)
            prog["ow_input"].value = 0
            for unit, (sampler, table) in enumerate((tables or {}).items(), start=1):
                table = np.ascontiguousarray(table, dtype="f4")
                extra.append(ctx.texture((table.shape[1], table.shape[0]), 4, table.tobytes(), dtype="f4"))
                extra[-1].use(unit)
                prog[sampler].value = unit
            fbo.use()
            fbo.viewport = (0, 0, n, 1)
            vao.render()
            return np.frombuffer(tex_out.read(), dtype="f4").reshape(n, 4).astype(np.float64)
        finally:
            for obj in (vao, vbo, fbo, tex_out, tex_in, prog, *extra, *([block] if block else [])):
                obj.release()
