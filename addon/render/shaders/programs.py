"""Every program the backends build: the base interfaces and each variant a frame can ask
for, so that tests (and Blender's create-infos) compile all of them up front."""
from __future__ import annotations

from .constants import SCATTER_MODES, WARP_STEPS
from .interfaces import (ADVANCE_PROGRAM, ComputeInterface, uniform_list, BARRIER_PROGRAM, DEPTH_PROGRAM, EDGE_PROGRAM, FOOTPRINT_PROGRAM,
                         GBUFFER_PROGRAM, GBUFFER_SAMPLES_PROGRAM, OVERLAY_PROGRAM, PREVIEW_PROGRAM,
                         RAY_TABLE_PROGRAM, RESOLVE_PROGRAM, SAMPLE_STATS_PROGRAM, SCATTER_PROGRAM,
                         SHADOW_TEST_PROGRAM)
from .variants import (VARIANT_BASES, EXACT_DEFINE, EXACT_SOFT_UNIFORMS, SELECTOR_KEYS, FIXED_KIND_NAMES, POINTS_DEFINE, is_footprint,
                       is_shadow_test, link_kind_variant, scatter_mode_variant, base_variant, alpha_of, exact_of,
                       exact_soft_of, exact_soft_media_of, grids_of, haze_of, medium_of, pieces_of, soft_of, veil_of,
                       warp_step_variant)

# The exact pass of a sized light by segments through a tree (passes/segments.py): the
# light's points as the exact soft pass places them, the tree's two tables, the marks
# (the lists' hits image), each sample's place between turns, and the unfinished count.
SEGMENTS_PROGRAM = ComputeInterface(
    name="omniwarp_exact_segments",
    compute_file="exact_segments.comp",
    uniforms=EXACT_SOFT_UNIFORMS + uniform_list("int ow_tree_leaves", "float ow_exact_eps", "int ow_budget",
                                                "float ow_sun_reach"),
    samplers=("ow_positions", "ow_normals", "ow_tree_boxes", "ow_tree_tris"),
    images=(("r32ui", "ow_hits"), ("r32ui", "ow_walk"), ("r32ui", "ow_work")),
)

DEPTH_PLAIN_PROGRAM = base_variant(DEPTH_PROGRAM.name, False, None)
SHADOW_TEST_PLAIN_PROGRAM = base_variant(SHADOW_TEST_PROGRAM.name, False, None)
VARIANT_PROGRAMS = tuple(base_variant(base, warped, kind) for base in VARIANT_BASES for warped in (True, False)
                         for kind in (None, *FIXED_KIND_NAMES)) + tuple(
    base_variant(FOOTPRINT_PROGRAM.name, warped, kind, True) for warped in (True, False) for kind in FIXED_KIND_NAMES)

_FOOTPRINTS = tuple({iface.name: iface for iface in (FOOTPRINT_PROGRAM, *VARIANT_PROGRAMS)
                     if is_footprint(iface)}.values())
_SHADOW_TESTS = tuple(iface for iface in VARIANT_PROGRAMS if is_shadow_test(iface))
EXACT_PROGRAMS = tuple(exact_of(iface, count) for iface in _FOOTPRINTS for count in (False, True))
ALPHA_PROGRAMS = tuple(alpha_of(iface) for iface in _FOOTPRINTS) + tuple(
    exact_of(alpha_of(iface), count) for iface in _FOOTPRINTS for count in (False, True))
GBUFFER_ALPHA_PROGRAM = alpha_of(GBUFFER_PROGRAM)
PIECES_PROGRAMS = tuple(pieces_of(iface) for iface in _FOOTPRINTS) + tuple(
    exact_of(pieces_of(iface), count) for iface in _FOOTPRINTS for count in (False, True))
VEIL_PROGRAMS = tuple(veil_of(iface) for iface in _SHADOW_TESTS)
SOFT_PROGRAMS = tuple(soft_of(iface) for iface in (*_SHADOW_TESTS, *VEIL_PROGRAMS))
EXACT_SOFT_PROGRAMS = tuple(exact_soft_of(iface) for iface in (*EXACT_PROGRAMS, *ALPHA_PROGRAMS, *PIECES_PROGRAMS,
                                                              *VARIANT_PROGRAMS)
                            if (EXACT_DEFINE in iface.defines and POINTS_DEFINE not in iface.defines)
                            or is_shadow_test(iface))
# Media: the exact pass's and the maps' medium variants, the haze's shadow tests,
# and the exact soft shadow tests that weigh the media per light point.
MEDIA_PROGRAMS = tuple(medium_of(exact_of(iface, count)) for iface in _FOOTPRINTS for count in (False, True)) + tuple(
    medium_of(exact_soft_of(exact_of(iface, count))) for iface in _FOOTPRINTS for count in (False, True)
    if POINTS_DEFINE not in iface.defines) + tuple(
    medium_of(iface) for iface in _FOOTPRINTS) + tuple(haze_of(iface) for iface in (*_SHADOW_TESTS, *VEIL_PROGRAMS,
                                                                                  *SOFT_PROGRAMS)) + tuple(
    exact_soft_media_of(iface) for iface in EXACT_SOFT_PROGRAMS if is_shadow_test(iface))
# Density grids: the shadow test of every plain, veil, haze, soft and exact soft variant.
GRID_PROGRAMS = tuple(grids_of(iface) for iface in (*_SHADOW_TESTS, *VEIL_PROGRAMS, *SOFT_PROGRAMS,
                                                    *(i for i in MEDIA_PROGRAMS if is_shadow_test(i)),
                                                    *(i for i in EXACT_SOFT_PROGRAMS if is_shadow_test(i))))
PROGRAMS = (*VARIANT_PROGRAMS, *MEDIA_PROGRAMS, *GRID_PROGRAMS, *EXACT_PROGRAMS, *ALPHA_PROGRAMS, *PIECES_PROGRAMS, *VEIL_PROGRAMS, *SOFT_PROGRAMS,
            *EXACT_SOFT_PROGRAMS, GBUFFER_ALPHA_PROGRAM, RAY_TABLE_PROGRAM, GBUFFER_PROGRAM,
            GBUFFER_SAMPLES_PROGRAM, PREVIEW_PROGRAM, OVERLAY_PROGRAM, EDGE_PROGRAM, RESOLVE_PROGRAM)
COMPUTE_PROGRAMS = (SCATTER_PROGRAM, SAMPLE_STATS_PROGRAM, BARRIER_PROGRAM, ADVANCE_PROGRAM, SEGMENTS_PROGRAM,
                    *(warp_step_variant(step) for step in WARP_STEPS),
                    *(scatter_mode_variant(mode, kind) for mode in SCATTER_MODES for kind in (None, *FIXED_KIND_NAMES)),
                    *(link_kind_variant(kind) for kind in (None, *FIXED_KIND_NAMES)))

# Every uniform name some program declares, and the selector keys: a name outside them is a
# mistake (a typo, a renamed uniform), which a device refuses (uniform_block.BlockState)
# instead of dropping.
UNIFORM_NAMES = frozenset(uniform.name for iface in (*PROGRAMS, *COMPUTE_PROGRAMS, DEPTH_PROGRAM, FOOTPRINT_PROGRAM,
                                                     SHADOW_TEST_PROGRAM, SCATTER_PROGRAM)
                          for uniform in iface.uniforms)
KNOWN_KEYS = UNIFORM_NAMES | SELECTOR_KEYS
