"""Every Blender API that differs between the lines this extension supports (4.2 LTS,
4.5 LTS, 5.2), in one place.

Each gate is decided by `bpy.app.version` or by feature detection on the RNA/type, never by
catching the failure of a whole feature. `bpy` and `gpu` are imported lazily, so this module
imports without Blender. The table of what differs and what the extension does on each line
is docs/versions.md; `line_gaps()` is the one-line-per-gap summary the CLI and the panels
show.
"""
from __future__ import annotations

import functools
import logging
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

log = logging.getLogger(__name__)

# The EEVEE option (5.0+) that scales direct light; the eevee row sets it to 1 where it exists.
EEVEE_DIRECT_LIGHT = "direct_light_intensity"
# The multilayer EXR names the Diffuse Direct pass "DiffDir" before Blender 5.0.
_SHORT_PASS_NAMES = {"Diffuse Direct": "DiffDir", "Diffuse Indirect": "DiffInd", "Diffuse Color": "DiffCol"}


def version() -> tuple[int, int, int]:
    """The running Blender's (major, minor, patch)."""
    import bpy

    return tuple(bpy.app.version[:3])


def exr_pass_name(name: str) -> str:
    """The multilayer-EXR channel name of the render pass `name` on this line."""
    if version() >= (5, 0, 0):
        return name
    return _SHORT_PASS_NAMES.get(name, name)


def has_gpu_init() -> bool:
    """`gpu.init()` (5.2+) creates the background-mode GPU context; older lines need a tiny render."""
    import gpu

    return hasattr(gpu, "init")


def has_depth_write() -> bool:
    """`GPUShaderCreateInfo.depth_write` (4.5+). Without it OpenGL still honours gl_FragDepth."""
    import gpu

    return hasattr(gpu.types.GPUShaderCreateInfo, "depth_write")


def has_compute() -> bool:
    """Compute shaders and image load/store through `gpu.compute` (all supported lines)."""
    import gpu

    return hasattr(gpu, "compute") and hasattr(gpu.types.GPUShaderCreateInfo, "local_group_size")


def gpu_texture(size: tuple[int, int], fmt: str, buffer: Any = None) -> Any:
    """A `GPUTexture`; before 5.0 the `data` argument must be a Buffer, not None, so it is left out."""
    import gpu

    if buffer is None:
        return gpu.types.GPUTexture(size, format=fmt)
    return gpu.types.GPUTexture(size, format=fmt, data=buffer)


def buffer_array(buffer: Any, dtype: Any) -> np.ndarray:
    """A `gpu.types.Buffer` (e.g. from `GPUTexture.read()`) as a flat numpy array in memory order.

    Before 5.0 a multi-dimensional Buffer exports Fortran strides over C-ordered memory, so
    `np.asarray` would transpose it; there the Buffer is viewed as one dimension first."""
    with memoryview(buffer) as view:
        in_order = view.ndim <= 1 or view.c_contiguous
        count = view.nbytes // view.itemsize
    if not in_order:
        buffer.dimensions = [count]
    return np.asarray(buffer, dtype=dtype).ravel()


def set_multilayer_exr(image_settings: Any, setter: Callable[[Any, str, Any], None]) -> None:
    """Select 32-bit multilayer OpenEXR output on `image_settings` through `setter(obj, name, value)`.

    5.x splits the choice in two: `media_type` first, then `file_format`; earlier lines have
    only `file_format`, whose enum holds OPEN_EXR_MULTILAYER directly."""
    if hasattr(image_settings, "media_type"):
        setter(image_settings, "media_type", "MULTI_LAYER_IMAGE")
    setter(image_settings, "file_format", "OPEN_EXR_MULTILAYER")


@functools.cache
def has_linear_curves() -> bool:
    """Whether Cycles draws poly hair curves straight between their points (5.x, with its
    "Linear 3D Curves" shape); 4.2-4.5 draw every hair curve as a Catmull-Rom spline."""
    import bpy

    curves = bpy.types.Scene.bl_rna.properties.get("cycles_curves")  # Cycles' own settings
    if curves is None:
        return False
    shapes = curves.fixed_type.properties["shape"].enum_items
    return "THICK_LINEAR" in {item.identifier for item in shapes}


@functools.cache  # the shadow rule asks once per object
def has_light_linking() -> bool:
    """Light and shadow linking (`Object.light_linking`, 4.0+)."""
    import bpy

    return "light_linking" in bpy.types.Object.bl_rna.properties


def eevee_engine_id() -> str | None:
    """The render engine id of EEVEE Next (virtual shadow maps), or None when this line lacks it.

    4.2-4.5 name it BLENDER_EEVEE_NEXT; 5.x calls it BLENDER_EEVEE again."""
    import bpy

    ids = {item.identifier for item in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    if "BLENDER_EEVEE_NEXT" in ids:
        return "BLENDER_EEVEE_NEXT"
    if "BLENDER_EEVEE" in ids and "shadow_maximum_resolution" in bpy.types.PointLight.bl_rna.properties:
        return "BLENDER_EEVEE"
    return None


def ensure_node_tree(id_block: Any) -> Any:
    """The node tree of a material or world, creating it where the line needs `use_nodes`.

    Before 5.0 a new material has no tree until `use_nodes` is set; 5.0 deprecates the flag
    (every material has nodes), so it is only written where the tree is missing."""
    if getattr(id_block, "node_tree", None) is None and hasattr(id_block, "use_nodes"):
        id_block.use_nodes = True
    return id_block.node_tree


def set_see_through(material: Any) -> None:
    """EEVEE's settings for a material with alpha: dithered surfaces and transparent shadows
    (EEVEE Next, 4.2+, on every line the manifest names); Cycles reads the nodes alone."""
    if hasattr(material, "surface_render_method"):
        material.surface_render_method = "DITHERED"
    if hasattr(material, "use_transparent_shadow"):
        material.use_transparent_shadow = True


def uses_nodes(id_block: Any) -> bool:
    """Whether a material or world renders through its node tree on this line."""
    if id_block.node_tree is None:
        return False
    if version() >= (5, 0, 0):
        return True  # use_nodes is deprecated and always true
    return bool(getattr(id_block, "use_nodes", True))


def has_get_transform() -> bool:
    """`bpy.props` properties accept `get_transform` (5.0+)."""
    return version() >= (5, 0, 0)


def system_properties(id_block: Any) -> Any:
    """Where an ID stores add-on properties: 5.x keeps them as "system properties"."""
    getter = getattr(id_block, "bl_system_properties_get", None)
    return getter() if getter is not None else id_block


@dataclass(frozen=True)
class LineGap:
    """Something this Blender line lacks, and what the extension does instead."""

    name: str  # stable id (tests, logs)
    text: str  # one line for the CLI and the panel


# The geometry-nodes grid nodes that read a Volume object's density grid
# (readers/volume_grids.py): in 4.x only behind an experimental flag.
GRID_NODES = ("GeometryNodeObjectInfo", "GeometryNodeGetNamedGrid", "GeometryNodeSampleGrid")
GRID_NODES_VERSION = (5, 0, 0)


def grid_nodes_available() -> bool:
    """Whether this Blender reads density grids through geometry nodes (5.0 or later)."""
    import bpy

    return version() >= GRID_NODES_VERSION and all(hasattr(bpy.types, n) for n in GRID_NODES)


@functools.cache
def line_gaps() -> tuple[LineGap, ...]:
    """What the running line lacks of the APIs the extension uses; empty on 5.2 (cached: the
    panels call it on every redraw, and the line never changes within a process)."""
    import bpy

    line = "Blender %d.%d" % version()[:2]
    gaps = []
    if eevee_engine_id() is None:
        gaps.append(LineGap("eevee_next", f"{line} has no EEVEE Next: the eevee row is not available"))
    elif EEVEE_DIRECT_LIGHT not in bpy.types.SceneEEVEE.bl_rna.properties:
        gaps.append(LineGap(EEVEE_DIRECT_LIGHT, f"{line} EEVEE has no direct light intensity: "
                                                "the eevee row renders direct light unscaled"))
    if not has_light_linking():
        gaps.append(LineGap("light_linking", f"{line} has no light linking: every object shadows every light"))
    if not has_compute():
        gaps.append(LineGap("compute", f"{line} has no compute shaders: the viewport preview cannot run"))
    if not has_depth_write():
        gaps.append(LineGap("depth_write", f"{line} shaders cannot declare depth_write: "
                                           "depth is written undeclared (OpenGL honours it)"))
    if not grid_nodes_available():
        gaps.append(LineGap("grid_nodes", f"{line} has no geometry-nodes grid nodes: Volume objects cast no "
                                          "shadow in OmniWarp's methods (named in every row's note)"))
    if not has_get_transform():
        gaps.append(LineGap("get_transform", f"{line} has no property get_transform: "
                                             "a stale stored method shows blank; the panel names the one used"))
    return tuple(gaps)


def _version_string() -> str:
    import bpy

    return bpy.app.version_string
