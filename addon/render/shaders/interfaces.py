"""The program interfaces: everything a backend declares around the shared stage bodies.

Declarations (inputs, outputs, uniforms, samplers, varyings, images) live in a
`ProgramInterface` or `ComputeInterface`, and each backend turns that into its own header:
a `#version` block for moderngl (render/backends/moderngl/glsl.py), a `GPUShaderCreateInfo` for
Blender's `gpu` module (render/backends/blender/gpu_objects.py). Names are the same in both, so the bodies
need no backend switch. Uniforms several passes read are declared once, in groups, and
each interface is composed from them (as EEVEE composes its create-infos).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ...core import samples, warping
from .constants import (FOOTPRINT_VERTICES, MAX_POINT_SIZE, MEDIA_POINTS, REGION_PLANES, SHARED_DEFINES, SLOTS,
                        VERTEX_TEXTURE_WIDTH)


@dataclass(frozen=True)
class Uniform:
    glsl_type: str  # float, int, vec2, vec4, mat3, ...
    name: str
    array: int = 0  # 0 = not an array


@dataclass(frozen=True)
class Varying:
    glsl_type: str
    name: str
    flat: bool = False


@dataclass(frozen=True)
class ProgramInterface:
    """Everything a backend must declare around the shared stage bodies."""

    name: str
    vertex_file: str
    fragment_file: str
    vertex_in: tuple[tuple[str, str], ...]  # (type, name)
    fragment_out: tuple[tuple[str, str], ...]  # (type, name), location = index
    uniforms: tuple[Uniform, ...] = ()
    samplers: tuple[str, ...] = ()  # sampler2D names, binding = index
    varyings: tuple[Varying, ...] = ()
    writes_depth: bool = False
    defines: dict[str, str] = field(default_factory=dict)
    images: tuple[tuple[str, str], ...] = ()  # (format, name) of uimage2D images of the fragment stage


@dataclass(frozen=True)
class ComputeInterface:
    """Declarations around a shared compute body: uniforms, samplers and images."""

    name: str
    compute_file: str
    uniforms: tuple[Uniform, ...] = ()
    samplers: tuple[str, ...] = ()  # sampler2D names, binding = index
    images: tuple[tuple[str, str], ...] = ()  # (format, name) of images, unit = index (image_type)
    local_size: int = 64  # invocations per work group along x
    defines: dict[str, str] = field(default_factory=dict)
    # Whether a work group's invocations read each other's image stores (after a barrier):
    # declared `coherent` where the backend's GLSL can say so (moderngl; Blender's
    # create-info has no such qualifier).
    coherent: bool = False

    def groups(self, invocations: int) -> int:
        """Work groups that cover `invocations` (the body returns past the end)."""
        return max(1, -(-int(invocations) // self.local_size))


def image_type(fmt: str) -> str:
    """The GLSL image type of an image format: uimage2D for r32ui, image2D for float ones."""
    return "uimage2D" if fmt.lower().endswith("ui") else "image2D"


def program_defines(iface: ProgramInterface | ComputeInterface) -> dict[str, str]:
    """Every #define of a program: the shared GPU constants, then its own."""
    return {**SHARED_DEFINES, **iface.defines}


def uniform_list(*specs: str) -> tuple[Uniform, ...]:
    """Uniforms from "type name" or "type name[size]" strings."""
    out = []
    for spec in specs:
        glsl_type, name = spec.split()
        size = 0
        if name.endswith("]"):
            name, size_text = name[:-1].split("[")
            size = int(size_text)
        out.append(Uniform(glsl_type, name, size))
    return tuple(out)


# Shared uniform groups -------------------------------------------------------------------
# One layer of a map: its rotation, its kind and the slot of its warp tables.
LAYER_UNIFORMS = uniform_list("mat3 ow_layer_rot", "int ow_layer_kind", "int ow_layer_slot")
# Where a layer's tile lies in the atlas and how its directions map there: warp, crop, depth
# range (radial, normalised) and the near clip.
TILE_UNIFORMS = uniform_list("int ow_warp_size", "vec4 ow_crop", "float ow_near", "float ow_far",
                             "float ow_clip_near", "float ow_resolution", "vec2 ow_tile_origin")
# A spot's or sun's map instead of a layer: its matrix, and a PSM's inverted depth.
PROJECTIVE_UNIFORMS = uniform_list("int ow_projective", "int ow_map_inverted", "mat4 ow_map_matrix")
# Every layer of a frame at once (the shadow test and the scatter pick one per sample).
FRAME_LAYER_UNIFORMS = uniform_list("mat3 ow_light_rot", f"mat3 ow_layer_rot[{SLOTS}]", f"vec4 ow_layer_crop[{SLOTS}]",
                                    "int ow_layer_kind", "int ow_param", "int ow_hemi", "int ow_warp_size")
# A sun's direction (its rays are parallel) where the light is a sun.
SUN_UNIFORMS = uniform_list("int ow_sun", "vec3 ow_light_axis")
# The light's position in double-single (light-centred geometry on the GPU).
LIGHT_POSITION_UNIFORMS = uniform_list("vec3 ow_light_hi", "vec3 ow_light_lo")

WARP_SAMPLERS = ("ow_warp_rows", "ow_warp_cols")
_FULLSCREEN = {"vertex_file": "fullscreen.vert", "vertex_in": (("vec2", "ow_corner"),)}
_VERTEX_TEXTURE_DEFINES = {"OW_VERTEX_WIDTH": str(VERTEX_TEXTURE_WIDTH),
                           "OW_FOOTPRINT_VERTICES": str(FOOTPRINT_VERTICES)}

# The map passes ---------------------------------------------------------------------------
DEPTH_PROGRAM = ProgramInterface(
    name="omniwarp_depth",
    vertex_file="depth.vert",
    fragment_file="depth.frag",
    vertex_in=(("vec3", "ow_position"), ("vec4", "ow_plane")),
    fragment_out=(("float", "ow_depth"),),
    uniforms=(LAYER_UNIFORMS + uniform_list("int ow_mapped") + TILE_UNIFORMS
              + uniform_list("int ow_unfold_split", "int ow_unfold_halves") + PROJECTIVE_UNIFORMS),
    samplers=WARP_SAMPLERS,
    varyings=(Varying("float", "v_distance"), Varying("vec4", "v_plane", flat=True), Varying("vec2", "v_map_xy")),
    writes_depth=True,
)

FOOTPRINT_PROGRAM = ProgramInterface(
    name="omniwarp_footprint",
    vertex_file="footprint.vert",
    fragment_file="footprint.frag",
    vertex_in=(("float", "ow_corner"),),
    fragment_out=(("float", "ow_depth"),),
    uniforms=(LAYER_UNIFORMS + uniform_list("mat3 ow_object_linear") + LIGHT_POSITION_UNIFORMS
              + uniform_list("float ow_edge_on_distance", "float ow_dilate") + TILE_UNIFORMS
              + uniform_list(f"vec4 ow_region_planes[{REGION_PLANES}]", "int ow_region_count", "float ow_region_slack")
              + PROJECTIVE_UNIFORMS
              # The exact pass over a spot's or sun's map: a sun's edge planes contain its light's
              # direction, and the samples are lifted off their surfaces by a share of their distance.
              + SUN_UNIFORMS + uniform_list("float ow_exact_lift_share")),
    samplers=WARP_SAMPLERS + ("ow_vertices", "ow_ray_table"),
    varyings=(Varying("vec4", "v_plane", flat=True),
              *(Varying("vec3", f"v_edge{i}", flat=True) for i in range(3))),
    writes_depth=True,
    defines={**_VERTEX_TEXTURE_DEFINES, "OW_REGION_PLANES": str(REGION_PLANES),
             "OW_MAX_POINT_SIZE": str(MAX_POINT_SIZE)},
)

RAY_TABLE_PROGRAM = ProgramInterface(
    name="omniwarp_ray_table",
    fragment_file="ray_table.frag",
    fragment_out=(("vec2", "ow_ray_xy"),),
    uniforms=uniform_list("int ow_layer_slot", "int ow_warp_size", "vec4 ow_crop", "float ow_resolution",
                          "vec2 ow_tile_origin"),
    samplers=WARP_SAMPLERS,
    **_FULLSCREEN,
)

SHADOW_TEST_PROGRAM = ProgramInterface(
    name="omniwarp_shadow_test",
    fragment_file="shadow_test.frag",
    fragment_out=(("vec2", "ow_result"),),
    uniforms=(FRAME_LAYER_UNIFORMS
              + uniform_list(f"vec4 ow_layer_tile[{SLOTS}]", f"vec4 ow_layer_box[{SLOTS}]", "float ow_resolution",
                             "float ow_near", "float ow_far", "float ow_bias_const", "float ow_bias_slope",
                             "float ow_bias_normal")
              + PROJECTIVE_UNIFORMS + uniform_list("float ow_depth_offset") + SUN_UNIFORMS
              + uniform_list("float ow_spot_cos", "int ow_edge_radius")),
    samplers=("ow_positions", "ow_normals", "ow_atlas") + WARP_SAMPLERS + ("ow_edges",),
    **_FULLSCREEN,
)

EDGE_PROGRAM = ProgramInterface(
    name="omniwarp_edge_distance",
    fragment_file="edge_distance.frag",
    fragment_out=(("float", "ow_edge"),),
    uniforms=uniform_list("int ow_edge_pass", "int ow_edge_radius", "float ow_edge_eps", "float ow_edge_tile_size"),
    samplers=("ow_atlas", "ow_edge_x"),
    **_FULLSCREEN,
)

# A frame's visibility copied where a compositor samples it, the exact pass's marks applied
# (passes/shadow_test.resolve_visibility).
RESOLVE_PROGRAM = ProgramInterface(
    name="omniwarp_visibility_resolve",
    fragment_file="visibility_resolve.frag",
    fragment_out=(("vec2", "ow_visibility"),),
    uniforms=uniform_list("int ow_marks", "int ow_media_on", "vec3 ow_media_light", "float ow_media_scale",
                          "int ow_media_points", "int ow_media_across", f"vec4 ow_media_index[{MEDIA_POINTS // 4}]"),
    samplers=("ow_test", "ow_positions"),
    images=(("r32ui", "ow_hits"), ("r32ui", "ow_media")),
    defines={"OW_MEDIA_WORDS": "1"},  # variants.MEDIA_WORDS_DEFINE: it reads the exact pass's words
    **_FULLSCREEN,
)

# Compute passes ---------------------------------------------------------------------------
SCATTER_PROGRAM = ComputeInterface(
    name="omniwarp_scatter",
    compute_file="scatter.comp",
    uniforms=(FRAME_LAYER_UNIFORMS
              + uniform_list(f"int ow_slot_tile[{SLOTS}]", "int ow_scatter_mode", "int ow_count_size",
                             "int ow_weighted",
                             # A spot's or sun's map (the exact pass's lists): the samples go through its matrix.
                             "int ow_projective", "mat4 ow_map_matrix")),
    samplers=("ow_positions",) + WARP_SAMPLERS,
    images=(("r32ui", "ow_counts"),),
)

# Planning statistics (core/samples.py names the fields and sizes; emitted as defines).
SAMPLE_STATS_PROGRAM = ComputeInterface(
    name="omniwarp_sample_stats",
    compute_file="sample_stats.comp",
    uniforms=uniform_list("mat3 ow_light_rot", "vec3 ow_view_axis", "float ow_view_offset", "int ow_hemi",
                          "int ow_stats_pass", "int ow_ortho"),
    samplers=("ow_positions",),
    images=(("r32ui", "ow_stats"), ("r32ui", "ow_stats_out")),
    local_size=samples.CUT_CHUNKS,  # pass 2's one group: an invocation a chunk of the histogram
    coherent=True,  # pass 2's invocations read each other's chunk sums
    defines={"OW_STAT_SPAN": str(samples.STAT_SPAN), "OW_HIST_BINS": str(samples.HIST_BINS),
             "OW_CUT_CHUNKS": str(samples.CUT_CHUNKS),
             "OW_STAT_COUNT": str(samples.STAT_COUNT), "OW_ROUNDING": repr(samples.ROUNDING),
             "OW_CUT_STEPS": str(100 * samples.CUT_STEPS),
             "OW_CUT_Q": str(round(samples.CULL_DEPTH_PERCENTILE * samples.CUT_STEPS)),
             **{f"OW_STAT_{name}": str(index) for index, name in enumerate(samples.STAT_FIELDS)}},
)

# Nothing but the barrier that ends every compute dispatch in Blender's `gpu` module, which
# has no call of its own for one (the Blender backend's _image_barrier).
BARRIER_PROGRAM = ComputeInterface(name="omniwarp_barrier", compute_file="barrier.comp", local_size=1)

# Between two rounds of the exact pass: each list's head moves past the entries walked.
ADVANCE_PROGRAM = ComputeInterface(
    name="omniwarp_list_advance",
    compute_file="list_advance.comp",
    uniforms=uniform_list("int ow_advance_steps", "int ow_tile_size"),
    images=(("r32ui", "ow_counts"), ("r32ui", "ow_next"), ("r32ui", "ow_work")),
)

# The NoTW warp built on the GPU (warp_build.comp; core/warping.py names the constants):
# the count strip, the crop's bounds, the families' working lines, each tile's window and
# shear, and the packed table it writes.
WARP_BUILD_PROGRAM = ComputeInterface(
    name="omniwarp_warp_build",
    compute_file="warp_build.comp",
    uniforms=uniform_list("int ow_family", "int ow_count_size", "int ow_tiles", "int ow_along",
                          f"int ow_tile_slot[{SLOTS}]"),
    images=(("r32ui", "ow_counts"), ("r32ui", "ow_bounds"), ("r32ui", "ow_work"), ("r32ui", "ow_info"),
            ("rgba32f", "ow_table")),
    defines={"OW_FLOOR_SHARE": repr(float(warping.FLOOR_SHARE)), "OW_MAX_SLOPE": repr(float(warping.MAX_SLOPE)),
             "OW_SHEAR_LIMIT": repr(float(warping.SHEAR_LIMIT)),
             "OW_IDENTITY_PRIOR": repr(float(warping.IDENTITY_PRIOR)),
             "OW_CROP_MARGIN": repr(float(warping.CROP_MARGIN))},
)

# The viewport ------------------------------------------------------------------------------
# The G-buffer, drawn from resident objects (the Blender backend's draw_gbuffer_steps).
GBUFFER_PROGRAM = ProgramInterface(
    name="omniwarp_gbuffer",
    vertex_file="gbuffer.vert",
    fragment_file="gbuffer.frag",
    vertex_in=(("float", "ow_corner"),),
    fragment_out=(("vec4", "ow_gb_position"), ("vec4", "ow_gb_normal")),
    uniforms=uniform_list("mat4 ow_view_proj", "vec4 ow_camera_pos",  # homogeneous eye
                          "mat3 ow_object_linear", "vec3 ow_object_origin"),
    samplers=("ow_vertices",),
    varyings=(Varying("vec3", "v_world"), Varying("vec3", "v_normal", flat=True)),
    defines=dict(_VERTEX_TEXTURE_DEFINES),
)

# The shadow test's samples from a G-buffer (the Blender backend's samples_from_gbuffer).
GBUFFER_SAMPLES_PROGRAM = ProgramInterface(
    name="omniwarp_gbuffer_samples",
    fragment_file="gbuffer_samples.frag",
    fragment_out=(("vec4", "ow_sample"),),
    uniforms=LIGHT_POSITION_UNIFORMS,
    samplers=("ow_gb_position",),
    **_FULLSCREEN,
)

PREVIEW_PROGRAM = ProgramInterface(
    name="omniwarp_preview",
    fragment_file="preview.frag",
    fragment_out=(("vec4", "ow_color"),),
    uniforms=uniform_list("vec3 ow_light_pos", "float ow_strength", "int ow_draw_base", "vec2 ow_target_size",
                          "int ow_sun", "vec3 ow_light_dir",
                          # An earlier view's visibility looked up from this one (backends/blender/draw.Reprojection).
                          "int ow_reproject", "mat4 ow_old_view_proj", "float ow_old_tolerance"),
    samplers=("ow_gb_position", "ow_gb_normal", "ow_visibility", "ow_old_position"),
    **_FULLSCREEN,
)

OVERLAY_PROGRAM = ProgramInterface(
    name="omniwarp_overlay",
    vertex_file="overlay.vert",
    fragment_file="overlay.frag",
    vertex_in=(("vec2", "ow_corner"),),
    fragment_out=(("vec4", "ow_color"),),
    uniforms=uniform_list("vec4 ow_rect", "vec2 ow_target_size", "int ow_mode", "float ow_max"),
    samplers=("ow_image",),
    varyings=(Varying("vec2", "v_uv"),),
)
