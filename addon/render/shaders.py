"""GLSL loader: the shader bodies in `gpu_shaders/` are written once.

Stage files hold only functions and `main()`; they pull helpers in with
`#include "lib/name.glsl"`. Declarations (inputs, outputs, uniforms, samplers,
varyings) live in a `ProgramInterface` here, and each backend turns that into its
own header: a `#version` block of declarations for moderngl, a
`GPUShaderCreateInfo` for Blender's `gpu` module. Names are the same in both, so
the bodies need no backend switch.
"""
from __future__ import annotations

import functools
import logging
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..core import alpha, footprint, projection, samples
from ..core.errors import BackendError

log = logging.getLogger(__name__)

SHADER_DIR = Path(__file__).resolve().parents[2] / "gpu_shaders"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)
GLSL_VERSION = "430 core"


# GPU constants with one source: every program's header defines them (`program_defines`),
# so no shader file spells them out.
PARAM_CODES = {"dpsm": 0, "cube": 1, "ipsm": 2, "unfold": 3, "sm": 4, "psm": 5}  # ow_param
SLOTS = 6  # layer slots the GLSL tables hold (ow_layer_rot[OW_SLOTS] and the like): a cube's faces
SHARED_DEFINES: dict[str, str] = {
    **{f"OW_PARAM_{name.upper()}": str(code) for name, code in PARAM_CODES.items()},
    "OW_KIND_PARABOLOID": str(projection.PARABOLOID),
    "OW_KIND_CUBE": str(projection.CUBE),
    "OW_KIND_UNFOLD": str(projection.UNFOLD),
    "OW_SLOTS": str(SLOTS),
    "OW_EDGE_ON": repr(float(footprint.GPU_EDGE_ON)),  # the host's count of drawn triangles uses it
    # See-through surfaces (core/alpha.py): the exact pass's word and the alpha bounds.
    "OW_OPAQUE_ALPHA": repr(float(alpha.OPAQUE_ALPHA)),
    "OW_CLEAR_ALPHA": repr(float(alpha.CLEAR_ALPHA)),
    "OW_HIT_OPAQUE": f"{alpha.HIT_OPAQUE:#x}u",
    "OW_OPTICAL_SCALE": repr(float(alpha.OPTICAL_SCALE)),
}
# The exact pass's work image (R32UI, WORK_TEXELS x 1; footprint.frag, list_advance.comp):
# a round's walks cut at its bound, and on measurement frames the entries and fragments
# walked (the host folds them round by round); from WORK_BOX, four words per tile, the box of the
# texels whose lists go on into the next round.
WORK_CUT, WORK_ENTRIES, WORK_FRAGMENTS, WORK_BOX = 0, 1, 2, 8
WORK_TEXELS = WORK_BOX + 4 * SLOTS
SHARED_DEFINES.update({"OW_WORK_CUT": str(WORK_CUT), "OW_WORK_ENTRIES": str(WORK_ENTRIES),
                       "OW_WORK_FRAGMENTS": str(WORK_FRAGMENTS), "OW_WORK_BOX": str(WORK_BOX)})


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
    images: tuple[tuple[str, str], ...] = ()  # (format, name) of uimage2D images, unit = index
    local_size: int = 64  # invocations per work group along x
    defines: dict[str, str] = field(default_factory=dict)

    def groups(self, invocations: int) -> int:
        """Work groups that cover `invocations` (the body returns past the end)."""
        return max(1, -(-int(invocations) // self.local_size))


def load_source(relative: str, shader_dir: Path = SHADER_DIR) -> str:
    """Read a GLSL file and inline its `#include`s, each file at most once.

    Raises BackendError for a missing file or an include cycle.
    """
    seen: set[Path] = set()

    def expand(path: Path, stack: tuple[Path, ...]) -> str:
        resolved = path.resolve()
        if resolved in stack:
            chain = " -> ".join(p.name for p in stack + (resolved,))
            raise BackendError(f"GLSL include cycle: {chain}")
        if not resolved.is_file():
            raise BackendError(f"GLSL file not found: {path} (looked under {shader_dir})")
        if resolved in seen:
            return f"// (already included: {path.name})\n"
        seen.add(resolved)
        text = resolved.read_text(encoding="utf-8")

        def replace(match: re.Match) -> str:
            return expand(shader_dir / match.group(1), stack + (resolved,))

        return _INCLUDE.sub(replace, text)

    return expand(shader_dir / relative, ())


# Shared interfaces ---------------------------------------------------------

_WARP_SAMPLERS = ("ow_warp_rows", "ow_warp_cols")

DEPTH_PROGRAM = ProgramInterface(
    name="omniwarp_depth",
    vertex_file="depth.vert",
    fragment_file="depth.frag",
    vertex_in=(("vec3", "ow_position"), ("vec4", "ow_plane")),
    fragment_out=(("float", "ow_depth"),),
    uniforms=(
        Uniform("mat3", "ow_layer_rot"),
        Uniform("int", "ow_layer_kind"),
        Uniform("int", "ow_layer_slot"),
        Uniform("int", "ow_mapped"),
        Uniform("int", "ow_warp_size"),
        Uniform("vec4", "ow_crop"),
        Uniform("float", "ow_near"),
        Uniform("float", "ow_far"),
        Uniform("float", "ow_clip_near"),
        Uniform("float", "ow_resolution"),
        Uniform("vec2", "ow_tile_origin"),
        Uniform("int", "ow_unfold_split"),
        Uniform("int", "ow_unfold_halves"),
        Uniform("int", "ow_projective"),
        Uniform("int", "ow_map_inverted"),
        Uniform("mat4", "ow_map_matrix"),
    ),
    samplers=_WARP_SAMPLERS,
    varyings=(
        Varying("float", "v_distance"),
        Varying("vec4", "v_plane", flat=True),
        Varying("vec2", "v_map_xy"),
    ),
    writes_depth=True,
)

# Vertex texture of the footprint pass: texel t of an object at (t % W, t // W); vertex i
# is texels 2i and 2i + 1 (double-single, resident.vertex_texels).
VERTEX_TEXTURE_WIDTH = 2048
# Vertices the footprint pass draws per triangle: one quad as two triangles.
FOOTPRINT_VERTICES = 6
# Largest point sprite (texels a side) the footprint pass draws instead of a quad: every
# desktop GL driver supports 64 (llvmpipe 255; Vulkan's minimum is 64 too).
MAX_POINT_SIZE = 64
# Planes of the occluder region the footprint pass culls against (conv(light, frustum)
# of 8 corners and the light has at most 2 * 9 - 4 = 14 faces).
REGION_PLANES = 16

FOOTPRINT_PROGRAM = ProgramInterface(
    name="omniwarp_footprint",
    vertex_file="footprint.vert",
    fragment_file="footprint.frag",
    vertex_in=(("float", "ow_corner"),),
    fragment_out=(("float", "ow_depth"),),
    uniforms=(
        Uniform("mat3", "ow_layer_rot"),
        Uniform("mat3", "ow_object_linear"),
        Uniform("vec3", "ow_light_hi"),
        Uniform("vec3", "ow_light_lo"),
        Uniform("float", "ow_edge_on_distance"),
        Uniform("int", "ow_layer_kind"),
        Uniform("int", "ow_layer_slot"),
        Uniform("int", "ow_warp_size"),
        Uniform("vec2", "ow_warp_shear"),
        Uniform("vec4", "ow_crop"),
        Uniform("float", "ow_near"),
        Uniform("float", "ow_far"),
        Uniform("float", "ow_clip_near"),
        Uniform("float", "ow_resolution"),
        Uniform("float", "ow_dilate"),
        Uniform("vec2", "ow_tile_origin"),
        Uniform("vec4", "ow_region_planes", REGION_PLANES),
        Uniform("int", "ow_region_count"),
        Uniform("float", "ow_region_slack"),
        Uniform("int", "ow_projective"),
        Uniform("int", "ow_map_inverted"),
        Uniform("mat4", "ow_map_matrix"),
        # The exact pass over a spot's or sun's map: a sun's edge planes contain its light's
        # direction, and the samples are lifted off their surfaces by a share of their distance.
        Uniform("int", "ow_sun"),
        Uniform("vec3", "ow_light_axis"),
        Uniform("float", "ow_exact_lift_share"),
    ),
    samplers=_WARP_SAMPLERS + ("ow_vertices", "ow_ray_table"),
    varyings=(
        Varying("vec4", "v_plane", flat=True),
        Varying("vec3", "v_edge0", flat=True),
        Varying("vec3", "v_edge1", flat=True),
        Varying("vec3", "v_edge2", flat=True),
    ),
    writes_depth=True,
    defines={"OW_VERTEX_WIDTH": str(VERTEX_TEXTURE_WIDTH), "OW_REGION_PLANES": str(REGION_PLANES),
             "OW_FOOTPRINT_VERTICES": str(FOOTPRINT_VERTICES), "OW_MAX_POINT_SIZE": str(MAX_POINT_SIZE)},
)

RAY_TABLE_PROGRAM = ProgramInterface(
    name="omniwarp_ray_table",
    vertex_file="fullscreen.vert",
    fragment_file="ray_table.frag",
    vertex_in=(("vec2", "ow_corner"),),
    fragment_out=(("vec2", "ow_ray_xy"),),
    uniforms=(
        Uniform("int", "ow_layer_slot"),
        Uniform("int", "ow_warp_size"),
        Uniform("vec4", "ow_crop"),
        Uniform("float", "ow_resolution"),
        Uniform("vec2", "ow_tile_origin"),
    ),
    samplers=_WARP_SAMPLERS,
)

SHADOW_TEST_PROGRAM = ProgramInterface(
    name="omniwarp_shadow_test",
    vertex_file="fullscreen.vert",
    fragment_file="shadow_test.frag",
    vertex_in=(("vec2", "ow_corner"),),
    fragment_out=(("vec2", "ow_result"),),
    uniforms=(
        Uniform("mat3", "ow_light_rot"),
        Uniform("mat3", "ow_layer_rot", SLOTS),
        Uniform("vec4", "ow_layer_tile", SLOTS),
        Uniform("vec4", "ow_layer_crop", SLOTS),
        Uniform("vec4", "ow_layer_box", SLOTS),
        Uniform("int", "ow_param"),
        Uniform("int", "ow_layer_kind"),
        Uniform("int", "ow_hemi"),
        Uniform("int", "ow_warp_size"),
        Uniform("float", "ow_resolution"),
        Uniform("float", "ow_near"),
        Uniform("float", "ow_far"),
        Uniform("float", "ow_bias_const"),
        Uniform("float", "ow_bias_slope"),
        Uniform("float", "ow_bias_normal"),
        Uniform("int", "ow_projective"),
        Uniform("int", "ow_map_inverted"),
        Uniform("mat4", "ow_map_matrix"),
        Uniform("float", "ow_depth_offset"),
        Uniform("int", "ow_sun"),
        Uniform("vec3", "ow_light_axis"),
        Uniform("float", "ow_spot_cos"),
        Uniform("int", "ow_edge_radius"),
    ),
    samplers=("ow_positions", "ow_normals", "ow_atlas") + _WARP_SAMPLERS + ("ow_edges",),
)

SCATTER_PROGRAM = ComputeInterface(
    name="omniwarp_scatter",
    compute_file="scatter.comp",
    uniforms=(
        Uniform("mat3", "ow_light_rot"),
        Uniform("mat3", "ow_layer_rot", SLOTS),
        Uniform("vec4", "ow_layer_crop", SLOTS),
        Uniform("int", "ow_slot_tile", SLOTS),
        Uniform("int", "ow_layer_kind"),
        Uniform("int", "ow_param"),
        Uniform("int", "ow_hemi"),
        Uniform("int", "ow_warp_size"),
        Uniform("int", "ow_scatter_mode"),
        Uniform("int", "ow_count_size"),
        Uniform("int", "ow_weighted"),
        # A spot's or sun's map (the exact pass's lists): the samples go through its matrix.
        Uniform("int", "ow_projective"),
        Uniform("mat4", "ow_map_matrix"),
    ),
    samplers=("ow_positions",) + _WARP_SAMPLERS,
    images=(("r32ui", "ow_counts"),),
)

# Planning statistics (core/samples.py names the fields and sizes; emitted as defines).
SAMPLE_STATS_PROGRAM = ComputeInterface(
    name="omniwarp_sample_stats",
    compute_file="sample_stats.comp",
    uniforms=(
        Uniform("mat3", "ow_light_rot"),
        Uniform("vec3", "ow_view_axis"),
        Uniform("float", "ow_view_offset"),
        Uniform("int", "ow_hemi"),
        Uniform("int", "ow_stats_pass"),
        Uniform("float", "ow_depth_lo"),
        Uniform("float", "ow_depth_hi"),
        Uniform("int", "ow_log_bins"),
    ),
    samplers=("ow_positions",),
    images=(("r32ui", "ow_stats"),),
    defines={"OW_STAT_SPAN": str(samples.STAT_SPAN), "OW_HIST_BINS": str(samples.HIST_BINS),
             "OW_STAT_COUNT": str(samples.STAT_COUNT),
             **{f"OW_STAT_{name}": str(index) for index, name in enumerate(samples.STAT_FIELDS)}},
)

# Nothing but the barrier that ends every compute dispatch in Blender's `gpu` module, which
# has no call of its own for one (blender_backend._image_barrier).
BARRIER_PROGRAM = ComputeInterface(name="omniwarp_barrier", compute_file="barrier.comp", local_size=1)

# The G-buffer, drawn from resident objects (blender_backend.draw_gbuffer).
GBUFFER_PROGRAM = ProgramInterface(
    name="omniwarp_gbuffer",
    vertex_file="gbuffer.vert",
    fragment_file="gbuffer.frag",
    vertex_in=(("float", "ow_corner"),),
    fragment_out=(("vec4", "ow_gb_position"), ("vec4", "ow_gb_normal")),
    uniforms=(Uniform("mat4", "ow_view_proj"), Uniform("vec4", "ow_camera_pos"),  # homogeneous eye
              Uniform("mat3", "ow_object_linear"), Uniform("vec3", "ow_object_origin")),
    samplers=("ow_vertices",),
    varyings=(Varying("vec3", "v_world"), Varying("vec3", "v_normal", flat=True)),
    defines={"OW_VERTEX_WIDTH": str(VERTEX_TEXTURE_WIDTH), "OW_FOOTPRINT_VERTICES": str(FOOTPRINT_VERTICES)},
)

# The shadow test's samples from a G-buffer (blender_backend.samples_from_gbuffer).
GBUFFER_SAMPLES_PROGRAM = ProgramInterface(
    name="omniwarp_gbuffer_samples",
    vertex_file="fullscreen.vert",
    fragment_file="gbuffer_samples.frag",
    vertex_in=(("vec2", "ow_corner"),),
    fragment_out=(("vec4", "ow_sample"),),
    uniforms=(Uniform("vec3", "ow_light_hi"), Uniform("vec3", "ow_light_lo")),
    samplers=("ow_gb_position",),
)

PREVIEW_PROGRAM = ProgramInterface(
    name="omniwarp_preview",
    vertex_file="fullscreen.vert",
    fragment_file="preview.frag",
    vertex_in=(("vec2", "ow_corner"),),
    fragment_out=(("vec4", "ow_color"),),
    uniforms=(Uniform("vec3", "ow_light_pos"), Uniform("float", "ow_strength"), Uniform("int", "ow_draw_base"),
              Uniform("vec2", "ow_target_size"), Uniform("int", "ow_sun"), Uniform("vec3", "ow_light_dir")),
    samplers=("ow_gb_position", "ow_gb_normal", "ow_visibility"),
)

OVERLAY_PROGRAM = ProgramInterface(
    name="omniwarp_overlay",
    vertex_file="overlay.vert",
    fragment_file="overlay.frag",
    vertex_in=(("vec2", "ow_corner"),),
    fragment_out=(("vec4", "ow_color"),),
    uniforms=(Uniform("vec4", "ow_rect"), Uniform("vec2", "ow_target_size"), Uniform("int", "ow_mode"),
              Uniform("float", "ow_max")),
    samplers=("ow_image",),
    varyings=(Varying("vec2", "v_uv"),),
)

EDGE_PROGRAM = ProgramInterface(
    name="omniwarp_edge_distance",
    vertex_file="fullscreen.vert",
    fragment_file="edge_distance.frag",
    vertex_in=(("vec2", "ow_corner"),),
    fragment_out=(("float", "ow_edge"),),
    uniforms=(Uniform("int", "ow_edge_pass"), Uniform("int", "ow_edge_radius"), Uniform("float", "ow_edge_eps"),
              Uniform("float", "ow_edge_tile_size")),
    samplers=("ow_atlas", "ow_edge_x"),
)

# Variants of the depth and shadow-test programs. llvmpipe (and other SIMD software
# rasterisers) runs a branch on a uniform with masked lanes, so code a frame never takes
# still costs every fragment:
# - `OW_NO_WARP` removes the warp code (the binary-search loop of the inverse warp cost
#   every plain depth fragment ~6x its real work); `lib/mapping.glsl` keeps the crop.
# - `OW_FIXED_KIND` makes the layer kind (paraboloid or cube) a compile-time constant, so
#   the other kinds' projections, the unfold's transcendentals and the projective (spot,
#   sun) paths compile out. Measured on courtyard's plain cube faces at 1024: 3.6-4.4 ms
#   a face with the generic program, 2.2-2.9 ms with this variant, about 1 ms with a
#   trivial fragment stage.
NO_WARP_DEFINE = "OW_NO_WARP"
FIXED_KIND_DEFINE = "OW_FIXED_KIND"
POINTS_DEFINE = "OW_POINTS"  # the footprint pass as point sprites
# Layer kinds with a fixed-kind variant; the values mirror core.projection's
# PARABOLOID and CUBE (lib/projection.glsl's OW_KIND_PARABOLOID, OW_KIND_CUBE).
FIXED_KIND_NAMES = {projection.PARABOLOID: "paraboloid", projection.CUBE: "cube"}
_VARIANT_BASES = {DEPTH_PROGRAM.name: DEPTH_PROGRAM, SHADOW_TEST_PROGRAM.name: SHADOW_TEST_PROGRAM,
                  FOOTPRINT_PROGRAM.name: FOOTPRINT_PROGRAM}


def _variant(base_name: str, warped: bool, kind: int | None, points: bool = False) -> ProgramInterface:
    return _cached_variant(base_name, bool(warped), kind, bool(points))  # one cache key per variant


@functools.cache
def _cached_variant(base_name: str, warped: bool, kind: int | None, points: bool) -> ProgramInterface:
    base = _VARIANT_BASES[base_name]
    if warped and kind is None and not points:
        return base
    defines = dict(base.defines)
    name = base.name
    if points:
        defines[POINTS_DEFINE] = "1"
        name += "_points"
    if not warped:
        defines[NO_WARP_DEFINE] = "1"
        name += "_plain"
    if kind is not None:
        defines[FIXED_KIND_DEFINE] = str(kind)
        name += "_" + FIXED_KIND_NAMES[kind]
    return replace(base, name=name, defines=defines)


def program_variant(iface: ProgramInterface, uniforms: dict, points: bool = False) -> ProgramInterface:
    """The variant of the depth or shadow-test program that `uniforms` need.

    With the warp only when they set one (ow_warp_size > 0), and fixed to the layer
    kind when that is a paraboloid or a cube face and the frame is neither projective
    nor an unfold (which keep the generic program). Variants are built once and cached;
    each has its own name, because backends cache compiled programs by name.
    """
    if iface.name not in _VARIANT_BASES:
        raise BackendError(f"program {iface.name!r} has no variants")
    warped = int(uniforms.get("ow_warp_size", 0)) > 0
    kind = int(uniforms.get("ow_layer_kind", -1))
    generic = (kind not in FIXED_KIND_NAMES or int(uniforms.get("ow_projective", 0)) != 0
               or int(uniforms.get("ow_unfold_split", -1)) >= 0)
    if points and iface.name != FOOTPRINT_PROGRAM.name:
        raise BackendError(f"program {iface.name!r} has no point-sprite variant")
    return _variant(iface.name, warped, None if generic else kind, points)


EXACT_DEFINE = "OW_EXACT"
# Most list entries one fragment of the exact pass walks in its first round (footprint.frag's
# ow_exact_bound): a longer list is finished by later rounds, each with twice the bound of
# the one before (parameterizations.Parameterization.draw).
EXACT_MAX_WALK = 4096
EXACT_IMAGES = (("r32ui", "ow_counts"), ("r32ui", "ow_next"), ("r32ui", "ow_hits"), ("r32ui", "ow_work"))

# Between two rounds of the exact pass: each list's head moves past the entries walked.
ADVANCE_PROGRAM = ComputeInterface(
    name="omniwarp_list_advance",
    compute_file="list_advance.comp",
    uniforms=(Uniform("int", "ow_advance_steps"), Uniform("int", "ow_tile_size")),
    images=(("r32ui", "ow_counts"), ("r32ui", "ow_next"), ("r32ui", "ow_work")),
)


# The exact pass's counting variant (a measurement frame, ShadowPipeline.render(count_work=
# True)): its fragments also count the entries they walk. A define, not a uniform: on
# llvmpipe a branch on a uniform still runs its atomics masked, and those cost ordinary
# frames about a tenth of the pass (issue 26).
EXACT_COUNT_DEFINE = "OW_EXACT_COUNT"
EXACT_COUNT_KEY = "ow_exact_count"  # the uniforms' key that picks the counting variant
_EXACT_VARIANTS: dict[tuple[str, bool], ProgramInterface] = {}  # (footprint variant, count) -> exact variant


def exact_of(base: ProgramInterface, count: bool = False) -> ProgramInterface:
    """The irregular z-buffer's variant of a footprint program, counting its work with
    `count` (one object per variant: backends cache programs by name)."""
    held = _EXACT_VARIANTS.get((base.name, count))
    if held is None:
        # The exact pass sums see-through crossings per sample, so it has no veil.
        defines = {name: value for name, value in base.defines.items() if name != VEIL_DEFINE}
        defines[EXACT_DEFINE] = "1"
        if count:
            defines[EXACT_COUNT_DEFINE] = "1"
        held = _EXACT_VARIANTS[base.name, count] = replace(
            base, name=base.name + ("_exact_count" if count else "_exact"), defines=defines,
            samplers=base.samplers + ("ow_positions", "ow_normals"),
            uniforms=base.uniforms + (Uniform("int", "ow_exact_tile"), Uniform("float", "ow_exact_eps"),
                                      Uniform("int", "ow_exact_bound")),
            images=EXACT_IMAGES,
            varyings=base.varyings + tuple(Varying("vec3", f"v_edge_at{i}", flat=True) for i in range(3)))
    return held


def exact_variant(uniforms: dict, points: bool = False, see_through: bool = False) -> ProgramInterface:
    """The footprint pass of the irregular z-buffer (issue 19): each fragment walks its
    texel's list of samples (link_variant) and marks those whose segment to the light the
    triangle crosses, instead of storing a depth; `see_through` for an object with alpha,
    the counting variant when uniforms[EXACT_COUNT_KEY] is set, and the sized light's
    (exact_soft_of) when uniforms[EXACT_SOFT_KEY] counts its points."""
    base = program_variant(FOOTPRINT_PROGRAM, uniforms, points)
    held = exact_of(alpha_of(base) if see_through else base, bool(uniforms.get(EXACT_COUNT_KEY, 0)))
    if int(uniforms.get(EXACT_SOFT_KEY, 0)) > 0:
        if points:
            raise BackendError("the exact pass of a sized light draws quads: its footprints grow past a point sprite")
        held = exact_soft_of(held)
    return held


# Exact soft shadows of a sized light (lib/exact_soft.glsl, issue 27): the exact pass marks, per
# view sample, which of the light's N points (a square) each triangle blocks, in N bits of the
# sample's words (EXACT_SOFT_WORDS texels of the hits image, rows apart); the shadow test weighs
# the points left. The points go in clusters of EXACT_SOFT_CLUSTER, two to a word, each with
# its bounding box (ow_exact_bounds), which a triangle decides whole where it can.
EXACT_SOFT_DEFINE = "OW_EXACT_SOFT"
EXACT_SOFT_MAX_POINTS = 256
EXACT_SOFT_WORDS = EXACT_SOFT_MAX_POINTS // 32
EXACT_SOFT_CLUSTER = 16
EXACT_SOFT_KEY = "ow_exact_points"  # the uniforms' key: a sized light's point count (0: hard)
SHARED_DEFINES.update(OW_EXACT_SOFT_MAX_POINTS=str(EXACT_SOFT_MAX_POINTS), OW_EXACT_SOFT_CLUSTER=str(EXACT_SOFT_CLUSTER))
EXACT_SOFT_UNIFORMS = (Uniform("vec4", "ow_exact_light"), Uniform("float", "ow_exact_reach"),
                       Uniform("float", "ow_exact_spread"), Uniform("vec2", "ow_exact_spot"),
                       Uniform("mat3", "ow_exact_frame"), Uniform("int", EXACT_SOFT_KEY),
                       Uniform("vec4", "ow_exact_pattern", EXACT_SOFT_MAX_POINTS),
                       Uniform("vec4", "ow_exact_bounds", 2 * EXACT_SOFT_MAX_POINTS // EXACT_SOFT_CLUSTER),
                       Uniform("float", "ow_exact_far"))
_EXACT_SOFT_VARIANTS: dict[str, ProgramInterface] = {}  # program name -> its exact soft variant


def exact_soft_of(base: ProgramInterface) -> ProgramInterface:
    """The exact pass's or the shadow test's variant for a sized light: the footprints grown
    to the light's reach and N light points marked per sample, or the marks weighed into
    the sample's visibility. Hard lights keep the plain programs, unchanged."""
    footprint_pass = base.fragment_file == FOOTPRINT_PROGRAM.fragment_file
    if not (footprint_pass and EXACT_DEFINE in base.defines) and base.fragment_file != SHADOW_TEST_PROGRAM.fragment_file:
        raise BackendError(f"program {base.name!r} has no exact soft variant")
    held = _EXACT_SOFT_VARIANTS.get(base.name)
    if held is None:
        defines = {**base.defines, EXACT_SOFT_DEFINE: "1"}
        if footprint_pass:
            # The walk tests each triangle's edges from the sample: their vertices in one
            # order whichever triangle asks (hi, and the swap in w); and first the sample's
            # angle from the triangle's edges (v_cull).
            varyings = base.varyings + tuple(Varying("vec4", f"v_edge_hi{i}", flat=True) for i in range(3)) + tuple(
                Varying("vec4", f"v_cull{i}", flat=True) for i in range(3))
            images = base.images
        else:
            varyings, images = base.varyings, (("r32ui", "ow_hits"),)
        # Its own name: backends cache programs by name, and soft_of's shadow test is "_soft".
        held = _EXACT_SOFT_VARIANTS[base.name] = replace(
            base, name=base.name + ("_soft" if footprint_pass else "_exact_soft"), defines=defines, uniforms=base.uniforms + EXACT_SOFT_UNIFORMS,
            varyings=varyings, images=images, samplers=base.samplers)
    return held


ALPHA_DEFINE = "OW_ALPHA"
ALPHA_SAMPLERS = ("ow_alpha_image", "ow_alpha_transfer")  # the material's channel and transfer (R32F)
_ALPHA_VARIANTS: dict[str, ProgramInterface] = {}  # footprint variant name -> its see-through variant
# The veil of a map (lib/veil.glsl): the see-through crossings of each atlas texel, written
# by the see-through footprint programs and read by the shadow test's veil variant.
VEIL_DEFINE = "OW_VEIL"
VEIL_IMAGES = (("r32ui", "ow_veil_optical"), ("r32ui", "ow_veil_near"), ("r32ui", "ow_veil_far"))
_VEIL_VARIANTS: dict[str, ProgramInterface] = {}  # shadow-test variant name -> its veil variant


def alpha_of(base: ProgramInterface) -> ProgramInterface:
    """The see-through variant of a footprint or G-buffer program (issue 25): the texel's
    ray meets the triangle, its barycentrics give the UV and the material's alpha
    (lib/alpha.glsl) drops the fragment or, in the exact pass, weighs the crossing; the
    G-buffer drops what the camera sees through. Objects without alpha keep the plain
    programs, unchanged."""
    held = _ALPHA_VARIANTS.get(base.name)
    if held is None:
        varyings = (Varying("vec2", "v_uv"),)
        defines = {**base.defines, ALPHA_DEFINE: "1"}
        images = base.images
        if base.fragment_file == FOOTPRINT_PROGRAM.fragment_file:
            varyings = (Varying("vec4", "v_uv01", flat=True), Varying("vec2", "v_uv2", flat=True)) + varyings
            # A map's depth pass puts the partly transparent crossings in the veil.
            defines[VEIL_DEFINE] = "1"
            images = VEIL_IMAGES
        held = _ALPHA_VARIANTS[base.name] = replace(
            base, name=base.name + "_alpha", defines=defines, images=images,
            samplers=base.samplers + ALPHA_SAMPLERS, uniforms=base.uniforms + (Uniform("int", "ow_alpha_mode"),),
            varyings=base.varyings + varyings)
    return held


# Soft shadows of a sized light (lib/soft.glsl, issue 27): the light's points a shadow test
# reads (core/light_shape.stratified_points, at most SOFT_MAX_POINTS), and the steps of its
# blocker search along each segment to the light.
SOFT_DEFINE = "OW_SOFT"
SOFT_MAX_POINTS = 64
SOFT_MAX_SEARCH = 16
SOFT_SEARCH_STEPS = 3
SOFT_KINDS = {"sphere": 1, "area": 2, "sun_disk": 3}  # ow_soft_kind: how the points lie (lib/soft.glsl)
SHARED_DEFINES.update({"OW_SOFT_MAX_POINTS": str(SOFT_MAX_POINTS), "OW_SOFT_SEARCH_STEPS": str(SOFT_SEARCH_STEPS)})
SOFT_UNIFORMS = (Uniform("vec4", "ow_soft_points", SOFT_MAX_POINTS), Uniform("int", "ow_soft_count"),
                 Uniform("vec4", "ow_soft_search_points", SOFT_MAX_SEARCH), Uniform("int", "ow_soft_search"),
                 Uniform("int", "ow_soft_kind"), Uniform("float", "ow_soft_spread"), Uniform("vec2", "ow_soft_spot"))
_SOFT_VARIANTS: dict[str, ProgramInterface] = {}  # shadow-test variant name -> its soft variant


def soft_of(base: ProgramInterface) -> ProgramInterface:
    """The shadow test's variant for a sized light (lib/soft.glsl): its maps (a point
    light's, a spot's or a sun's) filtered by the light's own points. Hard lights keep the
    plain test, unchanged."""
    if base.fragment_file != SHADOW_TEST_PROGRAM.fragment_file:
        raise BackendError(f"program {base.name!r} has no soft variant")
    held = _SOFT_VARIANTS.get(base.name)
    if held is None:
        held = _SOFT_VARIANTS[base.name] = replace(
            base, name=base.name + "_soft", defines={**base.defines, SOFT_DEFINE: "1"},
            uniforms=base.uniforms + SOFT_UNIFORMS)
    return held


def veil_of(base: ProgramInterface) -> ProgramInterface:
    """The shadow test's variant that also reads the map's veil (lib/veil.glsl): for a
    frame that drew see-through parts. Other frames keep the plain test, unchanged."""
    if base.fragment_file != SHADOW_TEST_PROGRAM.fragment_file:
        raise BackendError(f"program {base.name!r} has no veil variant")
    held = _VEIL_VARIANTS.get(base.name)
    if held is None:
        held = _VEIL_VARIANTS[base.name] = replace(
            base, name=base.name + "_veil", defines={**base.defines, VEIL_DEFINE: "1"}, images=VEIL_IMAGES)
    return held



SCATTER_MODE_DEFINE = "OW_SCATTER_MODE"
SCATTER_MODES = (0, 1, 2)  # after the crop; through the row warps; through the full warp


@functools.cache
def _scatter_variant(mode: int, kind: int | None) -> ComputeInterface:
    defines = {**SCATTER_PROGRAM.defines, SCATTER_MODE_DEFINE: str(mode)}
    name = f"{SCATTER_PROGRAM.name}_mode{mode}"
    if kind is not None:
        defines[FIXED_KIND_DEFINE] = str(kind)
        name += "_" + FIXED_KIND_NAMES[kind]
    return replace(SCATTER_PROGRAM, name=name, defines=defines)


LINK_DEFINE = "OW_LINK"


@functools.cache
def _link_variant(kind: int | None) -> ComputeInterface:
    base = _scatter_variant(2, kind)
    return replace(base, name=base.name.replace("_mode2", "_link"), defines={**base.defines, LINK_DEFINE: "1"},
                   images=base.images + (("r32ui", "ow_next"),))


def link_variant(uniforms: dict) -> ComputeInterface:
    """The scatter through the full warp that links each sample into its texel's list (the
    irregular z-buffer's lists, issue 19) instead of counting: `ow_counts` gets the heads,
    `ow_next` (one texel a sample) the links."""
    kind = int(uniforms.get("ow_layer_kind", -1))
    return _link_variant(kind if kind in FIXED_KIND_NAMES else None)


def scatter_variant(uniforms: dict) -> ComputeInterface:
    """The count-map scatter built for the uniforms' mode (ow_scatter_mode) and kind.

    The analysis runs three scatters a frame over every view sample; with the mode and
    the kind as constants, the other modes' warp lookups and the other kinds'
    projections compile out instead of running masked.
    """
    mode = int(uniforms.get("ow_scatter_mode", 0))
    if mode not in SCATTER_MODES:
        raise BackendError(f"unknown scatter mode {mode}")
    kind = int(uniforms.get("ow_layer_kind", -1))
    return _scatter_variant(mode, kind if kind in FIXED_KIND_NAMES else None)


DEPTH_PLAIN_PROGRAM = _variant(DEPTH_PROGRAM.name, False, None)
SHADOW_TEST_PLAIN_PROGRAM = _variant(SHADOW_TEST_PROGRAM.name, False, None)
VARIANT_PROGRAMS = tuple(_variant(base, warped, kind) for base in _VARIANT_BASES for warped in (True, False)
                         for kind in (None, *FIXED_KIND_NAMES)) + tuple(
    _variant(FOOTPRINT_PROGRAM.name, warped, kind, True) for warped in (True, False) for kind in FIXED_KIND_NAMES)


_FOOTPRINTS = tuple({iface.name: iface for iface in (FOOTPRINT_PROGRAM, *VARIANT_PROGRAMS)
                     if iface.fragment_file == FOOTPRINT_PROGRAM.fragment_file}.values())
EXACT_PROGRAMS = tuple(exact_of(iface, count) for iface in _FOOTPRINTS for count in (False, True))
ALPHA_PROGRAMS = tuple(alpha_of(iface) for iface in _FOOTPRINTS) + tuple(
    exact_of(alpha_of(iface), count) for iface in _FOOTPRINTS for count in (False, True))
GBUFFER_ALPHA_PROGRAM = alpha_of(GBUFFER_PROGRAM)
VEIL_PROGRAMS = tuple(veil_of(iface) for iface in VARIANT_PROGRAMS
                      if iface.fragment_file == SHADOW_TEST_PROGRAM.fragment_file)
SOFT_PROGRAMS = tuple(soft_of(iface) for iface in (*VARIANT_PROGRAMS, *VEIL_PROGRAMS)
                      if iface.fragment_file == SHADOW_TEST_PROGRAM.fragment_file)
EXACT_SOFT_PROGRAMS = tuple(exact_soft_of(iface) for iface in (*EXACT_PROGRAMS, *ALPHA_PROGRAMS, *VARIANT_PROGRAMS)
                            if (EXACT_DEFINE in iface.defines and POINTS_DEFINE not in iface.defines)
                            or iface.fragment_file == SHADOW_TEST_PROGRAM.fragment_file)
PROGRAMS = (*VARIANT_PROGRAMS, *EXACT_PROGRAMS, *ALPHA_PROGRAMS, *VEIL_PROGRAMS, *SOFT_PROGRAMS, *EXACT_SOFT_PROGRAMS, GBUFFER_ALPHA_PROGRAM, RAY_TABLE_PROGRAM, GBUFFER_PROGRAM, GBUFFER_SAMPLES_PROGRAM, PREVIEW_PROGRAM, OVERLAY_PROGRAM, EDGE_PROGRAM)
COMPUTE_PROGRAMS = (SCATTER_PROGRAM, SAMPLE_STATS_PROGRAM, BARRIER_PROGRAM, ADVANCE_PROGRAM, *(_scatter_variant(mode, kind) for mode in SCATTER_MODES
                                                             for kind in (None, *FIXED_KIND_NAMES)),
                    *(_link_variant(kind) for kind in (None, *FIXED_KIND_NAMES)))


def program_defines(iface: "ProgramInterface | ComputeInterface") -> dict[str, str]:
    """Every #define of a program: the shared GPU constants, then its own."""
    return {**SHARED_DEFINES, **iface.defines}
