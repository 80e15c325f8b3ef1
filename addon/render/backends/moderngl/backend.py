"""moderngl backend: a standalone EGL context, no window, no Blender.

The device adapter (`ModernGLDevice`) maps the primitives of device.py onto moderngl;
every pass is written once in render/passes. One GL owner per process (docs/design.md
section 3): never use this backend in a process that also draws with Blender's `gpu`
module or renders EEVEE.
"""
from __future__ import annotations

import contextlib
import logging
from typing import Any, Iterator

import numpy as np

from ....core import interrupt
from ....core.errors import BackendError
from ...backend import ShadowBackend
from ...device import (COMPONENTS, FULLSCREEN, FULLSCREEN_CORNERS, Device, Geometry, GPUTimer, Program, Rect, Target,
                     UniformValues)
from .gl_calls import gl_calls
from .glsl import moderngl_compute_source, moderngl_sources
from .uniforms import ProgramBlock
from ...passes.footprints import FOOTPRINT_VERTICES, corner_capacity, corner_indices
from ...shaders import ComputeInterface, ProgramInterface

log = logging.getLogger(__name__)

_FULLSCREEN = np.array(FULLSCREEN_CORNERS, dtype="f4")
_ATTRIBUTE_FORMATS = {"float": "1f", "vec2": "2f", "vec3": "3f", "vec4": "4f"}


_ALREADY_BOUND = contextlib.nullcontext()
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast")  # whose barriers wait for all queued work

class _Timer(GPUTimer):
    """A time-elapsed query over the work submitted inside `with`, its context bound there:
    our own query read as 64 bits (gl_calls), else moderngl's (32 bits: wraps at 4,295 ms)."""

    def __init__(self, device: "ModernGLDevice", query) -> None:
        self._device = device
        self._query = query  # a GL query name (int) with gl_calls, else a moderngl Query
        self._binding = contextlib.ExitStack()

    def __enter__(self) -> "_Timer":
        self._binding.enter_context(self._device.bound())
        if isinstance(self._query, int):
            gl_calls().begin_timer(self._query)
        else:
            self._query.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        try:
            if isinstance(self._query, int):
                gl_calls().end_timer()
            else:
                self._query.__exit__(*exc)
        finally:
            self._binding.close()

    @property
    def elapsed_ms(self) -> float:
        with self._device.bound():  # nanoseconds; reading it waits for the GPU
            if isinstance(self._query, int):
                return gl_calls().elapsed_ns(self._query) * 1e-6
            return self._query.elapsed * 1e-6


class ModernGLDevice(Device):
    """device.Device on moderngl's standalone context."""

    name = "moderngl"

    def __init__(self, backend: str = "egl") -> None:
        try:
            import moderngl
        except ImportError as exc:  # the package is a hard dependency of the CLI
            raise BackendError("moderngl is not installed; run scripts/setup_env.sh") from exc
        self._mgl = moderngl
        self.backend_name = backend
        try:
            self.ctx = moderngl.create_standalone_context(backend=backend)
        except Exception as exc:  # moderngl raises plain Exception when EGL is missing
            raise BackendError(
                f"could not create a standalone {backend.upper()} OpenGL context ({exc}); "
                "install Mesa EGL: apt install libegl1 libegl-mesa0 libgl1-mesa-dri"
            ) from exc
        self._bound = False
        self.programs: dict[str, Any] = {}
        self._uniforms: dict[str, ProgramBlock] = {}  # per program: its uniform block and buffer
        self._vaos: dict[str, Any] = {}  # a vertex array renders with the program it was made for
        self._clear_fbos: dict[int, Any] = {}  # id(texture) -> framebuffer that clears or reads it
        self._corners = None  # the footprint pass's corner buffer
        self._corner_triangles = 0
        self._queries: dict[str, Any] = {}  # timer queries by key (timer)
        self._software: bool | None = None  # a software rasteriser (llvmpipe): known at the first barrier
        with self.bound():
            self._fullscreen = self.ctx.buffer(_FULLSCREEN.tobytes())

    def bound(self) -> contextlib.AbstractContextManager:
        # Several standalone contexts may live in one process (tests, a CLI run next to a
        # fixture); only the outermost call binds, since leaving a nested `with ctx:` would
        # unbind it while the outer call still draws. A nested call (every call inside a
        # frame) costs one shared no-op context.
        return _ALREADY_BOUND if self._bound else self._binding()

    @contextlib.contextmanager
    def _binding(self) -> Iterator[None]:
        with self.ctx:
            self._bound = True
            try:
                yield
            finally:
                self._bound = False

    def renderer(self) -> str:
        with self.bound():
            info = self.ctx.info
            return f"{info['GL_RENDERER']} | OpenGL {info['GL_VERSION']}"

    def max_texture_size(self) -> int:
        with self.bound():
            return int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])

    # programs -----------------------------------------------------------------
    def program(self, iface: Program):
        """Compile (once) and return the program or compute shader of an interface."""
        prog = self.programs.get(iface.name)
        if prog is None:
            # Deferred: the Ctrl-C handler raising while moderngl compiles segfaulted the
            # process (10 of 30 interrupted compares, 2026-12-02; deferring the Python
            # handler did not: 0 of 32). The interruption is raised once the program is kept.
            with interrupt.deferred(), self.bound():
                prog = self._build(iface)
        return prog

    def _build(self, iface: Program):
        try:
            if isinstance(iface, ComputeInterface):
                prog = self.ctx.compute_shader(moderngl_compute_source(iface))
            else:
                vertex, fragment = moderngl_sources(iface)
                prog = self.ctx.program(vertex_shader=vertex, fragment_shader=fragment)
        except Exception as exc:  # moderngl reports compile errors as plain Exception
            raise BackendError(f"GLSL program {iface.name} failed to build: {exc}") from exc
        for binding, sampler in enumerate(iface.samplers):
            if sampler in prog:
                prog[sampler].value = binding
        self.programs[iface.name] = prog
        return prog

    def _use(self, iface: Program, uniforms: UniformValues, textures: dict[str, Any],
             images: dict[str, Any] | None):
        prog = self.program(iface)
        block = self._uniforms.get(iface.name)
        if block is None:
            block = self._uniforms[iface.name] = ProgramBlock(self.ctx, iface)
        block.use(uniforms)
        for binding, sampler in enumerate(iface.samplers):
            texture = textures.get(sampler)
            if texture is None:
                raise BackendError(f"{iface.name}: no texture for sampler {sampler}")
            texture.use(binding)
        for unit, (_, name) in enumerate(iface.images if images else ()):
            images[name].bind_to_image(unit, read=True, write=True)
        return prog

    # resources ----------------------------------------------------------------
    def texture(self, size: tuple[int, int], fmt: str, data: np.ndarray | None = None):
        raw = None if data is None else np.ascontiguousarray(data, dtype="u4" if fmt == "R32UI" else "f4").tobytes()
        with self.bound():
            tex = self.ctx.texture(size, COMPONENTS[fmt], raw, dtype="u4" if fmt == "R32UI" else "f4")
            tex.filter = (self._mgl.NEAREST, self._mgl.NEAREST)
        return tex

    def upload(self, texture, size: tuple[int, int], fmt: str, data: np.ndarray):
        if texture is not None and texture.size == tuple(size) and texture.components == COMPONENTS[fmt]:
            with self.bound():
                texture.write(np.ascontiguousarray(data, dtype="u4" if fmt == "R32UI" else "f4").tobytes())
            return texture
        self.free(texture)
        return self.texture(size, fmt, data)

    def free(self, *objects: Any) -> None:
        with self.bound():
            for obj in objects:
                if obj is None:
                    continue
                if isinstance(obj, Target):
                    obj.handle.release()
                    if obj.depth is not None:
                        obj.depth.release()
                    continue
                fbo = self._clear_fbos.pop(id(obj), None)
                if fbo is not None:
                    fbo.release()
                obj.release()

    def texture_size(self, texture) -> tuple[int, int]:
        return tuple(texture.size)

    def target(self, colors: tuple[Any, ...], depth: bool = False) -> Target:
        size = tuple(colors[0].size)
        with self.bound():
            depth_buffer = self.ctx.depth_renderbuffer(size) if depth else None
            fbo = self.ctx.framebuffer(color_attachments=list(colors), depth_attachment=depth_buffer)
        return Target(fbo, tuple(colors), size, depth_buffer)

    def clear(self, target: Target, color, depth: float | None = None, rects: list[Rect] | None = None) -> None:
        with self.bound():
            fbo = target.handle
            fbo.use()
            fbo.viewport = (0, 0) + target.size
            for rect in rects if rects is not None else (None,):
                fbo.clear(*color, depth=1.0 if depth is None else depth, viewport=rect)  # a scissored clear

    def clear_image(self, image) -> None:
        # Through a framebuffer (an integer clear per attachment, on the GPU): about 3x
        # faster on llvmpipe than writing zeros from the host.
        with self.bound():
            self._framebuffer_of(image).clear(0.0, 0.0, 0.0, 0.0)

    def _framebuffer_of(self, texture):
        """A framebuffer over one texture, made once: it clears an image and reads a rect."""
        fbo = self._clear_fbos.get(id(texture))
        if fbo is None:
            fbo = self._clear_fbos[id(texture)] = self.ctx.framebuffer(color_attachments=[texture])
        return fbo

    def read(self, texture, fmt: str, rect: Rect | None = None) -> np.ndarray:
        dtype = "u4" if fmt == "R32UI" else "f4"
        with self.bound():
            self._wait()  # a read waits for the GPU anyway: wait without the GIL
            if rect is None:
                raw = np.frombuffer(texture.read(), dtype=dtype)
            else:  # textures read whole only: a rect is read through a framebuffer
                data = self._framebuffer_of(texture).read(viewport=rect, components=COMPONENTS[fmt], dtype=dtype)
                raw = np.frombuffer(data, dtype=dtype)
        width, height = texture.size if rect is None else rect[2:]
        return raw.reshape((height, width) + ((COMPONENTS[fmt],) if COMPONENTS[fmt] > 1 else ())).copy()

    # work ---------------------------------------------------------------------
    @contextlib.contextmanager
    def drawing(self, target: Target, viewport: Rect, scissor: Rect | None = None,
                depth_test: bool = False) -> Iterator[None]:
        with self.bound():
            fbo = target.handle
            fbo.use()
            fbo.viewport = viewport
            fbo.scissor = viewport if scissor is None else scissor
            if depth_test:
                self.ctx.enable(self._mgl.DEPTH_TEST)
                self.ctx.disable(self._mgl.CULL_FACE)  # both windings cast shadows
                self.ctx.depth_func = "<"
            else:
                self.ctx.disable(self._mgl.DEPTH_TEST)
            try:
                yield
            finally:
                self.ctx.disable(self._mgl.DEPTH_TEST)
                self.ctx.disable(self._mgl.PROGRAM_POINT_SIZE)
                fbo.scissor = None  # the whole framebuffer again

    def draw(self, iface: ProgramInterface, uniforms: UniformValues, textures: dict[str, Any],
             geometry: Geometry = FULLSCREEN, images: dict[str, Any] | None = None) -> None:
        with self.bound():
            prog = self._use(iface, uniforms, textures, images)
            if geometry.kind == "vertices":
                self._draw_arrays(prog, iface, geometry.arrays)
                return
            if geometry.kind == "corners":
                self._ensure_corners(geometry.first + geometry.count)
            key = f"{iface.name}:{geometry.kind}"
            vao = self._vaos.get(key)
            if vao is None:
                source = ((self._corners, "1f", "ow_corner") if geometry.kind == "corners"
                          else (self._fullscreen, "2f", "ow_corner"))
                vao = self._vaos[key] = self.ctx.vertex_array(prog, [source])
            if geometry.kind == "fullscreen":
                vao.render(self._mgl.TRIANGLES)
            elif geometry.points:
                # One vertex per triangle: vertex i of the corner buffer is triangle i.
                self.ctx.enable(self._mgl.PROGRAM_POINT_SIZE)
                vao.render(self._mgl.POINTS, vertices=geometry.count, first=geometry.first)
            else:
                vao.render(self._mgl.TRIANGLES, vertices=geometry.count * FOOTPRINT_VERTICES,
                           first=geometry.first * FOOTPRINT_VERTICES)

    def _draw_arrays(self, prog, iface: ProgramInterface, arrays: dict[str, np.ndarray]) -> None:
        types = dict((name, glsl_type) for glsl_type, name in iface.vertex_in)
        buffers = [(self.ctx.buffer(np.ascontiguousarray(data, dtype="f4").tobytes()), _ATTRIBUTE_FORMATS[types[name]],
                    name) for name, data in arrays.items()]
        try:
            vao = self.ctx.vertex_array(prog, buffers)
            try:
                vao.render(self._mgl.TRIANGLES)
            finally:
                vao.release()
        finally:
            for buffer, _, _ in buffers:
                buffer.release()

    def _ensure_corners(self, triangles: int) -> None:
        """A corner buffer for at least `triangles` (the footprint vertex arrays use it)."""
        capacity = corner_capacity(triangles, self._corner_triangles)
        if capacity == self._corner_triangles:
            return
        for name in [n for n in self._vaos if n.endswith(":corners")]:
            self._vaos.pop(name).release()  # they point at the old buffer
        if self._corners is not None:
            self._corners.release()
        self._corners = self.ctx.buffer(corner_indices(capacity).tobytes())
        self._corner_triangles = capacity

    def dispatch(self, iface: ComputeInterface, uniforms: UniformValues, textures: dict[str, Any],
                 images: dict[str, Any], groups: int) -> None:
        with self.bound():
            self._use(iface, uniforms, textures, images).run(group_x=groups)
            self.barrier()  # image stores, before later loads and read-backs

    def barrier(self) -> None:
        with self.bound():
            if self._software is None:
                self._software = any(name in self.ctx.info["GL_RENDERER"].lower() for name in SOFTWARE_RENDERERS)
            if self._software:
                # A software rasteriser's barrier is a full wait, which moderngl makes holding
                # the GIL: wait without it first (a GPU's barrier does not wait; left alone).
                self._wait()
            self.ctx.memory_barrier()

    def finish(self, target: Target | None = None) -> None:
        with self.bound():
            self._wait()

    def _wait(self) -> None:
        """Block until the GPU is done, without the GIL where EGL gives glFinish (gl_calls)."""
        calls = self._calls()
        if calls is not None:
            calls.finish()
        else:
            self.ctx.finish()

    def _calls(self):
        """The ctypes GL calls, for an EGL context (they are found through EGL)."""
        return gl_calls() if self.backend_name == "egl" else None

    def timer(self, key: str = "frame") -> GPUTimer:
        # One query a key, made once and reused (moderngl cannot free a query before the context).
        query = self._queries.get(key)
        if query is None:
            with self.bound():
                calls = self._calls()
                query = self._queries[key] = calls.new_timer() if calls is not None else self.ctx.query(time=True)
        return _Timer(self, query)

    def release(self) -> None:
        with self.bound():
            for obj in (*self._vaos.values(), *self._clear_fbos.values(), *self.programs.values()):
                obj.release()
            self._vaos.clear()
            self._clear_fbos.clear()
            self.programs.clear()
            for block in self._uniforms.values():
                block.release()
            self._uniforms.clear()
            self._fullscreen.release()
            if self._corners is not None:
                self._corners.release()
                self._corners = None
            for query in self._queries.values():
                if isinstance(query, int):  # ours (gl_calls); moderngl's go with the context
                    gl_calls().delete(query)
            self._queries.clear()
        self.ctx.release()  # not bound: leaving `with ctx` would touch the released context


class ModernGLBackend(ShadowBackend):
    """Shadow backend on moderngl's standalone context."""

    name = "moderngl"

    def __init__(self, backend: str = "egl") -> None:
        super().__init__(ModernGLDevice(backend))
        self.ctx = self.device.ctx
        self._mgl = self.device._mgl

    @property
    def _programs(self) -> dict[str, Any]:
        return self.device.programs

    def program(self, iface: Program):
        """Compile (once) and return the program (or compute shader) for an interface."""
        return self.device.program(iface)
