"""Blender `gpu` helpers of the Blender backend: textures and framebuffers (counted),
shader create-infos from the shared `ProgramInterface`s, read-backs, and the count of
the GPU objects a holder keeps.

`gpu` is imported lazily, so this module imports without Blender. In background mode
call `ensure_gpu()` first: Blender 5.2 has `gpu.init()`; older versions need one tiny
Workbench render (docs/design.md section 3).
"""
from __future__ import annotations

import logging
from typing import Any

import numpy as np

from ....compat import blender as blender_compat
from ...shaders import ComputeInterface, ProgramInterface, image_type, load_source, program_defines
from ...shaders.uniform_block import INSTANCE, UniformBlock

log = logging.getLogger(__name__)

# GPU objects (textures, framebuffers, shaders) created by this module. Blender's gpu
# types take no weak references and cannot be asked whether they are alive, so ownership
# is explicit: a backend keeps its objects in its own attributes, `live_resources()` counts
# the distinct ones it holds (`count_gpu_objects`), and `release()` drops them all; Blender
# frees an object when its last reference goes. The tests compare these counts across
# register cycles and redraws, and CREATED across repeated frames.
CREATED = {"texture": 0, "framebuffer": 0, "shader": 0, "uniform_buffer": 0}

# The Python types of Blender's GPU objects (gpu.types), by name: what count_gpu_objects counts.
_GPU_TYPES = frozenset({"GPUTexture", "GPUFrameBuffer", "GPUShader", "GPUBatch", "GPUVertBuf", "GPUIndexBuf",
                        "GPUUniformBuf", "GPUOffScreen", "GPUStorageBuf"})


def count_gpu_objects(*roots: Any) -> int:
    """Distinct Blender GPU objects reachable from `roots`: through dicts, lists, tuples and
    sets, and the attributes of this package's own objects (dataclasses, backends). One
    texture held in two places counts once."""
    package = __name__.split(".render.")[0]
    found: set[int] = set()
    visited: set[int] = set()
    stack = list(roots)
    while stack:
        value = stack.pop()
        if id(value) in visited:
            continue
        visited.add(id(value))
        kind = type(value)
        if kind.__name__ in _GPU_TYPES:
            found.add(id(value))
        elif isinstance(value, dict):
            stack.extend(value.values())
        elif isinstance(value, (list, tuple, set, frozenset)):
            stack.extend(value)
        elif kind.__module__.startswith(package) and hasattr(value, "__dict__"):
            stack.extend(vars(value).values())
    return len(found)

_GLSL_TYPES = {
    "float": "FLOAT", "vec2": "VEC2", "vec3": "VEC3", "vec4": "VEC4", "mat3": "MAT3", "mat4": "MAT4",
    "int": "INT", "ivec2": "IVEC2", "ivec3": "IVEC3", "ivec4": "IVEC4", "bool": "BOOL",
}


def ensure_gpu() -> None:
    """Make the `gpu` module usable for drawing (needed in background mode)."""
    import bpy
    import gpu

    if not bpy.app.background:
        return
    if blender_compat.has_gpu_init():
        gpu.init()  # Blender 5.2+: creates the GPU context for background mode; idempotent
        return
    # Older versions: one tiny Workbench render creates the context as a side effect.
    scene = bpy.data.scenes.new("omniwarp_gpu_init")
    try:
        scene.render.engine = "BLENDER_WORKBENCH"
        scene.render.resolution_x = scene.render.resolution_y = 4
        camera = bpy.data.objects.new("omniwarp_gpu_init_cam", bpy.data.cameras.new("omniwarp_gpu_init_cam"))
        scene.collection.objects.link(camera)
        scene.camera = camera
        bpy.ops.render.render(scene=scene.name)
    finally:
        data = scene.camera.data if scene.camera else None
        if scene.camera:
            bpy.data.objects.remove(scene.camera)
        if data:
            bpy.data.cameras.remove(data)
        bpy.data.scenes.remove(scene)


def _declare_uniforms(info: Any, iface: ProgramInterface | ComputeInterface) -> None:
    """The program's uniforms as one std140 uniform buffer (shaders/uniform_block.py says
    why not push constants), its members reached by their bare names through defines."""
    block = UniformBlock.of(iface)
    if not block.members:
        return
    info.typedef_source(block.glsl_struct())
    info.uniform_buf(0, block.type_name, INSTANCE)
    for name, member in block.member_defines().items():
        info.define(name, member)


def uniform_buffer(data: bytes) -> Any:
    """A `GPUUniformBuf` holding `data` (counted in CREATED)."""
    import gpu

    CREATED["uniform_buffer"] += 1
    return gpu.types.GPUUniformBuf(data)


def create_info(iface: ProgramInterface) -> Any:
    """A `GPUShaderCreateInfo` declaring everything `iface` names, with the shared GLSL."""
    import gpu

    info = gpu.types.GPUShaderCreateInfo()
    _declare_uniforms(info, iface)
    for slot, sampler in enumerate(iface.samplers):
        info.sampler(slot, "FLOAT_2D", sampler)
    for slot, (glsl_type, name) in enumerate(iface.vertex_in):
        info.vertex_in(slot, _GLSL_TYPES[glsl_type], name)
    if iface.varyings:
        stage = gpu.types.GPUStageInterfaceInfo(f"{iface.name}_iface")
        for var in iface.varyings:
            (stage.flat if var.flat else stage.smooth)(_GLSL_TYPES[var.glsl_type], var.name)
        info.vertex_out(stage)
    for slot, (glsl_type, name) in enumerate(iface.fragment_out):
        info.fragment_out(slot, _GLSL_TYPES[glsl_type], name)
    if iface.writes_depth and blender_compat.has_depth_write():
        # Declared where the API has it (4.5+); OpenGL honours gl_FragDepth either way.
        info.depth_write("ANY")
    _declare_images_and_defines(info, iface)
    info.vertex_source(load_source(iface.vertex_file))
    info.fragment_source(load_source(iface.fragment_file))
    return info


def compute_create_info(iface: ComputeInterface) -> Any:
    """A `GPUShaderCreateInfo` for a compute program: its uniform block, samplers, images."""
    import gpu

    info = gpu.types.GPUShaderCreateInfo()
    info.local_group_size(iface.local_size, 1, 1)
    _declare_uniforms(info, iface)
    for slot, sampler in enumerate(iface.samplers):
        info.sampler(slot, "FLOAT_2D", sampler)
    _declare_images_and_defines(info, iface)
    info.compute_source(load_source(iface.compute_file))
    return info


def _declare_images_and_defines(info: Any, iface: ProgramInterface | ComputeInterface) -> None:
    """A program's images (read and written, at their units) and every #define."""
    for unit, (fmt, name) in enumerate(iface.images):
        info.image(unit, fmt.upper(), "UINT_2D" if image_type(fmt) == "uimage2D" else "FLOAT_2D", name,
                   qualifiers={"READ", "WRITE"})
    for key, value in program_defines(iface).items():
        info.define(key, value)


def float_texture(size: tuple[int, int], fmt: str, data: np.ndarray | None = None):
    """A float `GPUTexture` (R32F, RG32F or RGBA32F), optionally filled from numpy (row 0 at
    the bottom; counted in CREATED)."""
    import gpu

    buffer = None
    if data is not None:
        flat = np.ascontiguousarray(data, dtype=np.float32).ravel()
        buffer = gpu.types.Buffer("FLOAT", flat.size, flat)
    CREATED["texture"] += 1
    return blender_compat.gpu_texture(size, fmt, buffer)


def empty_texture(size: tuple[int, int], fmt: str):
    """A `GPUTexture` of any format with undefined contents (counted in CREATED)."""
    CREATED["texture"] += 1
    return blender_compat.gpu_texture(size, fmt)


def read_uint(texture) -> np.ndarray:
    """An R32UI texture's contents as (height, width) uint32, row 0 at the bottom."""
    raw = blender_compat.buffer_array(texture.read(), np.uint32)
    return raw.reshape(texture.height, texture.width).copy()


def framebuffer(**slots):
    """A `GPUFrameBuffer` (counted in CREATED). It holds no reference to its textures: the
    caller keeps them, or a texture freed under it leaves the slot empty."""
    import gpu

    CREATED["framebuffer"] += 1
    return gpu.types.GPUFrameBuffer(**slots)


def backend_type() -> str:
    """The GPU backend Blender draws with (OPENGL, VULKAN, METAL)."""
    import gpu

    getter = getattr(gpu.platform, "backend_type_get", None)
    return getter() if getter is not None else "OPENGL"


def _components(fmt: str) -> int:
    return {"R32F": 1, "RG32F": 2, "RGBA32F": 4}[fmt]


def read_texture(texture, fmt: str) -> np.ndarray:
    """Texture contents as (height, width[, channels]) float32, row 0 at the bottom."""
    raw = blender_compat.buffer_array(texture.read(), np.float32)
    channels = _components(fmt)
    shape = (texture.height, texture.width) + ((channels,) if channels > 1 else ())
    return raw.reshape(shape).copy()
