"""Variants of the programs: the same interface with defines (and the declarations those
defines read), each with its own name, because backends cache compiled programs by name.

Every variant comes from one helper, `derive`, and lives in one cache keyed by its name.

llvmpipe (and other SIMD software rasterisers) runs a branch on a uniform with masked
lanes, so code a frame never takes still costs every fragment:
- `OW_NO_WARP` removes the warp code (the binary-search loop of the inverse warp cost
  every plain depth fragment ~6x its real work); `lib/mapping.glsl` keeps the crop.
- `OW_FIXED_KIND` makes the layer kind (paraboloid or cube) a compile-time constant, so
  the other kinds' projections, the unfold's transcendentals and the projective (spot,
  sun) paths compile out. Measured on courtyard's plain cube faces at 1024: 3.6-4.4 ms
  a face with the generic program, 2.2-2.9 ms with this variant, about 1 ms with a
  trivial fragment stage.
"""
from __future__ import annotations

from dataclasses import replace
from typing import TypeVar

from ...core import projection
from ...core.errors import BackendError
from .constants import (GRID_LIGHT_POINTS, GRID_MAX, MEDIA_POINTS, EXACT_SOFT_CLUSTER, EXACT_SOFT_MAX_POINTS, NO_SPLIT, SCATTER_MODE_CODES, SCATTER_MODES,
                        SOFT_MAX_POINTS, SOFT_MAX_SEARCH, WARP_STEPS)
from .interfaces import (DEPTH_PROGRAM, FOOTPRINT_PROGRAM, SCATTER_PROGRAM, SHADOW_TEST_PROGRAM, WARP_BUILD_PROGRAM,
                         ComputeInterface, ProgramInterface, Uniform, Varying, uniform_list)

Interface = TypeVar("Interface", ProgramInterface, ComputeInterface)

NO_WARP_DEFINE = "OW_NO_WARP"
FIXED_KIND_DEFINE = "OW_FIXED_KIND"
POINTS_DEFINE = "OW_POINTS"  # the footprint pass as point sprites
EXACT_DEFINE = "OW_EXACT"
# The exact pass's counting variant (a measurement frame, frame.Measure(count_work=True)):
# its fragments also count the entries they walk. A define, not a uniform: on
# llvmpipe a branch on a uniform still runs its atomics masked, and those cost ordinary
# frames about a tenth of the pass.
EXACT_COUNT_DEFINE = "OW_EXACT_COUNT"
EXACT_COUNT_KEY = "ow_exact_count"  # the uniforms' key that picks the counting variant
# The density grids' textures, carried in the shadow test's uniforms to its draw.
GRID_SAMPLERS_KEY = "ow_grid_samplers"
# Keys a frame's uniform dictionaries carry that are no uniform: they pick a variant or
# its textures, and a device skips them.
SELECTOR_KEYS = frozenset({EXACT_COUNT_KEY, GRID_SAMPLERS_KEY})
EXACT_SOFT_DEFINE = "OW_EXACT_SOFT"
EXACT_SOFT_KEY = "ow_exact_points"  # the uniforms' key: a sized light's point count (0: hard)
ALPHA_DEFINE = "OW_ALPHA"
# A part of pieces (hair, points; resident.py): the footprint pass boxes and hits swept
# spheres instead of triangles (lib/footprint_piece.glsl, lib/exact_piece.glsl).
PIECES_DEFINE = "OW_PIECES"
# The veil of a map (lib/veil.glsl): the see-through crossings of each atlas texel, written
# by the see-through footprint programs and read by the shadow test's veil variant.
VEIL_DEFINE = "OW_VEIL"
# A part of a homogeneous medium (lib/media.glsl): the exact pass sums its crossings
# per sample (ow_media), the maps per texel (the haze, read by the shadow test's haze variant).
MEDIUM_DEFINE = "OW_MEDIUM"
HAZE_DEFINE = "OW_HAZE"
# Density grids (lib/grids.glsl): the shadow test marches each sample's segment through them.
GRIDS_DEFINE = "OW_GRIDS"
SOFT_DEFINE = "OW_SOFT"
SCATTER_MODE_DEFINE = "OW_SCATTER_MODE"
LINK_DEFINE = "OW_LINK"
WARP_STEP_DEFINE = "OW_STEP"  # the one step a warp_build.comp program runs

# Layer kinds with a fixed-kind variant; the values mirror core.projection's
# PARABOLOID and CUBE (lib/projection.glsl's OW_KIND_PARABOLOID, OW_KIND_CUBE).
FIXED_KIND_NAMES = {projection.PARABOLOID: "paraboloid", projection.CUBE: "cube"}
# The footprint pass's three entry points: the depth pass, its see-through variant, the exact pass.
FOOTPRINT_ALPHA_FILE = "footprint_alpha.frag"
FOOTPRINT_EXACT_FILE = "footprint_exact.frag"
FOOTPRINT_MEDIUM_FILE = "footprint_medium.frag"
FOOTPRINT_FILES = (FOOTPRINT_PROGRAM.fragment_file, FOOTPRINT_ALPHA_FILE, FOOTPRINT_EXACT_FILE, FOOTPRINT_MEDIUM_FILE)

EXACT_IMAGES = (("r32ui", "ow_counts"), ("r32ui", "ow_next"), ("r32ui", "ow_hits"), ("r32ui", "ow_work"))
ALPHA_SAMPLERS = ("ow_alpha_image", "ow_alpha_transfer")  # the material's channel and transfer (R32F)
VEIL_IMAGES = (("r32ui", "ow_veil_optical"), ("r32ui", "ow_veil_near"), ("r32ui", "ow_veil_far"))
MEDIA_IMAGE = ("r32ui", "ow_media")  # the exact pass's optical depths, three rows of words a sample
HAZE_IMAGES = (("r32ui", "ow_haze_r"), ("r32ui", "ow_haze_g"), ("r32ui", "ow_haze_b"), ("r32ui", "ow_haze_near"),
               ("r32ui", "ow_haze_far"))
MEDIA_TEST_UNIFORMS = uniform_list("vec3 ow_media_light", "float ow_media_scale", "float ow_media_offset")
# The light points a sample keeps optical depths for (1: a hard light's) and their indices in
# the exact pass's pattern (passes/media.py's share_points), four a vec4.
MEDIA_SHARE_UNIFORMS = uniform_list("int ow_media_points", "int ow_media_across", "float ow_media_scale",
                                    f"vec4 ow_media_index[{MEDIA_POINTS // 4}]")
# Programs that hold the exact pass's words and MEDIA_SHARE_UNIFORMS (lib/media.glsl's readers).
MEDIA_WORDS_DEFINE = "OW_MEDIA_WORDS"
EXACT_SOFT_UNIFORMS = uniform_list("vec4 ow_exact_light", "float ow_exact_reach", "float ow_exact_spread",
                                   "vec2 ow_exact_spot", "mat3 ow_exact_frame", f"int {EXACT_SOFT_KEY}",
                                   f"vec4 ow_exact_pattern[{EXACT_SOFT_MAX_POINTS}]",
                                   f"vec4 ow_exact_bounds[{2 * EXACT_SOFT_MAX_POINTS // EXACT_SOFT_CLUSTER}]",
                                   "float ow_exact_far")
SOFT_UNIFORMS = uniform_list(f"vec4 ow_soft_points[{SOFT_MAX_POINTS}]", "int ow_soft_count",
                             f"vec4 ow_soft_search_points[{SOFT_MAX_SEARCH}]", "int ow_soft_search",
                             "int ow_soft_kind", "float ow_soft_spread", "vec2 ow_soft_spot")

_VARIANTS: dict[str, ProgramInterface | ComputeInterface] = {}  # the one cache: variant name -> interface


def derive(base: Interface, name: str, *, defines: dict[str, str] | None = None, drop: tuple[str, ...] = (),
           uniforms: tuple[Uniform, ...] = (), samplers: tuple[str, ...] = (), varyings: tuple[Varying, ...] = (),
           images: tuple[tuple[str, str], ...] | None = None, fragment_file: str | None = None) -> Interface:
    """The variant `name` of `base`: its defines less `drop` plus `defines`, and the
    uniforms, samplers and varyings appended; `images` and `fragment_file` replace base's.
    Built once: every later call with that name returns the same object."""
    held = _VARIANTS.get(name)
    if held is None:
        merged = {key: value for key, value in base.defines.items() if key not in drop}
        merged.update(defines or {})
        changes: dict = {"name": name, "defines": merged, "uniforms": base.uniforms + uniforms,
                         "samplers": base.samplers + samplers}
        if varyings:
            changes["varyings"] = base.varyings + varyings
        if images is not None:
            changes["images"] = images
        if fragment_file is not None:
            changes["fragment_file"] = fragment_file
        held = _VARIANTS[name] = replace(base, **changes)
    return held


def is_footprint(iface: ProgramInterface | ComputeInterface) -> bool:
    return getattr(iface, "fragment_file", None) in FOOTPRINT_FILES


def is_shadow_test(iface: ProgramInterface | ComputeInterface) -> bool:
    return getattr(iface, "fragment_file", None) == SHADOW_TEST_PROGRAM.fragment_file


VARIANT_BASES = {DEPTH_PROGRAM.name: DEPTH_PROGRAM, SHADOW_TEST_PROGRAM.name: SHADOW_TEST_PROGRAM,
                  FOOTPRINT_PROGRAM.name: FOOTPRINT_PROGRAM}


def base_variant(base_name: str, warped: bool, kind: int | None, points: bool = False) -> ProgramInterface:
    """A depth, footprint or shadow-test program without the warp, fixed to a kind, or as
    point sprites (the base itself when none of those)."""
    base = VARIANT_BASES[base_name]
    if warped and kind is None and not points:
        return base
    defines, name = {}, base.name
    if points:
        defines[POINTS_DEFINE] = "1"
        name += "_points"
    if not warped:
        defines[NO_WARP_DEFINE] = "1"
        name += "_plain"
    if kind is not None:
        defines[FIXED_KIND_DEFINE] = str(kind)
        name += "_" + FIXED_KIND_NAMES[kind]
    return derive(base, name, defines=defines)


def program_variant(iface: ProgramInterface, uniforms: dict, points: bool = False) -> ProgramInterface:
    """The variant of the depth or shadow-test program that `uniforms` need.

    With the warp only when they set one (ow_warp_size > 0), and fixed to the layer
    kind when that is a paraboloid or a cube face and the frame is neither projective
    nor an unfold (which keep the generic program). Variants are built once and cached;
    each has its own name, because backends cache compiled programs by name.
    """
    if iface.name not in VARIANT_BASES:
        raise BackendError(f"program {iface.name!r} has no variants")
    warped = int(uniforms.get("ow_warp_size", 0)) > 0
    kind = int(uniforms.get("ow_layer_kind", -1))
    generic = (kind not in FIXED_KIND_NAMES or int(uniforms.get("ow_projective", 0)) != 0
               or int(uniforms.get("ow_unfold_split", NO_SPLIT)) > NO_SPLIT)
    if points and iface.name != FOOTPRINT_PROGRAM.name:
        raise BackendError(f"program {iface.name!r} has no point-sprite variant")
    return base_variant(iface.name, warped, None if generic else kind, points)


def exact_of(base: ProgramInterface, count: bool = False) -> ProgramInterface:
    """The irregular z-buffer's variant of a footprint program (footprint_exact.frag),
    counting its work with `count`. The exact pass sums see-through crossings per sample,
    so it has no veil."""
    defines = {EXACT_DEFINE: "1", **({EXACT_COUNT_DEFINE: "1"} if count else {})}
    return derive(base, base.name + ("_exact_count" if count else "_exact"), defines=defines, drop=(VEIL_DEFINE,),
                  samplers=("ow_positions", "ow_normals"),
                  uniforms=uniform_list("int ow_exact_tile", "float ow_exact_eps", "int ow_exact_bound"),
                  images=EXACT_IMAGES, fragment_file=FOOTPRINT_EXACT_FILE,
                  varyings=(*(Varying("vec3", f"v_edge_at{i}", flat=True) for i in range(3)),
                            Varying("float", "v_overlapped", flat=True)))


def exact_variant(uniforms: dict, points: bool = False, see_through: bool = False,
                  pieces: bool = False, medium: bool = False) -> ProgramInterface:
    """The footprint pass of the irregular z-buffer: each fragment walks its
    texel's list of samples (link_variant) and marks those whose segment to the light the
    triangle crosses, instead of storing a depth; `see_through` for an object with alpha,
    `pieces` for a part of hair or points, the counting variant when
    uniforms[EXACT_COUNT_KEY] is set, and the sized light's (exact_soft_of) when
    uniforms[EXACT_SOFT_KEY] counts its points; `medium` for a part of a medium (medium_of)."""
    base = program_variant(FOOTPRINT_PROGRAM, uniforms, points)
    base = pieces_of(base) if pieces else (alpha_of(base) if see_through else base)
    held = exact_of(base, bool(uniforms.get(EXACT_COUNT_KEY, 0)))
    if int(uniforms.get(EXACT_SOFT_KEY, 0)) > 0:
        if points:
            raise BackendError("the exact pass of a sized light draws quads: its footprints grow past a point sprite")
        held = exact_soft_of(held)
    return medium_of(held) if medium else held


def exact_soft_of(base: ProgramInterface) -> ProgramInterface:
    """The exact pass's or the shadow test's variant for a sized light (lib/exact_soft.glsl):
    the footprints grown to the light's reach and N light points marked per
    sample, or the marks weighed into the sample's visibility. Hard lights keep the plain
    programs, unchanged."""
    footprint_pass = is_footprint(base) and EXACT_DEFINE in base.defines
    if not footprint_pass and not is_shadow_test(base):
        raise BackendError(f"program {base.name!r} has no exact soft variant")
    if footprint_pass:
        # The walk tests each triangle's edges from the sample: their vertices in one order
        # whichever triangle asks (hi, and the swap in w); and first the sample's angle
        # from the triangle's edges (v_cull).
        varyings = tuple(Varying("vec4", f"v_{what}{i}", flat=True) for what in ("edge_hi", "cull") for i in range(3))
        images = None
    else:
        varyings, images = (), (("r32ui", "ow_hits"),)
    # Its own name: backends cache programs by name, and soft_of's shadow test is "_soft".
    return derive(base, base.name + ("_soft" if footprint_pass else "_exact_soft"), defines={EXACT_SOFT_DEFINE: "1"},
                  uniforms=EXACT_SOFT_UNIFORMS, varyings=varyings, images=images)


EXACT_SOFT_MEDIA_DEFINE = "OW_EXACT_SOFT_MEDIA"


def exact_soft_media_of(base: ProgramInterface) -> ProgramInterface:
    """The exact soft shadow test's variant for a frame whose exact pass summed media per
    light point (lib/exact_soft_medium.glsl): it weighs them with the surfaces' weights and
    marks (shadow_test.frag), so readers and the resolve leave them (passes/media.py's
    SampleMedia.weighed)."""
    if not is_shadow_test(base) or EXACT_SOFT_DEFINE not in base.defines:
        raise BackendError(f"program {base.name!r} has no exact soft media variant")
    return derive(base, base.name + "_media", defines={EXACT_SOFT_MEDIA_DEFINE: "1", MEDIA_WORDS_DEFINE: "1"},
                  uniforms=uniform_list("vec3 ow_media_light") + MEDIA_SHARE_UNIFORMS,
                  images=base.images + (MEDIA_IMAGE,))


def alpha_of(base: ProgramInterface) -> ProgramInterface:
    """The see-through variant of a footprint or G-buffer program: the texel's
    ray meets the triangle, its barycentrics give the UV and the material's alpha
    (lib/alpha.glsl) drops the fragment or, in the exact pass (exact_of of this variant),
    weighs the crossing; the G-buffer drops what the camera sees through. Objects without
    alpha keep the plain programs, unchanged."""
    uv = (Varying("vec2", "v_uv"),)
    alpha = {"samplers": ALPHA_SAMPLERS, "uniforms": uniform_list("int ow_alpha_mode")}
    if not is_footprint(base):
        return derive(base, base.name + "_alpha", defines={ALPHA_DEFINE: "1"}, varyings=uv, **alpha)
    # A map's depth pass (footprint_alpha.frag) puts the partly transparent crossings in the veil.
    return derive(base, base.name + "_alpha", defines={ALPHA_DEFINE: "1", VEIL_DEFINE: "1"}, images=VEIL_IMAGES,
                  varyings=(Varying("vec4", "v_uv01", flat=True), Varying("vec2", "v_uv2", flat=True)) + uv,
                  fragment_file=FOOTPRINT_ALPHA_FILE, **alpha)


def pieces_of(base: ProgramInterface) -> ProgramInterface:
    """The footprint pass's variant for a part of pieces: each piece (a sphere
    swept from a to b) over the box of its bounding box's image, its fragments finding
    their ray's entry or walking their samples' segments against it. Parts of triangles
    keep the plain programs, unchanged."""
    if not is_footprint(base):
        raise BackendError(f"program {base.name!r} has no pieces variant")
    return derive(base, base.name + "_pieces", defines={PIECES_DEFINE: "1"},
                  varyings=(Varying("vec4", "v_piece_a", flat=True), Varying("vec4", "v_piece_b", flat=True),
                            Varying("vec3", "v_piece_curve", flat=True), Varying("vec4", "v_piece_cut_a", flat=True),
                            Varying("vec4", "v_piece_cut_b", flat=True), Varying("vec3", "v_piece_ta", flat=True),
                            Varying("vec3", "v_piece_tb", flat=True)))


def medium_of(base: ProgramInterface) -> ProgramInterface:
    """The footprint pass's variant for a part of a homogeneous medium
    (lib/media.glsl): in the exact pass (a base from exact_of) each listed sample's segment
    adds its signed crossing to the sample's optical depths (ow_media); in the maps each
    texel's ray adds its crossing to the texel's haze. Its triangles store no depth."""
    if not is_footprint(base):
        raise BackendError(f"program {base.name!r} has no medium variant")
    sigma = uniform_list("vec3 ow_medium_sigma")
    if EXACT_DEFINE in base.defines:
        # ow_media_points: the light points a sample keeps optical depths for (1: hard).
        return derive(base, base.name + "_medium", defines={MEDIUM_DEFINE: "1", MEDIA_WORDS_DEFINE: "1"},
                      uniforms=sigma + MEDIA_SHARE_UNIFORMS, images=base.images + (MEDIA_IMAGE,))
    return derive(base, base.name + "_medium", defines={MEDIUM_DEFINE: "1", HAZE_DEFINE: "1"},
                  uniforms=sigma + uniform_list("float ow_media_offset"), images=HAZE_IMAGES,
                  fragment_file=FOOTPRINT_MEDIUM_FILE)


def haze_of(base: ProgramInterface) -> ProgramInterface:
    """The shadow test's variant that also reads the maps' haze (lib/media.glsl): for a
    frame that drew media. Other frames keep their test, unchanged."""
    if not is_shadow_test(base):
        raise BackendError(f"program {base.name!r} has no haze variant")
    return derive(base, base.name + "_haze", defines={HAZE_DEFINE: "1"}, uniforms=MEDIA_TEST_UNIFORMS,
                  images=base.images + HAZE_IMAGES)


GRID_SAMPLERS = tuple(f"ow_grid{g}" for g in range(GRID_MAX))
GRID_UNIFORMS = uniform_list("int ow_grid_count", f"mat4 ow_grid_to_index[{GRID_MAX}]", f"vec4 ow_grid_size[{GRID_MAX}]",
                             f"vec4 ow_grid_sigma[{GRID_MAX}]", "float ow_grid_reach", "int ow_grid_light_kind",
                             "int ow_grid_light_count", f"vec4 ow_grid_light_points[{GRID_LIGHT_POINTS}]",
                             "mat3 ow_grid_light_frame")


def grids_of(base: ProgramInterface) -> ProgramInterface:
    """The shadow test's variant that marches each sample's segment to the light through
    the frame's density grids (lib/grids.glsl), for any method. Frames without
    grids keep their test, unchanged."""
    if not is_shadow_test(base):
        raise BackendError(f"program {base.name!r} has no grids variant")
    return derive(base, base.name + "_grids", defines={GRIDS_DEFINE: "1"}, uniforms=GRID_UNIFORMS,
                  samplers=GRID_SAMPLERS)


def soft_of(base: ProgramInterface) -> ProgramInterface:
    """The shadow test's variant for a sized light (lib/soft.glsl): its maps (a point
    light's, a spot's or a sun's) filtered by the light's own points. Hard lights keep the
    plain test, unchanged."""
    if not is_shadow_test(base):
        raise BackendError(f"program {base.name!r} has no soft variant")
    return derive(base, base.name + "_soft", defines={SOFT_DEFINE: "1"}, uniforms=SOFT_UNIFORMS)


def veil_of(base: ProgramInterface) -> ProgramInterface:
    """The shadow test's variant that also reads the map's veil (lib/veil.glsl): for a
    frame that drew see-through parts. Other frames keep the plain test, unchanged."""
    if not is_shadow_test(base):
        raise BackendError(f"program {base.name!r} has no veil variant")
    return derive(base, base.name + "_veil", defines={VEIL_DEFINE: "1"}, images=VEIL_IMAGES)


def scatter_mode_variant(mode: int, kind: int | None) -> ComputeInterface:
    defines = {SCATTER_MODE_DEFINE: str(mode)}
    name = f"{SCATTER_PROGRAM.name}_mode{mode}"
    if kind is not None:
        defines[FIXED_KIND_DEFINE] = str(kind)
        name += "_" + FIXED_KIND_NAMES[kind]
    return derive(SCATTER_PROGRAM, name, defines=defines)


def warp_step_variant(step: str) -> ComputeInterface:
    """The GPU warp's step `step` (constants.WARP_STEPS) as a program of its own: the other
    steps compile out, so a simple step carries none of the smoothing's private arrays
    (a software rasteriser allocates them for every invocation)."""
    return derive(WARP_BUILD_PROGRAM, f"{WARP_BUILD_PROGRAM.name}_{step}",
                  defines={WARP_STEP_DEFINE: str(WARP_STEPS[step])})


def link_kind_variant(kind: int | None) -> ComputeInterface:
    base = scatter_mode_variant(SCATTER_MODE_CODES["warp"], kind)
    return derive(base, base.name.replace("_mode2", "_link"), defines={LINK_DEFINE: "1"},
                  images=base.images + (("r32ui", "ow_next"),))


def _fixed_kind(uniforms: dict) -> int | None:
    kind = int(uniforms.get("ow_layer_kind", -1))
    return kind if kind in FIXED_KIND_NAMES else None


def link_variant(uniforms: dict) -> ComputeInterface:
    """The scatter through the full warp that links each sample into its texel's list (the
    irregular z-buffer's lists) instead of counting: `ow_counts` gets the heads,
    `ow_next` (one texel a sample) the links."""
    return link_kind_variant(_fixed_kind(uniforms))


def scatter_variant(uniforms: dict) -> ComputeInterface:
    """The count-map scatter built for the uniforms' mode (ow_scatter_mode) and kind.

    The analysis runs three scatters a frame over every view sample; with the mode and
    the kind as constants, the other modes' warp lookups and the other kinds'
    projections compile out instead of running masked.
    """
    mode = int(uniforms.get("ow_scatter_mode", 0))
    if mode not in SCATTER_MODES:
        raise BackendError(f"unknown scatter mode {mode}")
    return scatter_mode_variant(mode, _fixed_kind(uniforms))
