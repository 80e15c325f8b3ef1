"""moderngl backend: a standalone EGL context, no window, no Blender.

One GL owner per process (DESIGN.md section 3): never use this backend in a
process that also draws with Blender's `gpu` module or renders EEVEE.
"""
from __future__ import annotations

import functools
import logging

import numpy as np

from ..core.errors import BackendError
from .backend import AtlasLayout, ShadowBackend, UniformValues
from .shaders import DEPTH_PROGRAM, SHADOW_TEST_PROGRAM, ProgramInterface, moderngl_sources

log = logging.getLogger(__name__)

_FULLSCREEN = np.array([[-1.0, -1.0], [3.0, -1.0], [-1.0, 3.0]], dtype="f4")


def _uniform_bytes(value: object) -> bytes | None:
    """Raw bytes for matrix and array uniforms (column-major, as GLSL expects)."""
    arr = np.asarray(value)
    if arr.ndim >= 2 and arr.shape[-2:] == (3, 3):
        return np.ascontiguousarray(np.swapaxes(arr, -1, -2), dtype="f4").tobytes()
    if arr.ndim == 2:
        return np.ascontiguousarray(arr, dtype="f4").tobytes()
    return None


def _current(method):
    """Run a method with this backend's context current.

    Several standalone contexts may live in one process (tests, a CLI run next to a
    fixture); GL calls go to whichever is current, so each entry point binds its own.
    Only the outermost call binds: leaving a nested `with ctx:` would unbind it
    while the outer call still draws.
    """

    @functools.wraps(method)
    def bound(self, *args, **kwargs):
        if self._bound:
            return method(self, *args, **kwargs)
        with self.ctx:
            self._bound = True
            try:
                return method(self, *args, **kwargs)
            finally:
                self._bound = False

    return bound


class ModernGLBackend(ShadowBackend):
    """Shadow backend on moderngl's standalone context."""

    name = "moderngl"

    def __init__(self, backend: str = "egl") -> None:
        try:
            import moderngl
        except ImportError as exc:  # the package is a hard dependency of the CLI
            raise BackendError("moderngl is not installed; run scripts/setup_env.sh") from exc
        self._mgl = moderngl
        try:
            self.ctx = moderngl.create_standalone_context(backend=backend)
        except Exception as exc:  # moderngl raises plain Exception when EGL is missing
            raise BackendError(
                f"could not create a standalone {backend.upper()} OpenGL context ({exc}); "
                "install Mesa EGL: apt install libegl1 libegl-mesa0 libgl1-mesa-dri"
            ) from exc
        self._bound = False
        self._programs: dict[str, object] = {}
        self._atlas_layout: AtlasLayout | None = None
        self._atlas = self._atlas_depth = self._atlas_fbo = None
        self._test_targets: dict[tuple[int, int], tuple] = {}
        self._fullscreen_vbo = self.ctx.buffer(_FULLSCREEN.tobytes())
        self._fullscreen_vao = None
        self._released = False

    # programs ---------------------------------------------------------------
    @_current
    def program(self, iface: ProgramInterface):
        """Compile (once) and return the program for an interface."""
        prog = self._programs.get(iface.name)
        if prog is None:
            vertex, fragment = moderngl_sources(iface)
            try:
                prog = self.ctx.program(vertex_shader=vertex, fragment_shader=fragment)
            except Exception as exc:  # moderngl reports compile errors as plain Exception
                raise BackendError(f"GLSL program {iface.name} failed to build: {exc}") from exc
            for binding, sampler in enumerate(iface.samplers):
                if sampler in prog:
                    prog[sampler].value = binding
            self._programs[iface.name] = prog
        return prog

    @staticmethod
    def _set_uniforms(prog, uniforms: UniformValues) -> None:
        for name, value in uniforms.items():
            if name not in prog:
                continue  # optimised away by the GLSL compiler
            raw = _uniform_bytes(value)
            if raw is not None:
                prog[name].write(raw)
            elif isinstance(value, (tuple, list, np.ndarray)):
                prog[name].value = tuple(float(v) for v in np.asarray(value).ravel())
            else:
                prog[name].value = value

    # interface --------------------------------------------------------------
    @_current
    def renderer(self) -> str:
        info = self.ctx.info
        return f"{info['GL_RENDERER']} | OpenGL {info['GL_VERSION']}"

    @_current
    def max_texture_size(self) -> int:
        return int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])

    @_current
    def begin_atlas(self, layout: AtlasLayout) -> None:
        if self._atlas_layout != layout:
            self._free_atlas()
            self._atlas = self.ctx.texture(layout.size, 1, dtype="f4")
            self._atlas.filter = (self._mgl.NEAREST, self._mgl.NEAREST)
            self._atlas_depth = self.ctx.depth_renderbuffer(layout.size)
            self._atlas_fbo = self.ctx.framebuffer(color_attachments=[self._atlas], depth_attachment=self._atlas_depth)
            self._atlas_layout = layout
        self._atlas_fbo.use()
        self._atlas_fbo.viewport = (0, 0) + layout.size
        self._atlas_fbo.clear(1.0, 1.0, 1.0, 1.0, depth=1.0)

    @_current
    def draw_layer(self, tile: int, vertices: np.ndarray, uniforms: UniformValues) -> None:
        if self._atlas_layout is None:
            raise BackendError("draw_layer called before begin_atlas")
        if len(vertices) == 0:
            return
        prog = self.program(DEPTH_PROGRAM)
        self._set_uniforms(prog, uniforms)
        data = np.ascontiguousarray(vertices, dtype="f4")
        vbo = self.ctx.buffer(data.tobytes())
        try:
            vao = self.ctx.vertex_array(prog, [(vbo, "3f 4f 2f", "ow_position", "ow_plane", "ow_range")])
            try:
                x, y = self._atlas_layout.origin(tile)
                res = self._atlas_layout.resolution
                self._atlas_fbo.use()
                self._atlas_fbo.viewport = (x, y, res, res)
                self.ctx.enable(self._mgl.DEPTH_TEST)
                self.ctx.disable(self._mgl.CULL_FACE)  # both windings cast shadows
                self.ctx.depth_func = "<"
                vao.render(self._mgl.TRIANGLES)
            finally:
                vao.release()
        finally:
            vbo.release()
            self.ctx.disable(self._mgl.DEPTH_TEST)

    def _targets(self, size: tuple[int, int]):
        found = self._test_targets.get(size)
        if found is None:
            pos = self.ctx.texture(size, 4, dtype="f4")
            nrm = self.ctx.texture(size, 4, dtype="f4")
            out = self.ctx.texture(size, 2, dtype="f4")
            for tex in (pos, nrm, out):
                tex.filter = (self._mgl.NEAREST, self._mgl.NEAREST)
            fbo = self.ctx.framebuffer(color_attachments=[out])
            found = (pos, nrm, out, fbo)
            self._test_targets[size] = found
        return found

    @_current
    def shadow_test(self, positions: np.ndarray, normals: np.ndarray, uniforms: UniformValues) -> np.ndarray:
        if self._atlas is None:
            raise BackendError("shadow_test called before any atlas exists")
        height, width = positions.shape[:2]
        pos, nrm, out, fbo = self._targets((width, height))
        pos.write(np.ascontiguousarray(positions, dtype="f4").tobytes())
        nrm.write(np.ascontiguousarray(normals, dtype="f4").tobytes())
        prog = self.program(SHADOW_TEST_PROGRAM)
        self._set_uniforms(prog, uniforms)
        if self._fullscreen_vao is None:
            self._fullscreen_vao = self.ctx.vertex_array(prog, [(self._fullscreen_vbo, "2f", "ow_corner")])
        pos.use(0)
        nrm.use(1)
        self._atlas.use(2)
        fbo.use()
        fbo.viewport = (0, 0, width, height)
        self.ctx.disable(self._mgl.DEPTH_TEST)
        self._fullscreen_vao.render(self._mgl.TRIANGLES)
        raw = out.read()
        return np.frombuffer(raw, dtype="f4").reshape(height, width, 2).copy()

    @_current
    def read_atlas(self) -> np.ndarray:
        if self._atlas is None or self._atlas_layout is None:
            raise BackendError("no atlas to read")
        width, height = self._atlas_layout.size
        return np.frombuffer(self._atlas.read(), dtype="f4").reshape(height, width).copy()

    @_current
    def finish(self) -> None:
        self.ctx.finish()

    def _free_atlas(self) -> None:
        for obj in (self._atlas_fbo, self._atlas, self._atlas_depth):
            if obj is not None:
                obj.release()
        self._atlas = self._atlas_depth = self._atlas_fbo = None
        self._atlas_layout = None

    def release(self) -> None:
        if self._released:
            return
        with self.ctx:
            self._free_atlas()
            for pos, nrm, out, fbo in self._test_targets.values():
                for obj in (fbo, out, nrm, pos):
                    obj.release()
            self._test_targets.clear()
            if self._fullscreen_vao is not None:
                self._fullscreen_vao.release()
            self._fullscreen_vbo.release()
            for prog in self._programs.values():
                prog.release()
            self._programs.clear()
        self.ctx.release()
        self._released = True
