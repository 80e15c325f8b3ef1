"""Blender `gpu` module backend: the same GLSL as moderngl, declared through
`GPUShaderCreateInfo`.

`gpu` is imported lazily, so this module imports without Blender (the layering
test checks that). In background mode call `blender_gpu.ensure_gpu()` first. The
module-level helpers (textures, create-infos, read-backs) are in blender_gpu.py.

One GL owner per process: never mix this backend with moderngl in one process.
"""
from __future__ import annotations

import logging
from typing import Any

import numpy as np

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
from .blender_gpu import (
    _VECTOR_SIZES,
    CREATED,
    _backend_type,
    _float_texture,
    _framebuffer,
    _read,
    compute_create_info,
    count_gpu_objects,
    create_info,
    empty_texture,
    read_uint,
)
from .shaders import (
    ADVANCE_PROGRAM,
    BARRIER_PROGRAM,
    DEPTH_PROGRAM,
    EDGE_PROGRAM,
    FOOTPRINT_VERTICES,
    GBUFFER_ALPHA_PROGRAM,
    GBUFFER_PROGRAM,
    GBUFFER_SAMPLES_PROGRAM,
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

class BlenderGPUBackend(ShadowBackend):
    """Shadow backend on Blender's `gpu` module (viewport, background, headless)."""

    name = "blender-gpu"

    def __init__(self) -> None:
        try:
            import gpu  # noqa: F401
        except ImportError as exc:
            raise BackendError("the Blender gpu backend needs Blender (bpy) to run") from exc
        super().__init__()
        self._shaders: dict[str, Any] = {}
        self._layout: AtlasLayout | None = None
        self._atlas = self._atlas_depth = self._atlas_fb = None
        self._textures: dict[str, Any] = {}
        self._sample_size: tuple[int, int] | None = None
        self._test_target = None
        self._count_targets: dict[int, Any] = {}  # count-map size -> R32UI strip of its tiles
        self._stats_target = None  # R32UI row of the planning statistics (reduce_samples)
        self._links = None  # (heads strip, next links) of link_samples, R32UI
        self._gbuffer_target = None  # (size, texture, framebuffer) of samples_from_gbuffer
        self._no_warp = None  # the one zero texel bound as both warp tables without a warp
        self._batches: dict[str, Any] = {}
        self._active: dict[str, frozenset[str]] = {}  # program name -> uniforms it kept
        self._overlay_dummy = None
        self._edge_fbs: tuple = ()
        self._edge_size: tuple[int, int] | None = None
        self._vertices: dict[str, tuple[int, Any]] = {}  # object key -> (revision, vertex texture)
        self._ray_fb = None  # framebuffer of the ray table, the atlas's size
        self._corner_triangles = 0  # triangles the footprint batch's corner buffer holds
        # Point sprites need the shader's point size, which the gpu module takes on OpenGL;
        # other GPU backends draw every footprint as a quad (the same texels).
        self.point_sprites = _backend_type() == "OPENGL"
        self._released = False
        self.set_warp_tables(None, None)
        # Read only by warped footprint draws, after build_ray_table replaced it.
        self._textures["ow_ray_table"] = _float_texture((1, 1), "RG32F", np.zeros(2, np.float32))

    # shaders ----------------------------------------------------------------
    def shader(self, iface: ProgramInterface | ComputeInterface):
        """Build (once) the shader (or compute shader) for an interface."""
        import gpu

        shader = self._shaders.get(iface.name)
        if shader is None:
            info = compute_create_info(iface) if isinstance(iface, ComputeInterface) else create_info(iface)
            try:
                shader = gpu.shader.create_from_info(info)
                CREATED["shader"] += 1
            except Exception as exc:  # gpu reports GLSL errors as plain Exception
                raise BackendError(f"GLSL program {iface.name} failed to build in Blender: {exc}") from exc
            self._shaders[iface.name] = shader
        return shader

    def cached_batch(self, key: str):
        """A batch kept by this backend (released with it), or None."""
        return self._batches.get(key)

    def store_batch(self, key: str, batch) -> None:
        """Keep a batch for reuse across draws; `release` drops it."""
        self._batches[key] = batch

    def bind_program(self, iface: ProgramInterface, uniforms: UniformValues, textures: dict[str, Any] | None = None):
        """Bind a program with uniforms and textures (by sampler name); return the shader.

        Textures not given are taken from the backend's own (samples, atlas, warps).
        """
        return self._bind(iface, uniforms, textures)

    def _bind(self, iface: ProgramInterface | ComputeInterface, uniforms: UniformValues,
              textures: dict[str, Any] | None = None):
        shader = self.shader(iface)
        shader.bind()
        active = self._active_names(iface, shader)
        types = {u.name: u for u in iface.uniforms}
        for name, value in uniforms.items():
            uniform = types.get(name)
            if uniform is None or name not in active:
                continue  # not declared, or optimised away by the GLSL compiler
            self._set_uniform(shader, uniform, value)
        for sampler in iface.samplers:
            texture = (textures or {}).get(sampler) or self._textures.get(sampler)
            if texture is None:
                raise BackendError(f"{iface.name}: no texture for sampler {sampler}")
            if sampler in active:
                shader.uniform_sampler(sampler, texture)
        return shader

    def _active_names(self, iface: ProgramInterface | ComputeInterface, shader) -> frozenset[str]:
        """Uniforms and samplers the compiled shader still has (cached per program).

        A variant that compiles code out (OW_NO_WARP) loses the uniforms only that
        code read, and `gpu` raises ValueError when asked to set a missing uniform.
        """
        names = self._active.get(iface.name)
        if names is None:
            found = set()
            for name in [u.name for u in iface.uniforms] + list(iface.samplers):
                try:
                    shader.uniform_from_name(name)
                except ValueError:
                    continue  # compiled out
                found.add(name)
            names = self._active[iface.name] = frozenset(found)
        return names

    @staticmethod
    def _set_uniform(shader, uniform, value) -> None:
        import gpu

        arr = np.asarray(value, dtype=np.float64)
        if uniform.glsl_type in ("int", "bool", "ivec2", "ivec3", "ivec4"):
            if uniform.array:
                # uniform_int takes at most 4 values; arrays go through their location.
                ints = [int(v) for v in arr.ravel()]
                length = 1 if uniform.glsl_type in ("int", "bool") else int(uniform.glsl_type[-1])
                shader.uniform_vector_int(shader.uniform_from_name(uniform.name),
                                          gpu.types.Buffer("INT", len(ints), ints), length, len(ints) // length)
            else:
                shader.uniform_int(uniform.name, int(value) if arr.ndim == 0 else [int(v) for v in arr.ravel()])
            return
        if uniform.glsl_type.startswith("mat"):
            # GLSL matrices are column-major: upload the transpose's rows.
            arr = np.swapaxes(arr.reshape((-1,) + arr.shape[-2:]), -1, -2)
        flat = np.ascontiguousarray(arr, dtype=np.float32).ravel()
        if uniform.array:
            location = shader.uniform_from_name(uniform.name)
            length = _VECTOR_SIZES[uniform.glsl_type]
            shader.uniform_vector_float(location, gpu.types.Buffer("FLOAT", flat.size, flat), length,
                                        flat.size // length)
        elif flat.size == 1:
            shader.uniform_float(uniform.name, float(flat[0]))
        else:
            shader.uniform_float(uniform.name, [float(v) for v in flat])

    # interface --------------------------------------------------------------
    def renderer(self) -> str:
        import gpu

        return f"{gpu.platform.renderer_get()} | {gpu.platform.version_get()} (Blender gpu)"

    def max_texture_size(self) -> int:
        import gpu

        return int(gpu.capabilities.max_texture_size_get())

    def begin_atlas(self, layout: AtlasLayout, boxes: dict[int, tuple[int, int, int, int]] | None = None) -> None:
        import gpu

        if self._layout != layout:
            self._atlas = _float_texture(layout.size, "R32F")
            self._atlas_depth = empty_texture(layout.size, "DEPTH_COMPONENT32F")
            self._atlas_fb = _framebuffer(color_slots=(self._atlas,), depth_slot=self._atlas_depth)
            self._layout = layout
            self._textures["ow_atlas"] = self._atlas
        self._veil_live = False  # cleared again at this atlas's first see-through draw
        with self._atlas_fb.bind():
            rects = self._clear_rects(layout, boxes)
            if rects is None:
                self._atlas_fb.clear(color=(1.0, 1.0, 1.0, 1.0), depth=1.0)
                return
            # A framebuffer clear honours the scissor test: clear each readable box only.
            scissor_before = gpu.state.scissor_get()
            gpu.state.scissor_test_set(True)
            try:
                for rect in rects:
                    gpu.state.scissor_set(*rect)
                    self._atlas_fb.clear(color=(1.0, 1.0, 1.0, 1.0), depth=1.0)
            finally:
                gpu.state.scissor_test_set(False)
                gpu.state.scissor_set(*scissor_before)

    def draw_layer(self, tile: int, vertices: np.ndarray, uniforms: UniformValues, span: int = 1,
                   scissor: tuple[int, int, int, int] | None = None) -> None:
        import gpu
        from gpu_extras.batch import batch_for_shader

        viewport = self._layer_viewport(self._layout, tile, span)
        if len(vertices) == 0:
            return
        data = np.ascontiguousarray(vertices, dtype=np.float32)
        with self._atlas_fb.bind():
            shader = self._bind(program_variant(DEPTH_PROGRAM, uniforms), uniforms)
            batch = batch_for_shader(shader, "TRIS", {
                "ow_position": data[:, 0:3], "ow_plane": data[:, 3:7]})
            gpu.state.viewport_set(*viewport)
            if scissor is not None:
                # Fragments outside the readable box are never looked up (map-space culling).
                gpu.state.scissor_set(*self._layout.scissor_rect(tile, scissor))
                gpu.state.scissor_test_set(True)
            gpu.state.depth_test_set("LESS")
            gpu.state.depth_mask_set(True)
            gpu.state.face_culling_set("NONE")  # both windings cast shadows
            try:
                batch.draw(shader)
            finally:
                gpu.state.depth_test_set("NONE")
                gpu.state.depth_mask_set(False)
                if scissor is not None:
                    gpu.state.scissor_test_set(False)

    def _resident_revisions(self) -> dict[str, int]:
        return {key: revision for key, (revision, _) in self._vertices.items()}

    def _upload_vertices(self, key: str, revision: int, texels: np.ndarray) -> None:
        rows, width = texels.shape[:2]
        self._vertices[key] = (revision, _float_texture((width, rows), "RGBA32F", texels))

    def _drop_vertices(self, key: str) -> None:
        self._vertices.pop(key, None)  # Blender frees the texture with its last reference

    def _upload_channel(self, data: np.ndarray):
        rows, columns = data.shape
        return _float_texture((columns, rows), "R32F", data)

    def _free_channel(self, texture) -> None:
        """Nothing to do: Blender frees the texture with its last reference."""

    def _new_veil(self, size: tuple[int, int]) -> tuple[object, ...]:
        return tuple(empty_texture(size, "R32UI") for _ in VEIL_IMAGES)

    def _clear_veil(self, images: tuple[object, ...]) -> None:
        for image in images:
            image.clear(format="UINT", value=(0,))

    def _free_veil(self, image: object) -> None:
        """Nothing to do: Blender frees the texture with its last reference."""

    def _image_barrier(self) -> None:
        """Make image stores of earlier draws visible to later image loads. The `gpu` module
        has no barrier call, but every compute dispatch ends with one (texture fetch and
        image access, pygpu_compute_dispatch): an empty one-group dispatch."""
        import gpu

        gpu.compute.dispatch(self._bind(BARRIER_PROGRAM, {}), 1, 1, 1)

    def _corner_batch(self, shader, triangles: int, points: bool):
        """The footprint pass's batch (quads, or points) over one corner buffer of at least
        `triangles`: both batches share its vertex buffer, uploaded once per growth."""
        import gpu

        capacity = corner_capacity(triangles, self._corner_triangles)
        if capacity != self._corner_triangles or "footprint" not in self._batches:
            corners = corner_indices(capacity)
            fmt = gpu.types.GPUVertFormat()
            fmt.attr_add(id="ow_corner", comp_type="F32", len=1, fetch_mode="FLOAT")
            buffer = gpu.types.GPUVertBuf(fmt, len(corners))
            buffer.attr_fill("ow_corner", corners)
            self._batches["footprint"] = gpu.types.GPUBatch(type="TRIS", buf=buffer)
            self._batches["footprint_points"] = gpu.types.GPUBatch(type="POINTS", buf=buffer)
            self._corner_triangles = capacity
        return self._batches["footprint_points" if points else "footprint"]

    def draw_gbuffer(self, scene, uniforms: UniformValues) -> None:
        """Draw a resident scene (`resident.ResidentScene`) into the bound G-buffer with
        GBUFFER_PROGRAM: only objects new or changed since the last sync upload."""
        self.sync_scene(scene)
        for key, obj in scene.objects.items():
            if obj.triangles == 0:
                continue
            origin = obj.matrix[:3, :3] @ obj.origin + obj.matrix[:3, 3]
            values = {**uniforms, "ow_object_linear": obj.matrix[:3, :3], "ow_object_origin": origin}
            textures = {"ow_vertices": self._vertices[key][1], **self.alpha_textures(key)}
            if obj.alpha is not None:  # a see-through part: the camera sees it where alpha >= 1/2
                values["ow_alpha_mode"] = obj.alpha.mode
            shader = self._bind(GBUFFER_ALPHA_PROGRAM if obj.alpha is not None else GBUFFER_PROGRAM, values, textures)
            batch = self._corner_batch(shader, obj.triangles, False)
            batch.draw_range(shader, elem_start=0, elem_count=obj.triangles * FOOTPRINT_VERTICES)

    def build_ray_table(self, tile: int, uniforms: UniformValues) -> None:
        import gpu

        if self._layout is None:
            raise BackendError("build_ray_table called before begin_atlas")
        size = self._layout.size
        table = self._textures["ow_ray_table"]
        if (table.width, table.height) != size or self._ray_fb is None:
            table = self._textures["ow_ray_table"] = _float_texture(size, "RG32F")
            self._ray_fb = _framebuffer(color_slots=(table,))
        with self._ray_fb.bind():
            shader = self._bind(RAY_TABLE_PROGRAM, uniforms)
            batch = self._fullscreen_batch(shader)
            gpu.state.viewport_set(*self._layout.span_viewport(tile, 1))
            gpu.state.depth_test_set("NONE")
            batch.draw(shader)

    def draw_footprints(self, tile: int, draws: list[FootprintDraw], uniforms: UniformValues,
                        scissor: tuple[int, int, int, int] | None = None, exact: bool = False) -> None:
        import gpu

        viewport = self._layer_viewport(self._layout, tile, caller="draw_footprints")
        self._ready_veil(draws, exact, self._layout)
        # Always scissored: point sprites may reach past the tile's edge.
        rect = self._layout.scissor_rect(tile, scissor) if scissor is not None else viewport
        with self._atlas_fb.bind():
            gpu.state.viewport_set(*viewport)
            scissor_before = gpu.state.scissor_get()
            gpu.state.scissor_set(*rect)
            gpu.state.scissor_test_set(True)
            gpu.state.depth_test_set("LESS")
            gpu.state.depth_mask_set(True)
            gpu.state.face_culling_set("NONE")  # footprint quads have either winding
            try:
                for draw in draws:
                    if draw.count <= 0:
                        continue  # a count of 0 would mean "all" to gpu
                    points = draw.points and self.point_sprites
                    iface, textures, images = self._footprint_program(draw, uniforms, exact, points, self._layout)
                    shader = self._bind(iface, {**uniforms, **draw.uniforms}, textures)
                    for name, image in images.items():
                        shader.image(name, image)
                    batch = self._corner_batch(shader, draw.first + draw.count, points)
                    if points:
                        gpu.state.program_point_size_set(True)
                        batch.draw_range(shader, elem_start=draw.first, elem_count=draw.count)
                    else:
                        gpu.state.program_point_size_set(False)
                        batch.draw_range(shader, elem_start=draw.first * FOOTPRINT_VERTICES,
                                         elem_count=draw.count * FOOTPRINT_VERTICES)
            finally:
                gpu.state.program_point_size_set(False)
                gpu.state.depth_test_set("NONE")
                gpu.state.depth_mask_set(False)
                gpu.state.scissor_test_set(False)
                gpu.state.scissor_set(*scissor_before)

    def _fullscreen_batch(self, shader):
        """The one screen-covering triangle, built once (every program names it ow_corner)."""
        from gpu_extras.batch import batch_for_shader

        batch = self._batches.get("fullscreen")
        if batch is None:
            batch = batch_for_shader(shader, "TRIS", {"ow_corner": FULLSCREEN_CORNERS})
            self._batches["fullscreen"] = batch
        return batch

    def _set_sample_size(self, size: tuple[int, int]) -> None:
        if self._sample_size != size:
            out = _float_texture(size, "RG32F")
            self._test_target = (out, _framebuffer(color_slots=(out,)))
            self._sample_size = size

    def upload_samples(self, positions: np.ndarray, normals: np.ndarray) -> None:
        height, width = positions.shape[:2]
        self._textures["ow_positions"] = _float_texture((width, height), "RGBA32F", positions)
        self._textures["ow_normals"] = _float_texture((width, height), "RGBA32F", normals)
        self._set_sample_size((width, height))

    def samples_from_gbuffer(self, textures: dict[str, Any], light_position: np.ndarray) -> None:
        """Make a G-buffer (blender_draw.render_gbuffer) the view samples without a read-back.

        GBUFFER_SAMPLES_PROGRAM light-centres its positions into a texture kept per size;
        the normals are the G-buffer's own texture (zero where no geometry was hit, as
        `upload_samples` expects).
        """
        import gpu

        position = textures["ow_gb_position"]
        size = (position.width, position.height)
        if self._gbuffer_target is None or self._gbuffer_target[0] != size:
            texture = _float_texture(size, "RGBA32F")
            self._gbuffer_target = (size, texture, _framebuffer(color_slots=(texture,)))
        _, texture, target = self._gbuffer_target
        light = np.asarray(light_position, dtype=np.float64)
        hi = light.astype(np.float32)
        lo = (light - hi.astype(np.float64)).astype(np.float32)
        with target.bind():
            shader = self._bind(GBUFFER_SAMPLES_PROGRAM, {"ow_light_hi": hi, "ow_light_lo": lo},
                                {"ow_gb_position": position})
            gpu.state.viewport_set(0, 0, *size)
            gpu.state.depth_test_set("NONE")
            self._fullscreen_batch(shader).draw(shader)
        self._textures["ow_positions"] = texture
        self._textures["ow_normals"] = textures["ow_gb_normal"]
        self._set_sample_size(size)

    def set_warp_tables(self, rows: np.ndarray | None, cols: np.ndarray | None) -> None:
        # gpu.types.GPUTexture has no write (Blender 5.2: clear and read only), so a table
        # is a new texture; "no warp" is one zero texel, made once and bound to both.
        for name, table in (("ow_warp_rows", rows), ("ow_warp_cols", cols)):
            if table is None:
                if self._no_warp is None:
                    self._no_warp = _float_texture((1, 1), "RGBA32F", pack_warp_table(None))
                self._textures[name] = self._no_warp
                continue
            data = pack_warp_table(table)
            self._textures[name] = _float_texture((data.shape[1], data.shape[0]), "RGBA32F", data)

    def scatter_counts(self, size: int, tiles: int, uniforms: UniformValues) -> np.ndarray:
        import gpu

        if self._sample_size is None:
            raise BackendError("scatter_counts called before upload_samples")
        target = self._count_targets.get(size)
        if target is None or target.width != size * tiles:
            # One strip per count-map size, reallocated when the layer count changes.
            target = empty_texture((size * tiles, size), "R32UI")
            self._count_targets[size] = target
        target.clear(format="UINT", value=(0,))
        iface = scatter_variant(uniforms)
        shader = self._bind(iface, uniforms)
        shader.image("ow_counts", target)
        width, height = self._sample_size
        gpu.compute.dispatch(shader, iface.groups(width * height), 1, 1)
        # dispatch() ends with a texture-fetch and image-access barrier (pygpu_compute_dispatch);
        # read() then waits for the GPU.
        return read_uint(target).astype(np.float32)

    def link_samples(self, size: int, tiles: int, uniforms: UniformValues, hit_words: int = 1) -> None:
        import gpu

        if self._sample_size is None:
            raise BackendError("link_samples called before upload_samples")
        width, height = self._sample_size
        held = self._links
        if (held is None or (held[0].width, held[0].height) != (size * tiles, size)
                or (held[1].width, held[1].height) != (width, height)
                or (held[2].width, held[2].height) != (width, height * hit_words)):
            # heads, links, the exact pass's marks and its work (shaders.EXACT_IMAGES)
            self._links = (empty_texture((size * tiles, size), "R32UI"),
                           empty_texture((width, height), "R32UI"),
                           empty_texture((width, height * hit_words), "R32UI"),
                           empty_texture((WORK_TEXELS, 1), "R32UI"))
        heads, links = self._links[:2]
        for texture in self._links:
            texture.clear(format="UINT", value=(0,))
        self._reset_work()
        iface = link_variant(uniforms)
        shader = self._bind(iface, uniforms)
        shader.image("ow_counts", heads)
        shader.image("ow_next", links)
        gpu.compute.dispatch(shader, iface.groups(width * height), 1, 1)

    def read_links(self) -> tuple[np.ndarray, np.ndarray]:
        if self._links is None:
            raise BackendError("read_links called before link_samples")
        heads, links = self._links[:2]
        return read_uint(heads), read_uint(links)

    def _read_hit_words(self) -> np.ndarray:
        self._image_barrier()  # the exact pass's fragment atomics, before the read
        return read_uint(self._links[2])

    def _take_work(self) -> np.ndarray:
        self._image_barrier()
        work = self._links[3]
        words = read_uint(work).ravel()
        work.clear(format="UINT", value=(0,))
        return words

    def _dispatch_advance(self, steps: int, tile_size: int) -> None:
        import gpu

        shader = self._bind(ADVANCE_PROGRAM, {"ow_advance_steps": steps, "ow_tile_size": tile_size})
        for name, texture in self._advance_images().items():
            shader.image(name, texture)
        heads = self._links[0]
        gpu.compute.dispatch(shader, ADVANCE_PROGRAM.groups(heads.width * heads.height), 1, 1)

    def reduce_samples(self, uniforms: UniformValues, clear: bool) -> np.ndarray:
        import gpu

        if self._sample_size is None:
            raise BackendError("reduce_samples called before upload_samples")
        if self._stats_target is None:
            self._stats_target = empty_texture((STAT_TEXELS, 1), "R32UI")
        if clear:
            self._stats_target.clear(format="UINT", value=(0,))
        shader = self._bind(SAMPLE_STATS_PROGRAM, uniforms)
        shader.image("ow_stats", self._stats_target)
        width, height = self._sample_size
        gpu.compute.dispatch(shader, SAMPLE_STATS_PROGRAM.groups(-(-width * height // STAT_SPAN)), 1, 1)
        # dispatch() ends with an image-access barrier; read() waits for the GPU.
        return read_uint(self._stats_target).ravel()

    def shadow_test(self, uniforms: UniformValues) -> np.ndarray:
        import gpu

        if self._atlas is None or self._sample_size is None:
            raise BackendError("shadow_test needs an atlas and uploaded samples")
        out, fb = self._test_target
        width, height = self._sample_size
        if "ow_edges" not in self._textures:
            # Bound even when no antialiasing runs (ow_edge_radius = 0 never reads it).
            self._textures["ow_edges"] = _float_texture((1, 1), "R32F", np.zeros(1, np.float32))
        iface, images = self._shadow_test_program(uniforms)
        if images:
            self._image_barrier()  # the depth pass's veil atomics, before the test's loads
        with fb.bind():
            shader = self._bind(iface, uniforms)
            for name, image in images.items():
                shader.image(name, image)
            batch = self._fullscreen_batch(shader)
            gpu.state.viewport_set(0, 0, width, height)
            gpu.state.depth_test_set("NONE")
            batch.draw(shader)
        return _read(out, "RG32F")

    def edge_distance(self, radius: int, eps: float) -> None:
        import gpu
        from gpu_extras.batch import batch_for_shader

        if self._atlas is None or self._layout is None:
            raise BackendError("edge_distance needs a drawn atlas")
        size = self._layout.size
        if self._edge_size != size:
            # Keep the framebuffers with their textures: both passes write a fresh target.
            for name in ("ow_edge_x", "ow_edges"):
                self._textures[name] = _float_texture(size, "R32F")
            self._edge_fbs = tuple(_framebuffer(color_slots=(self._textures[n],)) for n in ("ow_edge_x", "ow_edges"))
            self._edge_size = size
        for edge_pass, fb in enumerate(self._edge_fbs):
            with fb.bind():
                uniforms = self._edge_uniforms(edge_pass, radius, eps, self._layout.resolution)
                # Pass 0 writes ow_edge_x: sample the other target there (no feedback loop).
                override = {"ow_edge_x": self._textures["ow_edges"]} if edge_pass == 0 else None
                shader = self._bind(EDGE_PROGRAM, uniforms, override)
                batch = self._batches.get("edge")
                if batch is None:
                    batch = batch_for_shader(shader, "TRIS", {"ow_corner": FULLSCREEN_CORNERS})
                    self._batches["edge"] = batch
                gpu.state.viewport_set(0, 0, size[0], size[1])
                gpu.state.depth_test_set("NONE")
                batch.draw(shader)

    def read_atlas(self) -> np.ndarray:
        if self._atlas is None:
            raise BackendError("no atlas to read")
        return _read(self._atlas, "R32F")

    def finish(self) -> None:
        import gpu

        # Reading one texel back forces the queue to drain (there is no glFinish in `gpu`).
        if self._atlas is not None:
            with self._atlas_fb.bind():
                self._atlas_fb.read_color(0, 0, 1, 1, 1, 0, "FLOAT")
        else:
            gpu.state.viewport_get()

    def live_resources(self) -> int:
        """Distinct GPU objects this backend holds now (textures, framebuffers, shaders, batches)."""
        return count_gpu_objects(self)

    def release(self) -> None:
        """Drop every GPU object; Blender frees them when the last reference goes."""
        if self._released:
            return
        self._batches.clear()
        self._count_targets.clear()
        self._stats_target = None
        self._links = None
        self._gbuffer_target = None
        self._no_warp = None
        self._test_target = None
        self._textures.clear()
        self._atlas = self._atlas_depth = self._atlas_fb = None
        self._layout = None
        self._shaders.clear()
        self._active.clear()
        self._overlay_dummy = None
        self._edge_fbs = ()
        self._edge_size = None
        self._vertices.clear()
        self._release_alpha()
        self._release_veil()
        self._ray_fb = None
        self._corner_triangles = 0
        self._released = True
