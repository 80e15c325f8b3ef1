"""Every GPU constant, with one source: the host's values, emitted as `#define`s into every
program's header (`SHARED_DEFINES`, `interfaces.program_defines`), so no shader file spells
a number out that the host also knows.

The codes a uniform carries (a parameterization, a light kind, a mode, a sentinel) are
`Codes` tables: each names its defines and the GLSL quantities that hold one of its codes
(`holders`), which tests/test_glsl_constants.py forbids to compare with a bare number.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Mapping

from ...core import alpha, blockers, footprint, projection, ray_tree


@dataclass(frozen=True)
class Codes:
    """One table of codes: define `prefix + NAME` for each entry, and the GLSL expressions
    (a uniform, or a component of one) that hold one of the codes."""

    prefix: str
    codes: Mapping[str, int | float]
    holders: tuple[str, ...]

    def defines(self) -> dict[str, str]:
        return {f"{self.prefix}{name.upper()}": _glsl(value) for name, value in self.codes.items()}


def _glsl(value: int | float) -> str:
    """A GLSL literal of `value`; a negative one in parentheses, so a macro stays one operand."""
    text = repr(float(value)) if isinstance(value, float) else str(int(value))
    return f"({text})" if value < 0 else text


# Layers ---------------------------------------------------------------------------------
PARAM_CODES = {"dpsm": 0, "cube": 1, "ipsm": 2, "unfold": 3, "sm": 4, "psm": 5}  # ow_param
SLOTS = 6  # layer slots the GLSL tables hold (ow_layer_rot[OW_SLOTS] and the like): a cube's faces
LAYER_KINDS = {"paraboloid": projection.PARABOLOID, "cube": projection.CUBE, "unfold": projection.UNFOLD}
NO_SPLIT = -1  # ow_unfold_split of a frame that is not an unfold (else its split layer)
NO_TILE = -1  # ow_slot_tile[s] of a slot whose layer is not drawn (else its count-map tile)

# Sized lights (render/soft.py, lib/soft.glsl, lib/exact_soft.glsl): how the light's points
# lie (ow_soft_kind, ow_exact_light.x) and an area light's outline (ow_exact_light.w).
LIGHT_KINDS = MappingProxyType({"sphere": 1, "area": 2, "sun_disk": 3})
OUTLINES = MappingProxyType({"rectangle": 0, "ellipse": 1})
# The sign for "not a spot" in a spot cone's cos (ow_soft_spot.x, ow_exact_spot.x;
# lib/spot_cone.glsl): below every cosine; the GLSL tests below NO_SPOT_BELOW.
NO_SPOT = -2.0
NO_SPOT_BELOW = NO_SPOT + 0.5
# The sign for "no spread" in an area light's spread tangent (ow_soft_spread,
# ow_exact_spread): a tangent is never negative, so the GLSL tests below NO_SPREAD_BELOW.
NO_SPREAD = -1.0
NO_SPREAD_BELOW = 0.0

# See-through materials (core/alpha.py's AlphaMap.mode, lib/alpha.glsl): ow_alpha_mode is the
# interpolation plus ALPHA_INTERPOLATIONS times the extension.
INTERPOLATIONS = MappingProxyType({name: code for code, name in enumerate(alpha.INTERPOLATIONS)})
EXTENSIONS = MappingProxyType({name: code for code, name in enumerate(alpha.EXTENSIONS)})
ALPHA_INTERPOLATIONS = len(INTERPOLATIONS)

# The shadow test's flag per sample (FrameResult.flags; the result's second channel).
SAMPLE_FLAGS = MappingProxyType({"tested": 0, "no_geometry": 1, "outside": 2, "not_drawn": 3})
# Modes of the map thumbnails (overlay.frag, ow_mode), the edge-distance passes
# (edge_distance.frag, ow_edge_pass), the planning statistics' passes (sample_stats.comp,
# ow_stats_pass) and the count-map scatter (scatter.comp, ow_scatter_mode).
OVERLAY_MODES = MappingProxyType({"depth": 0, "count": 1, "legend": 2, "transmittance": 3})
EDGE_PASSES = MappingProxyType({"along_x": 0, "along_y": 1})
STATS_PASSES = MappingProxyType({"fields": 0, "histogram": 1, "cut": 2, "copy": 3})
SCATTER_MODE_CODES = MappingProxyType({"crop": 0, "rows": 1, "warp": 2})  # after the crop; the row warps; the full warp
SCATTER_MODES = tuple(SCATTER_MODE_CODES.values())
# The steps of the warp's construction on the GPU (warp_build.comp, OW_STEP) and the
# two families of a NoTW warp (ow_family): row offsets along u, then column offsets along v.
WARP_STEPS = MappingProxyType({"crop": 0, "crop_store": 1, "line_blur": 2, "lines": 3, "smooth_weights": 4,
                               "smooth_den": 5, "smooth_shear": 6, "smooth_store": 7, "rtw_top": 8, "rtw": 9,
                               "rtw_spread": 10, "pack": 11})
WARP_FAMILIES = MappingProxyType({"rows": 0, "cols": 1})

CODES = (
    Codes("OW_PARAM_", PARAM_CODES, ("ow_param",)),
    Codes("OW_KIND_", LAYER_KINDS, ("ow_layer_kind",)),
    Codes("OW_", {"no_split": NO_SPLIT}, ("ow_unfold_split",)),
    Codes("OW_", {"no_tile": NO_TILE}, ("ow_slot_tile",)),
    Codes("OW_LIGHT_", LIGHT_KINDS, ("ow_soft_kind", "ow_exact_light.x", "ow_grid_light_kind")),
    Codes("OW_OUTLINE_", OUTLINES, ("ow_exact_light.w",)),
    Codes("OW_", {"no_spot": NO_SPOT, "no_spot_below": NO_SPOT_BELOW}, ("ow_soft_spot.x", "ow_exact_spot.x")),
    Codes("OW_", {"no_spread": NO_SPREAD, "no_spread_below": NO_SPREAD_BELOW}, ("ow_soft_spread", "ow_exact_spread")),
    Codes("OW_INTERPOLATION_", INTERPOLATIONS, ("ow_alpha_mode % OW_ALPHA_INTERPOLATIONS",)),
    Codes("OW_EXTENSION_", EXTENSIONS, ("ow_alpha_mode / OW_ALPHA_INTERPOLATIONS",)),
    Codes("OW_FLAG_", {name: float(code) for name, code in SAMPLE_FLAGS.items()}, ("ow_result.y",)),
    Codes("OW_OVERLAY_", OVERLAY_MODES, ("ow_mode",)),
    Codes("OW_EDGE_", EDGE_PASSES, ("ow_edge_pass",)),
    Codes("OW_STATS_", STATS_PASSES, ("ow_stats_pass",)),
    Codes("OW_SCATTER_", SCATTER_MODE_CODES, ("ow_scatter_mode", "OW_SCATTER_MODE")),
    Codes("OW_WARP_", WARP_STEPS, ("OW_STEP",)),
    Codes("OW_FAMILY_", WARP_FAMILIES, ("ow_family",)),
)

# The GPU's warp build (warp_build.comp, passes/warp.py) ----------------------------------
# The smoothing's candidate windows 1, 2, 4, ... (warping.choose_window) for the largest
# count map (A = 256: 1 to 128), each tried by invocations of its own.
WARP_WINDOWS = 8
# Columns of the build's info image (R32UI, WARP_INFO_WIDTH x SLOTS, a row a tile): family
# f's window and shear at 2 f and 2 f + 1; the smoothing's populated lines and weight sum;
# the crop's scale along u and v; family f's steepest slope at slope + f (from pack); the
# shear of candidate window j at window_shear + j.
WARP_INFO = MappingProxyType({"window": 0, "shear": 1, "populated": 4, "weight_sum": 5, "crop_scale": 8,
                              "slope": 10, "window_shear": 12})
WARP_INFO_WIDTH = WARP_INFO["window_shear"] + WARP_WINDOWS

# Footprints -----------------------------------------------------------------------------
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

# The exact pass -------------------------------------------------------------------------
# Most list entries one fragment of the exact pass walks in its first round
# (footprint_exact.frag's ow_exact_bound): a longer list is finished by later rounds, each
# with twice the bound of the one before (parameterizations.Parameterization.draw).
EXACT_MAX_WALK = 4096
# Its work image (R32UI, WORK_TEXELS x 1; footprint_exact.frag, list_advance.comp): a
# round's walks cut at its bound, and on measurement frames the entries and fragments
# walked (the host folds them round by round); from WORK_BOX, four words per tile, the box
# of the texels whose lists go on into the next round.
WORK_CUT, WORK_ENTRIES, WORK_FRAGMENTS, WORK_BOX = 0, 1, 2, 8
WORK_TEXELS = WORK_BOX + 4 * SLOTS
# Exact soft shadows of a sized light (lib/exact_soft.glsl): the exact pass marks,
# per view sample, which of the light's N points (a square) each triangle blocks, in N bits
# of the sample's words (EXACT_SOFT_WORDS texels of the hits image, rows apart); the shadow
# test weighs the points left. The points go in clusters of EXACT_SOFT_CLUSTER, two to a
# word, each with its bounding box (ow_exact_bounds), which a triangle decides whole where
# it can.
EXACT_SOFT_MAX_POINTS = 256
EXACT_SOFT_WORDS = EXACT_SOFT_MAX_POINTS // 32
EXACT_SOFT_CLUSTER = 16

# Density grids (lib/grids.glsl): the most a frame marches through (one sampler
# each), and the most steps of half a voxel a sample's segment takes through one of them.
GRID_MAX = 4
GRID_MAX_STEPS = 1024
# A sized light's points each view sample's march follows through the grids (its stratified
# pattern, core/light_shape.stratified_points), the light they let through averaged.
GRID_LIGHT_POINTS = 16
# The most light points of a sized light whose segments the exact pass follows through
# homogeneous media (passes/media.py's media_points; ow_media_index holds their pattern
# indices, four a vec4).
MEDIA_POINTS = 144

# The shadow segments' tree (core/ray_tree.py, lib/ray_tree.glsl): the triangles a leaf
# holds, the width of its two tables' textures, and the most units of work (a box or a
# triangle) one shader invocation spends on its walks before it stops to be resumed in the
# next turn (a uniform): llvmpipe ends any loop of one invocation after 65,535 iterations,
# whatever the shader asks.
RAY_TREE_LEAF = ray_tree.LEAF
RAY_TREE_WIDTH = 4096
RAY_TREE_BUDGET = 32768
# A walk's verdict (lib/ray_tree.glsl's ow_tree_walk): nothing crosses the segment, a
# triangle does, or the budget ran out first (go on from the node it left).
RAY_TREE_CLEAR, RAY_TREE_BLOCKED, RAY_TREE_CUT = 0, 1, 2

# Soft shadows of a sized light (lib/soft.glsl): the light's points a shadow test
# reads (core/light_shape.stratified_points, at most SOFT_MAX_POINTS), and the steps of its
# blocker search along each segment to the light.
SOFT_MAX_POINTS = 64
SOFT_MAX_SEARCH = 16
SOFT_SEARCH_STEPS = 3


def _shared_defines() -> dict[str, str]:
    defines: dict[str, str] = {}
    for table in CODES:
        defines.update(table.defines())
    defines.update({
        "OW_SLOTS": str(SLOTS),
        "OW_ALPHA_INTERPOLATIONS": str(ALPHA_INTERPOLATIONS),
        "OW_EDGE_ON": repr(float(footprint.GPU_EDGE_ON)),  # the host's count of drawn triangles uses it
        # See-through surfaces (core/alpha.py): the exact pass's word and the alpha bounds.
        "OW_OPAQUE_ALPHA": repr(float(alpha.OPAQUE_ALPHA)),
        "OW_CLEAR_ALPHA": repr(float(alpha.CLEAR_ALPHA)),
        "OW_HIT_OPAQUE": f"{alpha.HIT_OPAQUE:#x}u", "OW_HIT_TWIN": f"{alpha.HIT_TWIN:#x}u",
        "OW_TWIN_SHARE": repr(float(alpha.TWIN_SHARE)), "OW_TWIN_COS": repr(float(alpha.TWIN_COS)),
        "OW_OPTICAL_SCALE": repr(float(alpha.OPTICAL_SCALE)),
        # How near a piece's surface a point lies on it, and its normal's least cosine with
        # the direction from the axis (lib/blockers.glsl ow_on_piece).
        "OW_OWN_SLACK": repr(float(blockers.OWN_SLACK)), "OW_OWN_COS": repr(float(blockers.OWN_COS)),
        # Cycles ignores a ribbon's hit nearer than this many radii (lib/blockers.glsl).
        "OW_RIBBON_AVOIDANCE": repr(float(blockers.RIBBON_AVOIDANCE)),
        "OW_WORK_CUT": str(WORK_CUT), "OW_WORK_ENTRIES": str(WORK_ENTRIES),
        "OW_WORK_FRAGMENTS": str(WORK_FRAGMENTS), "OW_WORK_BOX": str(WORK_BOX),
        "OW_EXACT_SOFT_MAX_POINTS": str(EXACT_SOFT_MAX_POINTS), "OW_EXACT_SOFT_CLUSTER": str(EXACT_SOFT_CLUSTER),
        "OW_SOFT_MAX_POINTS": str(SOFT_MAX_POINTS), "OW_SOFT_SEARCH_STEPS": str(SOFT_SEARCH_STEPS),
        "OW_GRID_MAX": str(GRID_MAX), "OW_GRID_MAX_STEPS": str(GRID_MAX_STEPS),
        "OW_GRID_LIGHT_POINTS": str(GRID_LIGHT_POINTS), "OW_MEDIA_POINTS": str(MEDIA_POINTS),
        "OW_WARP_WINDOWS": str(WARP_WINDOWS),
        "OW_RAY_TREE_LEAF": str(RAY_TREE_LEAF), "OW_RAY_TREE_WIDTH": str(RAY_TREE_WIDTH),
        "OW_TREE_CLEAR": str(RAY_TREE_CLEAR), "OW_TREE_BLOCKED": str(RAY_TREE_BLOCKED),
        "OW_TREE_CUT": str(RAY_TREE_CUT),
    })
    defines.update({f"OW_INFO_{name.upper()}": str(column) for name, column in WARP_INFO.items()})
    return defines


# The GPU constants every program's header defines: built once, here.
SHARED_DEFINES: Mapping[str, str] = MappingProxyType(_shared_defines())
