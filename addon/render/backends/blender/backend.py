"""Blender `gpu` module backend: the same GLSL as moderngl, declared through
`GPUShaderCreateInfo`.

The device adapter (`BlenderDevice`) maps the primitives of device.py onto `gpu`; every
pass is written once in render/passes. `gpu` is imported lazily, so this module imports
without Blender (the layering test checks that). In background mode call
`blender_gpu.ensure_gpu()` first. The helpers it draws on (textures, create-infos,
read-backs) are in blender_gpu.py. One GL owner per process: never mix this backend with
moderngl in one process.
"""
from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from typing import Any, Iterator

import numpy as np

from ....core.errors import BackendError
from ...backend import ShadowBackend
from .gpu_objects import (
    CREATED,
    backend_type,
    compute_create_info,
    count_gpu_objects,
    create_info,
    empty_texture,
    float_texture,
    framebuffer,
    read_texture,
    read_uint,
    uniform_buffer,
)
from ...device import FULLSCREEN, FULLSCREEN_CORNERS, Device, Geometry, Program, Rect, Target, UniformValues
from ...pacing import Steps
from ...passes.footprints import FOOTPRINT_VERTICES, corner_capacity, corner_indices
from ...passes.samples import set_size
from ...shaders.uniform_block import INSTANCE, BlockState, UniformBlock
from ...shaders import (
    BARRIER_PROGRAM,
    GBUFFER_ALPHA_PROGRAM,
    GBUFFER_PROGRAM,
    GBUFFER_SAMPLES_PROGRAM,
    ComputeInterface,
    ProgramInterface,
)

log = logging.getLogger(__name__)

class BlenderDevice(Device):
    """device.Device on Blender's `gpu` module. Blender frees a GPU object when its last
    reference goes, so `free` has nothing to do: the holders drop their references."""

    name = "blender-gpu"
    reads_whole = True  # GPUTexture.read has no rectangle

    def __init__(self) -> None:
        try:
            import gpu  # noqa: F401
        except ImportError as exc:
            raise BackendError("the Blender gpu backend needs Blender (bpy) to run") from exc
        self.shaders: dict[str, Any] = {}
        self._active: dict[str, frozenset[str]] = {}  # program name -> samplers it kept
        # program name -> (its uniforms' current values, the GPUUniformBuf holding them): one
        # buffer a program, updated only when a draw changes the block. Blender orders a
        # buffer's update after the draws queued before it (OpenGL by its rules, Vulkan by its
        # render graph), as it does a texture's.
        self.uniform_buffers: dict[str, tuple[BlockState, Any]] = {}
        self.batches: dict[str, Any] = {}
        self._corner_triangles = 0  # triangles the corner batches' buffer holds
        # Point sprites need the shader's point size, which the gpu module takes on OpenGL;
        # other GPU backends draw every footprint as a quad (the same texels).
        self.point_sprites = backend_type() == "OPENGL"

    def renderer(self) -> str:
        import gpu

        return f"{gpu.platform.renderer_get()} | {gpu.platform.version_get()} (Blender gpu)"

    def max_texture_size(self) -> int:
        import gpu

        return int(gpu.capabilities.max_texture_size_get())

    # programs -----------------------------------------------------------------
    def shader(self, iface: Program):
        """Build (once) the shader (or compute shader) for an interface."""
        import gpu

        shader = self.shaders.get(iface.name)
        if shader is None:
            info = compute_create_info(iface) if isinstance(iface, ComputeInterface) else create_info(iface)
            try:
                shader = gpu.shader.create_from_info(info)
                CREATED["shader"] += 1
            except Exception as exc:  # gpu reports GLSL errors as plain Exception
                raise BackendError(f"GLSL program {iface.name} failed to build in Blender: {exc}") from exc
            self.shaders[iface.name] = shader
        return shader

    def bind(self, iface: Program, uniforms: UniformValues, textures: dict[str, Any],
             images: dict[str, Any] | None = None):
        """Bind a program with its uniforms, samplers and images (by name); return the shader."""
        shader = self.shader(iface)
        shader.bind()
        active = self._active_names(iface, shader)
        if iface.uniforms:
            shader.uniform_block(INSTANCE, self._uniform_buffer(iface, uniforms))
        for sampler in iface.samplers:
            texture = textures.get(sampler)
            if texture is None:
                raise BackendError(f"{iface.name}: no texture for sampler {sampler}")
            if sampler in active:
                shader.uniform_sampler(sampler, texture)
        for _, name in iface.images if images else ():
            shader.image(name, images[name])
        return shader

    def _uniform_buffer(self, iface: Program, uniforms: UniformValues):
        """The program's uniform block with `uniforms` written over its current values."""
        kept = self.uniform_buffers.get(iface.name)
        if kept is None:
            state = BlockState(UniformBlock.of(iface))
            state.update(uniforms)
            state.take_changed()
            kept = self.uniform_buffers[iface.name] = (state, uniform_buffer(state.data))
        else:
            state, buffer = kept
            state.update(uniforms)
            if state.take_changed() is not None:  # GPUUniformBuf.update takes the whole block
                buffer.update(state.data)
        return kept[1]

    def _active_names(self, iface: Program, shader) -> frozenset[str]:
        """Samplers the compiled shader still has (cached per program): a variant that
        compiles code out (OW_NO_WARP) loses the samplers only that code read, and `gpu`
        raises ValueError when asked to set a missing one."""
        names = self._active.get(iface.name)
        if names is None:
            found = set()
            for name in iface.samplers:
                try:
                    shader.uniform_from_name(name)
                except ValueError:
                    continue  # compiled out
                found.add(name)
            names = self._active[iface.name] = frozenset(found)
        return names

    # resources ----------------------------------------------------------------
    def texture(self, size: tuple[int, int], fmt: str, data: np.ndarray | None = None):
        if fmt == "R32UI" or fmt.startswith("DEPTH"):
            return empty_texture(size, fmt)
        return float_texture(size, fmt, data)

    def upload(self, texture, size: tuple[int, int], fmt: str, data: np.ndarray):
        # GPUTexture has no write (Blender 5.2: clear and read only): always a new texture.
        return self.texture(size, fmt, data)

    def free(self, *objects: Any) -> None:
        """Nothing to do: Blender frees an object with its last reference."""

    def texture_size(self, texture) -> tuple[int, int]:
        return texture.width, texture.height

    def target(self, colors: tuple[Any, ...], depth: bool = False) -> Target:
        size = self.texture_size(colors[0])
        depth_texture = empty_texture(size, "DEPTH_COMPONENT32F") if depth else None
        slots = {"depth_slot": depth_texture} if depth else {}
        return Target(framebuffer(color_slots=tuple(colors), **slots), tuple(colors), size, depth_texture)

    def clear(self, target: Target, color, depth: float | None = None, rects: list[Rect] | None = None) -> None:
        import gpu

        fb = target.handle
        with fb.bind():
            if rects is None:
                fb.clear(color=color, depth=depth)
                return
            # A framebuffer clear honours the scissor test: clear each rectangle only.
            scissor_before = gpu.state.scissor_get()
            gpu.state.scissor_test_set(True)
            try:
                for rect in rects:
                    gpu.state.scissor_set(*rect)
                    fb.clear(color=color, depth=depth)
            finally:
                gpu.state.scissor_test_set(False)
                gpu.state.scissor_set(*scissor_before)

    def clear_image(self, image) -> None:
        image.clear(format="UINT", value=(0,))

    def read(self, texture, fmt: str, rect: Rect | None = None) -> np.ndarray:
        whole = read_uint(texture) if fmt == "R32UI" else read_texture(texture, fmt)
        if rect is None:
            return whole
        x, y, width, height = rect
        return whole[y:y + height, x:x + width].copy()

    # work ---------------------------------------------------------------------
    @contextlib.contextmanager
    def drawing(self, target: Target, viewport: Rect, scissor: Rect | None = None,
                depth_test: bool = False) -> Iterator[None]:
        import gpu

        with target.handle.bind():
            gpu.state.viewport_set(*viewport)
            scissor_before = gpu.state.scissor_get()
            if scissor is not None:
                gpu.state.scissor_set(*scissor)
                gpu.state.scissor_test_set(True)
            gpu.state.depth_test_set("LESS" if depth_test else "NONE")
            gpu.state.depth_mask_set(depth_test)
            gpu.state.face_culling_set("NONE")  # both windings cast shadows
            try:
                yield
            finally:
                gpu.state.program_point_size_set(False)
                gpu.state.depth_test_set("NONE")
                gpu.state.depth_mask_set(False)
                if scissor is not None:
                    gpu.state.scissor_test_set(False)
                    gpu.state.scissor_set(*scissor_before)

    def draw(self, iface: ProgramInterface, uniforms: UniformValues, textures: dict[str, Any],
             geometry: Geometry = FULLSCREEN, images: dict[str, Any] | None = None) -> None:
        import gpu
        from gpu_extras.batch import batch_for_shader

        shader = self.bind(iface, uniforms, textures, images)
        if geometry.kind == "vertices":
            batch_for_shader(shader, "TRIS", geometry.arrays).draw(shader)
        elif geometry.kind == "fullscreen":
            batch = self.batches.get("fullscreen")
            if batch is None:  # every screen program names its corner ow_corner
                batch = self.batches["fullscreen"] = batch_for_shader(shader, "TRIS", {"ow_corner": FULLSCREEN_CORNERS})
            batch.draw(shader)
        else:
            gpu.state.program_point_size_set(geometry.points)
            batch = self.corner_batch(geometry.first + geometry.count, geometry.points)
            scale = 1 if geometry.points else FOOTPRINT_VERTICES
            batch.draw_range(shader, elem_start=geometry.first * scale, elem_count=geometry.count * scale)

    def corner_batch(self, triangles: int, points: bool):
        """The footprint pass's batch (quads, or points) over one corner buffer of at least
        `triangles`: both batches share its vertex buffer, uploaded once per growth."""
        import gpu

        capacity = corner_capacity(triangles, self._corner_triangles)
        if capacity != self._corner_triangles or "footprint" not in self.batches:
            corners = corner_indices(capacity)
            fmt = gpu.types.GPUVertFormat()
            fmt.attr_add(id="ow_corner", comp_type="F32", len=1, fetch_mode="FLOAT")
            buffer = gpu.types.GPUVertBuf(fmt, len(corners))
            buffer.attr_fill("ow_corner", corners)
            self.batches["footprint"] = gpu.types.GPUBatch(type="TRIS", buf=buffer)
            self.batches["footprint_points"] = gpu.types.GPUBatch(type="POINTS", buf=buffer)
            self._corner_triangles = capacity
        return self.batches["footprint_points" if points else "footprint"]

    def dispatch(self, iface: ComputeInterface, uniforms: UniformValues, textures: dict[str, Any],
                 images: dict[str, Any], groups: int) -> None:
        import gpu

        # dispatch() ends with a texture-fetch and image-access barrier (pygpu_compute_dispatch).
        gpu.compute.dispatch(self.bind(iface, uniforms, textures, images), groups, 1, 1)

    def barrier(self) -> None:
        """The `gpu` module has no barrier call, but every compute dispatch ends with one
        (texture fetch and image access): an empty one-group dispatch."""
        import gpu

        gpu.compute.dispatch(self.bind(BARRIER_PROGRAM, {}, {}), 1, 1, 1)

    def finish(self, target: Target | None = None) -> None:
        import gpu

        # Reading one texel back forces the queue to drain (there is no glFinish in `gpu`).
        if target is not None:
            with target.handle.bind():
                target.handle.read_color(0, 0, 1, 1, 1, 0, "FLOAT")
        else:
            gpu.state.viewport_get()

    def release(self) -> None:
        import gpu

        # Blender skips a bind when the context's current shader has the same address, and
        # freeing a shader does not clear that pointer: a new shader allocated where the
        # freed, last-bound one was would then draw with the old program (a fresh backend's
        # G-buffer came out empty about one time in seven). A built-in, never freed, takes
        # its place first.
        if self.shaders:
            gpu.shader.from_builtin("UNIFORM_COLOR").bind()
        self.batches.clear()
        self.shaders.clear()
        self._active.clear()
        self.uniform_buffers.clear()
        self._corner_triangles = 0


class BlenderGPUBackend(ShadowBackend):
    """Shadow backend on Blender's `gpu` module (viewport, background, headless)."""

    name = "blender-gpu"

    def __init__(self) -> None:
        super().__init__(BlenderDevice())
        self._gbuffer_target = None  # (size, texture, target) of samples_from_gbuffer
        self._overlay_dummy = None  # blender_draw's 1x1 texture for a sampler a mode skips

    def cached_batch(self, key: str):
        """A batch kept by this backend (released with it), or None."""
        return self.device.batches.get(key)

    def store_batch(self, key: str, batch) -> None:
        """Keep a batch for reuse across draws; `release` drops it."""
        self.device.batches[key] = batch

    def bind_program(self, iface: ProgramInterface, uniforms: UniformValues, textures: dict[str, Any] | None = None):
        """Bind a program with uniforms and textures (by sampler name); return the shader.
        Textures not given are taken from the backend's own (samples, atlas, warps)."""
        return self.device.bind(iface, uniforms, {**self.textures, **(textures or {})})

    def draw_gbuffer_steps(self, scene, uniforms: UniformValues, bound: Callable) -> Steps[None]:
        """Draw a resident scene (`resident.ResidentScene`) into a G-buffer with
        GBUFFER_PROGRAM, each batch of draws inside `bound()` (its target bound, its state
        set): only objects new or changed since the last sync upload. Stepped
        (render/pacing.py): the viewport spreads a million triangles over redraws."""
        self.sync_scene(scene)
        queued: list[tuple[Any, dict, dict, int, int]] = []

        def flush() -> None:
            if queued:
                with bound():
                    for program, values, textures, first, count in queued:
                        self.device.draw(program, values, textures, Geometry.corners(first, count))
                queued.clear()

        def wait() -> None:
            flush()
            self.finish()  # stepping too: a slice's time holds its GPU work

        for key, obj in scene.objects.items():
            if obj.triangles == 0 or obj.pieces or obj.medium is not None:
                # Pieces (hair, points) cast shadows but are not in the G-buffer here; a
                # medium has no surface for the camera to see.
                continue
            origin = obj.matrix[:3, :3] @ obj.origin + obj.matrix[:3, 3]
            values = {**uniforms, "ow_object_linear": obj.matrix[:3, :3], "ow_object_origin": origin}
            textures = {**self.textures, "ow_vertices": self.vertices[key][1], **self.alpha_textures(key)}
            if obj.alpha is not None:  # a see-through part: the camera sees it where alpha >= 1/2
                values["ow_alpha_mode"] = obj.alpha.mode
            program = GBUFFER_ALPHA_PROGRAM if obj.alpha is not None else GBUFFER_PROGRAM
            kind = "step:gbuffer" if self.pacer.stepping else "wait:gbuffer"
            yield from self.pacer.steps(f"{kind}:{key}", obj.triangles,
                                        lambda first, count, p=program, v=values, t=textures: queued.append(
                                            (p, v, t, first, count)), wait)
        flush()

    def samples_from_gbuffer(self, textures: dict[str, Any], light_position: np.ndarray) -> None:
        """Make a G-buffer (blender_draw.render_gbuffer) the view samples without a read-back.

        GBUFFER_SAMPLES_PROGRAM light-centres its positions into a texture kept per size;
        the normals are the G-buffer's own texture (zero where no geometry was hit, as
        `upload_samples` expects).
        """
        position = textures["ow_gb_position"]
        size = (position.width, position.height)
        if self._gbuffer_target is None or self._gbuffer_target[0] != size:
            texture = self.device.texture(size, "RGBA32F")
            self._gbuffer_target = (size, texture, self.device.target((texture,)))
        _, texture, target = self._gbuffer_target
        light = np.asarray(light_position, dtype=np.float64)
        hi = light.astype(np.float32)
        lo = (light - hi.astype(np.float64)).astype(np.float32)
        with self.device.drawing(target, (0, 0) + size):
            self.device.draw(GBUFFER_SAMPLES_PROGRAM, {"ow_light_hi": hi, "ow_light_lo": lo},
                             {**self.textures, "ow_gb_position": position})
        self.textures["ow_positions"] = texture
        self.textures["ow_normals"] = textures["ow_gb_normal"]
        set_size(self, size)

    def live_resources(self) -> int:
        """Distinct GPU objects this backend holds now (textures, framebuffers, shaders, batches)."""
        return count_gpu_objects(self)

    def release(self) -> None:
        """Drop every GPU object; Blender frees them when the last reference goes."""
        super().release()
        self._gbuffer_target = None
        self._overlay_dummy = None
