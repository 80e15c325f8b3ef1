"""The shaders: the bodies in `gpu_shaders/` are written once, for both backends.

- `loader`: reads a stage file and inlines its `#include "lib/*.glsl"`s (an include path
  lets a test load a small shader of its own over the shipped `lib/`);
- `constants`: every GPU constant, and `SHARED_DEFINES`, which every program's header
  defines (the codes a uniform carries among them, so no shader compares with a bare number);
- `interfaces`: `ProgramInterface`, `ComputeInterface` and the base programs, composed from
  shared uniform groups;
- `variants`: the variants (no warp, a fixed kind, point sprites, exact, see-through, pieces, veil,
  soft, exact soft, the scatter modes and the list links), from one helper and one cache;
- `programs`: every program a backend may build.

The names other modules import from `shaders` are all here.
"""
from __future__ import annotations

from .constants import (ALPHA_INTERPOLATIONS, CODES, EDGE_PASSES, EXACT_MAX_WALK, EXACT_SOFT_CLUSTER,
                        EXACT_SOFT_MAX_POINTS, EXACT_SOFT_WORDS, EXTENSIONS, FOOTPRINT_VERTICES, INTERPOLATIONS,
                        LAYER_KINDS, LIGHT_KINDS, MAX_POINT_SIZE, NO_SPLIT, NO_SPOT, NO_SPREAD, NO_TILE, OUTLINES,
                        OVERLAY_MODES, PARAM_CODES, REGION_PLANES, SAMPLE_FLAGS, SCATTER_MODE_CODES, SCATTER_MODES,
                        SHARED_DEFINES, SLOTS, SOFT_MAX_POINTS, SOFT_MAX_SEARCH, SOFT_SEARCH_STEPS, STATS_PASSES,
                        VERTEX_TEXTURE_WIDTH, WARP_FAMILIES, WARP_STEPS, WORK_BOX, WORK_CUT, WORK_ENTRIES,
                        WORK_FRAGMENTS, WORK_TEXELS, Codes)
from .interfaces import (ADVANCE_PROGRAM, BARRIER_PROGRAM, DEPTH_PROGRAM, EDGE_PROGRAM, FOOTPRINT_PROGRAM,
                         GBUFFER_PROGRAM, GBUFFER_SAMPLES_PROGRAM, OVERLAY_PROGRAM, PREVIEW_PROGRAM,
                         RAY_TABLE_PROGRAM, RESOLVE_PROGRAM, SAMPLE_STATS_PROGRAM, SCATTER_PROGRAM,
                         SHADOW_TEST_PROGRAM, WARP_BUILD_PROGRAM, ComputeInterface, ProgramInterface, Uniform, Varying,
                         image_type, program_defines)
from .loader import GLSL_VERSION, SHADER_DIR, expand_source, load_source
from .programs import (ALPHA_PROGRAMS, COMPUTE_PROGRAMS, DEPTH_PLAIN_PROGRAM, EXACT_PROGRAMS, EXACT_SOFT_PROGRAMS,
                       GBUFFER_ALPHA_PROGRAM, MEDIA_PROGRAMS, PIECES_PROGRAMS, PROGRAMS, SEGMENTS_PROGRAM, SHADOW_TEST_PLAIN_PROGRAM, SOFT_PROGRAMS, VARIANT_PROGRAMS,
                       VEIL_PROGRAMS)
from .variants import (ALPHA_DEFINE, ALPHA_SAMPLERS, EXACT_COUNT_DEFINE, EXACT_COUNT_KEY, EXACT_DEFINE, EXACT_IMAGES,
                       EXACT_SOFT_DEFINE, EXACT_SOFT_KEY, EXACT_SOFT_UNIFORMS, FIXED_KIND_DEFINE, FIXED_KIND_NAMES,
                       FOOTPRINT_FILES, LINK_DEFINE, NO_WARP_DEFINE, PIECES_DEFINE, POINTS_DEFINE, SCATTER_MODE_DEFINE, SOFT_DEFINE,
                       SOFT_UNIFORMS, VEIL_DEFINE, VEIL_IMAGES, alpha_of, derive, exact_of, exact_soft_of,
                       exact_variant, link_variant, pieces_of, program_variant, scatter_variant, soft_of, veil_of,
                       warp_step_variant)
from .variants import (EXACT_SOFT_MEDIA_DEFINE, GRID_SAMPLERS, GRID_SAMPLERS_KEY, GRIDS_DEFINE, HAZE_DEFINE, HAZE_IMAGES, MEDIA_IMAGE,
                       MEDIA_WORDS_DEFINE, MEDIUM_DEFINE, grids_of, exact_soft_media_of, haze_of, medium_of)
from .constants import GRID_LIGHT_POINTS, GRID_MAX, GRID_MAX_STEPS, MEDIA_POINTS
from .constants import RAY_TREE_BUDGET, RAY_TREE_WIDTH

__all__ = [
    "RAY_TREE_BUDGET", "RAY_TREE_WIDTH",
    "GRID_LIGHT_POINTS", "MEDIA_POINTS", "GRID_MAX", "GRID_MAX_STEPS", "GRID_SAMPLERS", "GRID_SAMPLERS_KEY", "GRIDS_DEFINE", "grids_of", "EXACT_SOFT_MEDIA_DEFINE", "exact_soft_media_of", "MEDIA_WORDS_DEFINE", "HAZE_DEFINE", "HAZE_IMAGES", "haze_of", "MEDIA_IMAGE", "MEDIA_PROGRAMS", "MEDIUM_DEFINE", "medium_of",
    "ADVANCE_PROGRAM", "ALPHA_DEFINE", "ALPHA_INTERPOLATIONS", "alpha_of", "ALPHA_PROGRAMS", "ALPHA_SAMPLERS",
    "BARRIER_PROGRAM", "CODES", "Codes", "COMPUTE_PROGRAMS", "ComputeInterface", "DEPTH_PLAIN_PROGRAM",
    "DEPTH_PROGRAM", "derive", "EDGE_PASSES", "EDGE_PROGRAM", "EXACT_COUNT_DEFINE", "EXACT_COUNT_KEY", "EXACT_DEFINE",
    "EXACT_IMAGES", "EXACT_MAX_WALK", "exact_of", "EXACT_PROGRAMS", "EXACT_SOFT_CLUSTER", "EXACT_SOFT_DEFINE",
    "EXACT_SOFT_KEY", "EXACT_SOFT_MAX_POINTS", "exact_soft_of", "EXACT_SOFT_PROGRAMS", "EXACT_SOFT_UNIFORMS",
    "EXACT_SOFT_WORDS", "exact_variant", "expand_source", "EXTENSIONS", "FIXED_KIND_DEFINE", "FIXED_KIND_NAMES",
    "FOOTPRINT_FILES", "FOOTPRINT_PROGRAM", "FOOTPRINT_VERTICES", "GBUFFER_ALPHA_PROGRAM", "GBUFFER_PROGRAM",
    "GBUFFER_SAMPLES_PROGRAM", "GLSL_VERSION", "INTERPOLATIONS", "LAYER_KINDS", "LIGHT_KINDS", "LINK_DEFINE",
    "link_variant", "load_source", "MAX_POINT_SIZE", "NO_SPLIT", "NO_SPOT", "NO_SPREAD", "NO_TILE", "NO_WARP_DEFINE",
    "OUTLINES", "OVERLAY_MODES", "OVERLAY_PROGRAM", "PARAM_CODES", "PIECES_DEFINE", "pieces_of", "PIECES_PROGRAMS",
    "POINTS_DEFINE", "PREVIEW_PROGRAM",
    "program_defines", "program_variant", "ProgramInterface", "PROGRAMS", "RAY_TABLE_PROGRAM", "REGION_PLANES",
    "RESOLVE_PROGRAM",
    "SAMPLE_FLAGS", "SEGMENTS_PROGRAM", "SAMPLE_STATS_PROGRAM", "SCATTER_MODE_CODES", "SCATTER_MODE_DEFINE", "SCATTER_MODES",
    "SCATTER_PROGRAM", "scatter_variant", "SHADER_DIR", "SHADOW_TEST_PLAIN_PROGRAM", "SHADOW_TEST_PROGRAM",
    "SHARED_DEFINES", "SLOTS", "SOFT_DEFINE", "SOFT_MAX_POINTS", "SOFT_MAX_SEARCH", "soft_of", "SOFT_PROGRAMS",
    "SOFT_SEARCH_STEPS", "SOFT_UNIFORMS", "STATS_PASSES", "Uniform", "VARIANT_PROGRAMS", "Varying", "VEIL_DEFINE",
    "VEIL_IMAGES", "veil_of", "VEIL_PROGRAMS", "VERTEX_TEXTURE_WIDTH", "WARP_BUILD_PROGRAM", "WARP_FAMILIES",
    "WARP_STEPS", "warp_step_variant", "image_type", "WORK_BOX", "WORK_CUT", "WORK_ENTRIES",
    "WORK_FRAGMENTS", "WORK_TEXELS",
]
