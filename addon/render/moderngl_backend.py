"""moderngl backend: a standalone EGL context, no window, no Blender.

One GL owner per process (docs/design.md section 3): never use this backend in a
process that also draws with Blender's `gpu` module or renders EEVEE.
"""
from __future__ import annotations

import functools
import logging

import numpy as np

from ..core import interrupt
from ..core.errors import BackendError
from ..core.samples import STAT_SPAN, STAT_TEXELS
from .backend import (
    FULLSCREEN_CORNERS,
    AtlasLayout,
    FootprintDraw,
    ShadowBackend,
    UniformValues,
    corner_capacity,
    corner_indices,
    pack_warp_table,
)
from .moderngl_glsl import moderngl_compute_source, moderngl_sources
from .shaders import (
    ADVANCE_PROGRAM,
    ALPHA_SAMPLERS,
    DEPTH_PROGRAM,
    EDGE_PROGRAM,
    FOOTPRINT_PROGRAM,
    FOOTPRINT_VERTICES,
    RAY_TABLE_PROGRAM,
    SAMPLE_STATS_PROGRAM,
    VEIL_IMAGES,
    WORK_TEXELS,
    ComputeInterface,
    ProgramInterface,
    link_variant,
    program_variant,
    scatter_variant,
)

log = logging.getLogger(__name__)

_FULLSCREEN = np.array(FULLSCREEN_CORNERS, dtype="f4")


def _uniform_bytes(value: object, glsl_type: str = "") -> bytes | None:
    """Raw bytes for matrix and array uniforms (matrices column-major, as GLSL expects)."""
    arr = np.asarray(value)
    if glsl_type.startswith("mat") or (arr.ndim >= 2 and arr.shape[-2:] == (3, 3)):
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
        super().__init__()
        self._mgl = moderngl
        try:
            self.ctx = moderngl.create_standalone_context(backend=backend)
        except Exception as exc:  # moderngl raises plain Exception when EGL is missing
            raise BackendError(
                f"could not create a standalone {backend.upper()} OpenGL context ({exc}); "
                "install Mesa EGL: apt install libegl1 libegl-mesa0 libgl1-mesa-dri"
            ) from exc
        self._bound = False
        self._released = False
        self._programs: dict[str, object] = {}
        self._atlas_layout: AtlasLayout | None = None
        self._atlas = self._atlas_depth = self._atlas_fbo = None
        # Textures bound by sampler name; the warp tables start as 1x1 dummies.
        self._textures: dict[str, object] = {}
        self._sample_size: tuple[int, int] | None = None
        self._test_target = None  # (texture, framebuffer) of the sample size
        self._count_targets: dict[int, object] = {}  # count-map size -> R32UI strip of its tiles
        self._stats_target = None  # R32UI row of the planning statistics (reduce_samples)
        self._links = None  # (heads strip, next links) of link_samples, R32UI
        self._veil_fbo = None  # the veil's images as one framebuffer, for their clear
        self._link_fbos: tuple = ()  # the lists' images as framebuffers, for their clears
        with self.ctx:
            self._fullscreen_vbo = self.ctx.buffer(_FULLSCREEN.tobytes())
            self._set_table("ow_warp_rows", None)
            self._set_table("ow_warp_cols", None)
            # Read only by warped footprint draws, after build_ray_table replaced it.
            self._textures["ow_ray_table"] = self._float_texture((1, 1), 2, np.zeros(2, "f4").tobytes())
        self._vaos: dict[str, object] = {}
        self._edge_fbos: tuple | None = None
        self._vertices: dict[str, tuple[int, object]] = {}  # object key -> (revision, vertex texture)
        self._ray_fbo = None  # framebuffer of the ray table, the atlas's size
        self._corners = None  # corner buffer of the footprint pass (backend.corner_indices)
        self._corner_triangles = 0  # triangles it holds

    # programs ---------------------------------------------------------------
    @_current
    def program(self, iface: ProgramInterface | ComputeInterface):
        """Compile (once) and return the program (or compute shader) for an interface."""
        prog = self._programs.get(iface.name)
        if prog is None:
            # Deferred: the Ctrl-C handler raising while moderngl compiles segfaulted the
            # process (10 of 30 interrupted compares, 2026-12-02; blocking the signal on the
            # main thread did not help, deferring the Python handler did: 0 of 32). The
            # interruption is raised once the program is built and kept.
            with interrupt.deferred():
                prog = self._build(iface)
        return prog

    def _build(self, iface: ProgramInterface | ComputeInterface):
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
        self._programs[iface.name] = prog
        return prog

    def _use(self, iface: ProgramInterface | ComputeInterface, uniforms: UniformValues):
        prog = self.program(iface)
        types = {u.name: u.glsl_type for u in iface.uniforms}
        for name, value in uniforms.items():
            if name not in prog:
                continue  # optimised away by the GLSL compiler
            raw = _uniform_bytes(value, types.get(name, ""))
            if raw is not None:
                prog[name].write(raw)
            elif isinstance(value, (tuple, list, np.ndarray)):
                cast = int if types.get(name) == "int" else float
                prog[name].value = tuple(cast(v) for v in np.asarray(value).ravel())
            else:
                prog[name].value = value
        for binding, sampler in enumerate(iface.samplers):
            texture = self._textures.get(sampler)
            if texture is None:
                raise BackendError(f"{iface.name}: no texture for sampler {sampler}")
            texture.use(binding)
        return prog

    @staticmethod
    def _bind_images(iface: ProgramInterface | ComputeInterface, images: dict[str, object]) -> None:
        """Bind a program's images (`iface.images`, unit = index) from `images` by name."""
        for unit, (_, name) in enumerate(iface.images):
            images[name].bind_to_image(unit, read=True, write=True)

    def _float_texture(self, size: tuple[int, int], components: int, data: bytes | None = None):
        tex = self.ctx.texture(size, components, data, dtype="f4")
        tex.filter = (self._mgl.NEAREST, self._mgl.NEAREST)
        return tex

    def _set_table(self, name: str, table: np.ndarray | None) -> None:
        old = self._textures.get(name)
        data = pack_warp_table(table)
        size = (data.shape[1], data.shape[0])
        if old is not None and old.size == size:
            old.write(data.tobytes())
            return
        if old is not None:
            old.release()
        self._textures[name] = self._float_texture(size, 4, data.tobytes())

    # interface --------------------------------------------------------------
    @_current
    def renderer(self) -> str:
        info = self.ctx.info
        return f"{info['GL_RENDERER']} | OpenGL {info['GL_VERSION']}"

    @_current
    def max_texture_size(self) -> int:
        return int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])

    @_current
    def begin_atlas(self, layout: AtlasLayout, boxes: dict[int, tuple[int, int, int, int]] | None = None) -> None:
        if self._atlas_layout != layout:
            self._free_atlas()
            self._atlas = self._float_texture(layout.size, 1)
            self._atlas_depth = self.ctx.depth_renderbuffer(layout.size)
            self._atlas_fbo = self.ctx.framebuffer(color_attachments=[self._atlas], depth_attachment=self._atlas_depth)
            self._atlas_layout = layout
            self._textures["ow_atlas"] = self._atlas
        self._veil_live = False  # cleared again at this atlas's first see-through draw
        self._atlas_fbo.use()
        self._atlas_fbo.viewport = (0, 0) + layout.size
        rects = self._clear_rects(layout, boxes)
        if rects is None:
            self._atlas_fbo.clear(1.0, 1.0, 1.0, 1.0, depth=1.0)
            return
        for rect in rects:
            self._atlas_fbo.clear(1.0, 1.0, 1.0, 1.0, depth=1.0, viewport=rect)  # a scissored clear

    @_current
    def draw_layer(self, tile: int, vertices: np.ndarray, uniforms: UniformValues, span: int = 1,
                   scissor: tuple[int, int, int, int] | None = None) -> None:
        viewport = self._layer_viewport(self._atlas_layout, tile, span)
        if len(vertices) == 0:
            return
        prog = self._use(program_variant(DEPTH_PROGRAM, uniforms), uniforms)
        data = np.ascontiguousarray(vertices, dtype="f4")
        vbo = self.ctx.buffer(data.tobytes())
        try:
            vao = self.ctx.vertex_array(prog, [(vbo, "3f 4f", "ow_position", "ow_plane")])
            try:
                self._atlas_fbo.use()
                self._atlas_fbo.viewport = viewport
                # Fragments outside the readable box are never looked up (map-space culling).
                self._atlas_fbo.scissor = (viewport if scissor is None
                                           else self._atlas_layout.scissor_rect(tile, scissor))
                self.ctx.enable(self._mgl.DEPTH_TEST)
                self.ctx.disable(self._mgl.CULL_FACE)  # both windings cast shadows
                self.ctx.depth_func = "<"
                vao.render(self._mgl.TRIANGLES)
            finally:
                vao.release()
        finally:
            vbo.release()
            self.ctx.disable(self._mgl.DEPTH_TEST)
            self._atlas_fbo.scissor = None  # whole framebuffer again

    def _resident_revisions(self) -> dict[str, int]:
        return {key: revision for key, (revision, _) in self._vertices.items()}

    @_current
    def _upload_vertices(self, key: str, revision: int, texels: np.ndarray) -> None:
        self._drop_vertices(key)
        rows, width = texels.shape[:2]
        self._vertices[key] = (revision, self._float_texture((width, rows), 4, texels.tobytes()))

    @_current
    def _drop_vertices(self, key: str) -> None:
        held = self._vertices.pop(key, None)
        if held is not None:
            held[1].release()

    @_current
    def _upload_channel(self, data: np.ndarray):
        rows, columns = data.shape
        return self._float_texture((columns, rows), 1, np.ascontiguousarray(data, dtype="f4").tobytes())

    @_current
    def _free_channel(self, texture) -> None:
        texture.release()

    @_current
    def _new_veil(self, size: tuple[int, int]) -> tuple[object, ...]:
        images = tuple(self.ctx.texture(size, 1, dtype="u4") for _ in VEIL_IMAGES)
        # Cleared through a framebuffer (an integer clear per attachment): 3x faster on
        # llvmpipe than writing zeros from the host.
        self._veil_fbo = self.ctx.framebuffer(color_attachments=list(images))
        return images

    @_current
    def _clear_veil(self, images: tuple[object, ...]) -> None:
        self._veil_fbo.clear(0.0, 0.0, 0.0, 0.0)

    @_current
    def _free_veil(self, image: object) -> None:
        if self._veil_fbo is not None:
            self._veil_fbo.release()
            self._veil_fbo = None
        image.release()

    def _ensure_corners(self, triangles: int) -> None:
        """A corner buffer for at least `triangles` (the footprint vertex arrays use it)."""
        capacity = corner_capacity(triangles, self._corner_triangles)
        if capacity == self._corner_triangles:
            return
        for name in [n for n in self._vaos if n.startswith(FOOTPRINT_PROGRAM.name)]:
            self._vaos.pop(name).release()  # they point at the old buffer
        if self._corners is not None:
            self._corners.release()
        self._corners = self.ctx.buffer(corner_indices(capacity).tobytes())
        self._corner_triangles = capacity

    @_current
    def build_ray_table(self, tile: int, uniforms: UniformValues) -> None:
        if self._atlas_layout is None:
            raise BackendError("build_ray_table called before begin_atlas")
        size = self._atlas_layout.size
        table = self._textures["ow_ray_table"]
        if table.size != size:
            if self._ray_fbo is not None:
                self._ray_fbo.release()
            table.release()
            table = self._textures["ow_ray_table"] = self._float_texture(size, 2)
            self._ray_fbo = self.ctx.framebuffer(color_attachments=[table])
        prog = self._use(RAY_TABLE_PROGRAM, uniforms)
        vao = self._vaos.get(RAY_TABLE_PROGRAM.name)
        if vao is None:
            vao = self.ctx.vertex_array(prog, [(self._fullscreen_vbo, "2f", "ow_corner")])
            self._vaos[RAY_TABLE_PROGRAM.name] = vao
        self._ray_fbo.use()
        self._ray_fbo.viewport = self._atlas_layout.span_viewport(tile, 1)
        self.ctx.disable(self._mgl.DEPTH_TEST)
        vao.render(self._mgl.TRIANGLES)

    @_current
    def draw_footprints(self, tile: int, draws: list[FootprintDraw], uniforms: UniformValues,
                        scissor: tuple[int, int, int, int] | None = None, exact: bool = False) -> None:
        viewport = self._layer_viewport(self._atlas_layout, tile, caller="draw_footprints")
        self._ready_veil(draws, exact, self._atlas_layout)  # its clear binds its own framebuffer
        self._atlas_fbo.use()
        self._atlas_fbo.viewport = viewport
        self._atlas_fbo.scissor = viewport if scissor is None else self._atlas_layout.scissor_rect(tile, scissor)
        self.ctx.enable(self._mgl.DEPTH_TEST)
        self.ctx.disable(self._mgl.CULL_FACE)  # footprint quads have either winding
        self.ctx.depth_func = "<"
        try:
            for draw in draws:
                if draw.count <= 0:
                    continue
                iface, textures, images = self._footprint_program(draw, uniforms, exact, draw.points,
                                                                  self._atlas_layout)
                self._textures.update(textures)
                self._ensure_corners(draw.first + draw.count)
                prog = self._use(iface, {**uniforms, **draw.uniforms})
                self._bind_images(iface, images)
                vao = self._vaos.get(iface.name)
                if vao is None:
                    vao = self.ctx.vertex_array(prog, [(self._corners, "1f", "ow_corner")])
                    self._vaos[iface.name] = vao
                if draw.points:
                    # One vertex per triangle: vertex i of the corner buffer is triangle i.
                    self.ctx.enable(self._mgl.PROGRAM_POINT_SIZE)
                    vao.render(self._mgl.POINTS, vertices=draw.count, first=draw.first)
                else:
                    vao.render(self._mgl.TRIANGLES, vertices=draw.count * FOOTPRINT_VERTICES,
                               first=draw.first * FOOTPRINT_VERTICES)
        finally:
            for name in ("ow_vertices", *ALPHA_SAMPLERS):
                self._textures.pop(name, None)  # the object's own: not released here
            self.ctx.disable(self._mgl.DEPTH_TEST)
            self.ctx.disable(self._mgl.PROGRAM_POINT_SIZE)
            self._atlas_fbo.scissor = None

    @_current
    def upload_samples(self, positions: np.ndarray, normals: np.ndarray) -> None:
        height, width = positions.shape[:2]
        if self._sample_size != (width, height):
            for name in ("ow_positions", "ow_normals"):
                if name in self._textures:
                    self._textures[name].release()
                self._textures[name] = self._float_texture((width, height), 4)
            if self._test_target is not None:
                for obj in reversed(self._test_target):
                    obj.release()
            out = self._float_texture((width, height), 2)
            self._test_target = (out, self.ctx.framebuffer(color_attachments=[out]))
            self._sample_size = (width, height)
        self._textures["ow_positions"].write(np.ascontiguousarray(positions, dtype="f4").tobytes())
        self._textures["ow_normals"].write(np.ascontiguousarray(normals, dtype="f4").tobytes())

    @_current
    def set_warp_tables(self, rows: np.ndarray | None, cols: np.ndarray | None) -> None:
        self._set_table("ow_warp_rows", rows)
        self._set_table("ow_warp_cols", cols)

    @_current
    def scatter_counts(self, size: int, tiles: int, uniforms: UniformValues) -> np.ndarray:
        if self._sample_size is None:
            raise BackendError("scatter_counts called before upload_samples")
        target = self._count_targets.get(size)
        if target is None or target.width != size * tiles:
            # One strip per count-map size, reallocated when the layer count changes.
            if target is not None:
                target.release()
            target = self.ctx.texture((size * tiles, size), 1, dtype="u4")
            target.filter = (self._mgl.NEAREST, self._mgl.NEAREST)
            self._count_targets[size] = target
        target.write(np.zeros(size * tiles * size, dtype="u4").tobytes())
        iface = scatter_variant(uniforms)
        prog = self._use(iface, uniforms)
        target.bind_to_image(0, read=True, write=True)
        width, height = self._sample_size
        prog.run(group_x=iface.groups(width * height))
        # The read-back waits for the dispatch; image stores need this barrier first.
        self.ctx.memory_barrier()
        counts = np.frombuffer(target.read(), dtype="u4").reshape(size, size * tiles)
        return counts.astype(np.float32)

    @_current
    def link_samples(self, size: int, tiles: int, uniforms: UniformValues, hit_words: int = 1) -> None:
        if self._sample_size is None:
            raise BackendError("link_samples called before upload_samples")
        width, height = self._sample_size
        if (self._links is None or self._links[0].size != (size * tiles, size) or self._links[1].size != (width, height)
                or self._links[2].size != (width, height * hit_words)):
            self._free_links()
            # heads, links, the exact pass's marks and its work (shaders.EXACT_IMAGES)
            self._links = (self.ctx.texture((size * tiles, size), 1, dtype="u4"),
                           self.ctx.texture((width, height), 1, dtype="u4"),
                           self.ctx.texture((width, height * hit_words), 1, dtype="u4"),
                           self.ctx.texture((WORK_TEXELS, 1), 1, dtype="u4"))
            # Zeroed through framebuffers (an integer clear per attachment, on the GPU),
            # not written from the host: about 3x faster on llvmpipe (see _new_veil).
            heads, links, hits, work = self._links
            self._link_fbos = (self.ctx.framebuffer(color_attachments=[heads]),
                               self.ctx.framebuffer(color_attachments=[links]),
                               self.ctx.framebuffer(color_attachments=[hits]),  # a sized light's are taller
                               self.ctx.framebuffer(color_attachments=[work]))
        heads, links, hits, work = self._links
        for fbo in self._link_fbos:
            fbo.clear(0.0, 0.0, 0.0, 0.0)
        self._reset_work()
        iface = link_variant(uniforms)
        prog = self._use(iface, uniforms)
        heads.bind_to_image(0, read=True, write=True)
        links.bind_to_image(1, read=False, write=True)
        prog.run(group_x=iface.groups(width * height))
        self.ctx.memory_barrier()

    def _free_links(self) -> None:
        for obj in (*self._link_fbos, *(self._links or ())):
            obj.release()
        self._links = None
        self._link_fbos = ()

    @_current
    def read_links(self) -> tuple[np.ndarray, np.ndarray]:
        if self._links is None:
            raise BackendError("read_links called before link_samples")
        heads, links = self._links[:2]
        return (np.frombuffer(heads.read(), dtype="u4").reshape(heads.size[1], heads.size[0]).copy(),
                np.frombuffer(links.read(), dtype="u4").reshape(links.size[1], links.size[0]).copy())

    @_current
    def _read_hit_words(self) -> np.ndarray:
        self.ctx.memory_barrier()
        hits = self._links[2]
        return np.frombuffer(hits.read(), dtype="u4").reshape(hits.size[1], hits.size[0]).copy()

    @_current
    def _take_work(self) -> np.ndarray:
        self.ctx.memory_barrier()
        work = self._links[3]
        words = np.frombuffer(work.read(), dtype="u4").copy()
        self._link_fbos[3].clear(0.0, 0.0, 0.0, 0.0)  # the work image's own framebuffer
        return words

    @_current
    def _dispatch_advance(self, steps: int, tile_size: int) -> None:
        prog = self._use(ADVANCE_PROGRAM, {"ow_advance_steps": steps, "ow_tile_size": tile_size})
        self._bind_images(ADVANCE_PROGRAM, self._advance_images())
        heads = self._links[0]
        prog.run(group_x=ADVANCE_PROGRAM.groups(heads.width * heads.height))
        self.ctx.memory_barrier()

    @_current
    def reduce_samples(self, uniforms: UniformValues, clear: bool) -> np.ndarray:
        if self._sample_size is None:
            raise BackendError("reduce_samples called before upload_samples")
        if self._stats_target is None:
            self._stats_target = self.ctx.texture((STAT_TEXELS, 1), 1, dtype="u4")
            self._stats_target.filter = (self._mgl.NEAREST, self._mgl.NEAREST)
        if clear:
            self._stats_target.write(np.zeros(STAT_TEXELS, dtype="u4").tobytes())
        prog = self._use(SAMPLE_STATS_PROGRAM, uniforms)
        self._stats_target.bind_to_image(0, read=True, write=True)
        width, height = self._sample_size
        prog.run(group_x=SAMPLE_STATS_PROGRAM.groups(-(-width * height // STAT_SPAN)))
        self.ctx.memory_barrier()
        return np.frombuffer(self._stats_target.read(), dtype="u4").copy()

    @_current
    def shadow_test(self, uniforms: UniformValues) -> np.ndarray:
        if self._atlas is None or self._sample_size is None:
            raise BackendError("shadow_test needs an atlas and uploaded samples")
        width, height = self._sample_size
        if "ow_edges" not in self._textures:
            # Bound even when no antialiasing runs (ow_edge_radius = 0 never reads it).
            self._textures["ow_edges"] = self._float_texture((1, 1), 1, np.zeros(1, "f4").tobytes())
        iface, images = self._shadow_test_program(uniforms)
        prog = self._use(iface, uniforms)
        if images:
            self.ctx.memory_barrier()  # the depth pass's image atomics, before these loads
            self._bind_images(iface, images)
        # A moderngl vertex array renders with the program it was made for, so each
        # program variant keeps its own.
        vao = self._vaos.get(iface.name)
        if vao is None:
            vao = self.ctx.vertex_array(prog, [(self._fullscreen_vbo, "2f", "ow_corner")])
            self._vaos[iface.name] = vao
        out, fbo = self._test_target
        fbo.use()
        fbo.viewport = (0, 0, width, height)
        self.ctx.disable(self._mgl.DEPTH_TEST)
        vao.render(self._mgl.TRIANGLES)
        return np.frombuffer(out.read(), dtype="f4").reshape(height, width, 2).copy()

    @_current
    def edge_distance(self, radius: int, eps: float) -> None:
        if self._atlas is None or self._atlas_layout is None:
            raise BackendError("edge_distance needs a drawn atlas")
        size = self._atlas_layout.size
        for name in ("ow_edge_x", "ow_edges"):
            old = self._textures.get(name)
            if old is None or old.size != size:
                if old is not None:
                    old.release()
                self._textures[name] = self._float_texture(size, 1)
        fbos = self._edge_fbos
        if fbos is None or fbos[0].size != size:
            for fbo in fbos or ():
                fbo.release()
            fbos = tuple(self.ctx.framebuffer(color_attachments=[self._textures[n]]) for n in ("ow_edge_x", "ow_edges"))
            self._edge_fbos = fbos
        self.ctx.disable(self._mgl.DEPTH_TEST)
        for edge_pass, fbo in enumerate(fbos):
            uniforms = self._edge_uniforms(edge_pass, radius, eps, self._atlas_layout.resolution)
            prog = self._use(EDGE_PROGRAM, uniforms)
            if edge_pass == 0:
                # Pass 0 writes ow_edge_x: sample the other target there, so no texture
                # is both read and written (a GL feedback loop), even statically.
                self._textures["ow_edges"].use(EDGE_PROGRAM.samplers.index("ow_edge_x"))
            vao = self._vaos.get("edge")
            if vao is None:
                vao = self.ctx.vertex_array(prog, [(self._fullscreen_vbo, "2f", "ow_corner")])
                self._vaos["edge"] = vao
            fbo.use()
            fbo.viewport = (0, 0) + size
            vao.render(self._mgl.TRIANGLES)

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
        self._textures.pop("ow_atlas", None)
        self._atlas = self._atlas_depth = self._atlas_fbo = None
        self._atlas_layout = None

    def release(self) -> None:
        if self._released:
            return
        with self.ctx:
            # Drain the queue first: a release that an interrupt brings in the middle of a
            # frame must not free what llvmpipe's threads are still drawing with.
            self.ctx.finish()
            self._free_atlas()
            for vao in self._vaos.values():
                vao.release()
            self._vaos.clear()
            for tex in self._count_targets.values():
                tex.release()
            self._count_targets.clear()
            if self._stats_target is not None:
                self._stats_target.release()
                self._stats_target = None
            self._free_links()
            for fbo in self._edge_fbos or ():
                fbo.release()
            self._edge_fbos = None
            if self._test_target is not None:
                for obj in reversed(self._test_target):
                    obj.release()
            if self._ray_fbo is not None:
                self._ray_fbo.release()
                self._ray_fbo = None
            for _, texture in self._vertices.values():
                texture.release()
            self._vertices.clear()
            self._release_alpha()
            self._release_veil()
            for tex in self._textures.values():
                tex.release()
            self._textures.clear()
            self._fullscreen_vbo.release()
            if self._corners is not None:
                self._corners.release()
                self._corners = None
            for prog in self._programs.values():
                prog.release()
            self._programs.clear()
        self.ctx.release()
        self._released = True
