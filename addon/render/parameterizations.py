"""One object per parameterization: how each plans a frame, maps and draws its layers,
and what its shadow test needs (issue 17).

A `Parameterization` has the same few methods for every method family:

- `plan`: the frame's layers from the light and the view (core.plan);
- `base_mappings`: the layer mappings a frame without a warp uses (IPSM's zoom or cut);
- `prepare`: the geometry of the frame (resident footprints, or unfold's host stream);
- `scissor`: per-layer texel boxes the shadow test can read (map-space culling);
- `draw`: the depth pass into the atlas, returning the edge-distance radius (0: none);
- `test_uniforms`: what the shadow test needs beyond the shared layer tables.

The dual paraboloid, cube and IPSM draw resident footprints (footprint.vert); unfold
draws its host-built stream (unfold.py); the spot and sun maps draw the resident
triangles through one projective matrix. Adding a parameterization means one class
here, one entry in `PARAMETERIZATIONS` and its code in shaders.PARAM_CODES (emitted to the GLSL).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..core import footprint, projection
from ..core.frames import Layer
from ..core.plan import (
    REGION_SLACK,
    SCISSOR_EDGE_POINTS,
    Plan,
    layer_scissor,
    outside_region,
    plan_frame,
    plan_projective,
    sun_upstream_reach,
)
from ..core.samples import SampleStats
from ..core.scene import CameraSpec, LightSpec
from ..core.warping import LayerMapping, max_shear
from .backend import AtlasLayout, FootprintDraw, ShadowBackend
from .frame import PreparedGeometry, ShadowSettings
from .resident import CHUNK_TRIANGLES, ResidentScene
from .shaders import (EXACT_COUNT_KEY, EXACT_MAX_WALK, EXACT_SOFT_KEY, FOOTPRINT_VERTICES, MAX_POINT_SIZE,
                      REGION_PLANES, SLOTS)
from .soft import exact_soft_uniforms, light_reach, sample_far
from .unfold import VERTEX_FLOATS, edge_aa_parameters, prepare_unfold

log = logging.getLogger(__name__)

# The exact pass leaves out an occluder within this share of the segment's length from the
# sample: the receiver's own surface, and its coplanar neighbours, in float32 rounding.
EXACT_EPS = 1e-4
# The exact pass over a spot's or sun's map lifts each sample off its own surface, towards
# the light, by this share of its distance from the light-centred origin (footprint.frag's
# ow_exact_lift): about three times float32's rounding of the sample (6e-8), far below a
# pixel. On sun_field 5e-8 still left 333 samples of a face parallel to the sun shadowed by
# their own box, 1e-7 to 2e-7 none; from 5e-7 on, the lift moves shadow edges on the
# ground past Cycles' samples (1 pixel at 5e-7, 5 at 1e-6, 59 at 1e-5).
EXACT_LIFT = 2e-7
# Rounds of the exact pass after the first (_finish_lists): the bound doubles each round, so
# 16 of them walk lists of up to 4096 * 2^17 entries, far more than any frame's samples.
EXACT_MAX_ROUNDS = 16

# Near clip of cube faces, relative to far: geometry closer to the light than this
# is lost to clipping; 1e-6 keeps it far below a texel at any supported resolution.
CLIP_NEAR_RELATIVE = 1e-6



# Texels a footprint box grows by on each side: its float32 corners may fall short of the
# exact box by rounding (about 1e-4 map units, 2e-3 next to the light), and a texel
# centre left outside would lose its triangle (lib/footprint.glsl).
FOOTPRINT_DILATE_TEXELS = 1.0


@dataclass(frozen=True)
class DrawInputs:
    """What a parameterization's depth pass draws from (made by the pipeline per frame)."""

    plan: Plan
    settings: ShadowSettings
    geometry: PreparedGeometry
    layout: AtlasLayout
    tile_of_slot: dict[int, int]
    mappings: dict[int, LayerMapping]
    warp_size: int  # the count-map side A of the warp tables
    boxes: dict[int, tuple[int, int, int, int]]
    draws: list[FootprintDraw]  # the resident objects
    region: dict  # the occluder region's uniforms (region_uniforms)
    scene: ResidentScene
    light: LightSpec
    count_work: bool = False  # exact pass: count the list entries walked (a measurement frame)


class Parameterization:
    """The point-light defaults: plan_frame, no base mapping, resident footprints."""

    name = "abstract"

    def plan(self, light: LightSpec, settings: ShadowSettings, camera: CameraSpec | None, stats: SampleStats,
             near_far: tuple[float, float], bounds: tuple[np.ndarray, np.ndarray] | None) -> Plan:
        return plan_frame(light, self.name, camera, stats, near_far[1], cull=settings.cull, cut=settings.cut)

    def base_mappings(self, plan: Plan, light: LightSpec, settings: ShadowSettings) -> dict[int, LayerMapping]:
        return {}

    def prepare(self, light: LightSpec, scene: ResidentScene, plan: Plan, settings: ShadowSettings,
                near_far: tuple[float, float]) -> PreparedGeometry:
        return PreparedGeometry({}, near_far[0], near_far[1], scene.skipped, 0,
                                measure=_measurer(scene, light, plan, settings, near_far[1]))

    def scissor(self, plan: Plan, light: LightSpec, settings: ShadowSettings,
                mappings: dict[int, LayerMapping]) -> dict[int, tuple[int, int, int, int]]:
        return scissor_boxes(plan, light, settings, mappings)

    def draw(self, backend: ShadowBackend, inputs: DrawInputs) -> int:
        """One footprint draw per layer and object run; a warped layer first gets its ray table."""
        if not inputs.draws:
            return 0  # nothing to draw (no blockers): the cleared atlas is the map
        res = inputs.settings.resolution
        exact = inputs.settings.exact
        soft = (exact_soft_uniforms(inputs.light, inputs.settings, sample_far(inputs.plan, inputs.light))
                if exact else {})
        reach = float(soft.get("ow_exact_reach", 0.0))
        region = inputs.region
        if reach > 0.0:
            # A sized light's occluders lie within its reach of the hull of its centre and
            # the view: each plane of the region moves out by it.
            region = {**region, "ow_region_slack": float(region.get("ow_region_slack", 0.0)) + reach}
        # Per object, the chunks' light-centred spheres, the same on every layer.
        spheres = {draw.key: _chunk_spheres(inputs.scene.objects[draw.key], inputs.light) for draw in inputs.draws}
        passes = []  # (tile, draws, uniforms, scissor) per drawn layer
        for layer in inputs.plan.drawn:
            tile = inputs.tile_of_slot[layer.slot]
            mapping = inputs.mappings.get(layer.slot, LayerMapping.identity())
            uniforms = {**layer_uniforms(layer, inputs.geometry, res, inputs.layout.origin(tile), mapping,
                                         inputs.warp_size), **region}
            if exact:
                # The irregular z-buffer: the tile's lists are strip tile `tile` (link_lists).
                uniforms.update({"ow_exact_tile": tile, "ow_exact_eps": EXACT_EPS, "ow_exact_bound": EXACT_MAX_WALK,
                                 EXACT_COUNT_KEY: int(inputs.count_work), **soft})
            elif mapping.warp is not None:
                backend.build_ray_table(tile, uniforms)
            stretch = map_stretch(mapping)
            draws = [run for draw in inputs.draws
                     for run in footprint_ranges(draw, spheres[draw.key], layer, stretch, res, region, reach)]
            scissor = inputs.boxes.get(layer.slot)
            backend.draw_footprints(tile, draws, uniforms, scissor=scissor, exact=exact)
            passes.append((tile, draws, uniforms, scissor))
        if exact:
            _finish_lists(backend, inputs.layout, passes)
        return 0

    def test_uniforms(self, plan: Plan) -> dict:
        return {}


def _finish_lists(backend: ShadowBackend, layout: AtlasLayout, passes: list) -> None:
    """Later rounds of the exact pass until every list entry met every triangle over its
    texel (issue 26). A round whose walks stopped at their bound moves each list's head past
    the entries walked (backend.advance_lists) and draws the layers again, scissored to the
    texels whose lists go on, with twice the bound; so a texel of n samples takes about
    log2(n / EXACT_MAX_WALK) + 1 rounds, each entry is walked once per triangle, and a frame
    whose lists all fit (every ordinary one) pays one read of the work counters, which
    also folds the frame's work for `read_hits`."""
    bound = EXACT_MAX_WALK
    for _ in range(EXACT_MAX_ROUNDS):
        if not backend.exact_round():
            return
        remaining = backend.advance_lists(bound, layout)
        bound *= 2
        for tile, draws, uniforms, scissor in passes:
            box = remaining.get(tile)
            if box is not None:
                clip = box if scissor is None else _intersect(box, scissor)
                backend.draw_footprints(tile, draws, {**uniforms, "ow_exact_bound": bound}, scissor=clip, exact=True)
    if backend.exact_round():  # the last round's counters
        log.warning("exact pass: lists still unfinished after %d rounds", EXACT_MAX_ROUNDS)


def _intersect(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """The common part of two texel boxes (x0, y0, x1, y1); empty ones have x1 <= x0."""
    return max(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), min(a[3], b[3])


class DualParaboloid(Parameterization):
    """Two paraboloids back to back (Brabec et al. 2002)."""

    name = "dpsm"


class Cube(Parameterization):
    """Six 90 degree faces."""

    name = "cube"


class Ipsm(Parameterization):
    """One paraboloid along the axis of the cone that holds the view (Vanek et al.):
    without a warp its map is zoomed to the cone, or to the skewed cut."""

    name = "ipsm"

    def base_mappings(self, plan: Plan, light: LightSpec, settings: ShadowSettings) -> dict[int, LayerMapping]:
        if plan.ipsm_half_angle is None:
            return {}
        return {0: (cut_mapping(plan, light, settings.resolution) if settings.cut
                    else ipsm_mapping(plan.ipsm_half_angle, settings.resolution))}


class Unfold(Parameterization):
    """Dual sphere-unfolding: both halves in one draw of a host-built stream (unfold.py)."""

    name = "unfold"

    def prepare(self, light: LightSpec, scene: ResidentScene, plan: Plan, settings: ShadowSettings,
                near_far: tuple[float, float]) -> PreparedGeometry:
        return prepare_unfold(light, scene.world_triangles(), plan, settings, near_far)

    def scissor(self, plan: Plan, light: LightSpec, settings: ShadowSettings,
                mappings: dict[int, LayerMapping]) -> dict[int, tuple[int, int, int, int]]:
        return {}  # the draw spans both halves

    def draw(self, backend: ShadowBackend, inputs: DrawInputs) -> int:
        plan, geometry, res = inputs.plan, inputs.geometry, inputs.settings.resolution
        if not plan.drawn:
            return 0
        # The vertex stage picks the half from the vertex index (Stockli Contreras et al.).
        uniforms = layer_uniforms(plan.drawn[0], geometry, res, inputs.layout.origin(0), LayerMapping.identity(), 0)
        uniforms["ow_unfold_split"] = geometry.unfold_split
        uniforms["ow_unfold_halves"] = len(plan.drawn)
        backend.draw_layer(0, geometry.streams.get(0, np.zeros((0, VERTEX_FLOATS), np.float32)), uniforms,
                           span=len(plan.drawn))
        if not inputs.settings.edge_aa:
            return 0
        radius, eps = edge_aa_parameters(res, geometry.near, geometry.far)
        backend.edge_distance(radius, eps)
        return radius


class Projective(Parameterization):
    """A spot or sun map (sm, psm): one layer through one 4x4 projective matrix, which the
    GPU clips and interpolates exactly."""

    def __init__(self, name: str) -> None:
        self.name = name

    def plan(self, light: LightSpec, settings: ShadowSettings, camera: CameraSpec | None, stats: SampleStats,
             near_far: tuple[float, float], bounds: tuple[np.ndarray, np.ndarray] | None) -> Plan:
        # With nothing finite to draw, any box around the light will do.
        lo, hi = bounds if bounds is not None else (light.position - 1.0, light.position + 1.0)
        return plan_projective(light, self.name, camera, stats, lo, hi, settings.resolution, cull=settings.cull)

    def scissor(self, plan: Plan, light: LightSpec, settings: ShadowSettings,
                mappings: dict[int, LayerMapping]) -> dict[int, tuple[int, int, int, int]]:
        return {}  # the matrix already fits the map to the view

    def draw(self, backend: ShadowBackend, inputs: DrawInputs) -> int:
        plan = inputs.plan
        uniforms = {**layer_uniforms(plan.drawn[0], inputs.geometry, inputs.settings.resolution,
                                     inputs.layout.origin(0), LayerMapping.identity(), 0),
                    **inputs.region, **self.test_uniforms(plan)}
        if inputs.settings.exact:
            self._draw_exact(backend, inputs, uniforms)
            return 0
        backend.draw_footprints(0, inputs.draws, uniforms)
        return 0

    @staticmethod
    def _draw_exact(backend: ShadowBackend, inputs: DrawInputs, uniforms: dict) -> None:
        """The irregular z-buffer over the map (issue 27): every triangle over a conservative
        cover of its image (footprint.vert's ow_projective_quad), walking the lists of the
        map's texels (tile 0, linked through the map's matrix). A spot's triangle is clipped
        to the map's front, w >= CLIP_NEAR_RELATIVE * far (the map's w is the depth along the
        spot's axis); a sun's map has w = 1 and clips nothing. The covers are quads: their
        size in texels has no bound here that would fit a point sprite."""
        light = inputs.light
        sun = light.emission == "sun"
        soft = exact_soft_uniforms(light, inputs.settings, sample_far(inputs.plan, light))
        uniforms = {**uniforms, "ow_exact_tile": 0, "ow_exact_eps": EXACT_EPS, "ow_exact_bound": EXACT_MAX_WALK,
                    EXACT_COUNT_KEY: int(inputs.count_work), "ow_sun": int(sun), "ow_light_axis": light.axis,
                    "ow_clip_near": 0.0 if sun else inputs.geometry.far * CLIP_NEAR_RELATIVE,
                    "ow_exact_lift_share": EXACT_LIFT, **soft}
        if int(soft.get(EXACT_SOFT_KEY, 0)) > 0:
            # A sized light's occluders lie farther out: a spot's within its sphere's radius of
            # the region, a sun's within the tangent of its half angle times the region's
            # depth (plan_projective's hull reaches that far upstream of the view).
            uniforms["ow_region_slack"] = float(uniforms.get("ow_region_slack", 0.0)) + _projective_slack(
                light, inputs.scene)
        if not inputs.draws:
            return
        backend.draw_footprints(0, inputs.draws, uniforms, exact=True)
        _finish_lists(backend, inputs.layout, [(0, inputs.draws, uniforms, None)])

    def test_uniforms(self, plan: Plan) -> dict:
        return {"ow_projective": 1, "ow_map_inverted": int(plan.projective.inverted),
                "ow_map_matrix": plan.projective.matrix, "ow_depth_offset": plan.projective.depth_offset}


def _projective_slack(light: LightSpec, scene: ResidentScene) -> float:
    """How far a sized spot's or sun's occluders may lie outside the hard light's occluder
    region: the sphere's radius, or for a sun the tangent of its half angle times the
    region's reach upstream (plan.sun_upstream_reach, as plan_projective builds it)."""
    if light.emission != "sun":
        return light_reach(light.shape)
    bounds = scene.bounds()
    reach = sun_upstream_reach(*bounds) if bounds is not None else 1.0
    return math.tan(0.5 * light.shape.angle) * reach


PARAMETERIZATIONS: dict[str, Parameterization] = {
    p.name: p for p in (DualParaboloid(), Cube(), Ipsm(), Unfold(), Projective("sm"), Projective("psm"))}


def parameterization(name: str) -> Parameterization:
    """The object of a parameterization name (a Plan's, or a ShadowSettings')."""
    return PARAMETERIZATIONS[name]


def layer_uniforms(layer: Layer, geometry: PreparedGeometry, res: int, origin: tuple[int, int],
                    mapping: LayerMapping, warp_size: int) -> dict:
    """The uniforms of one layer's depth draw (both depth programs take them)."""
    warp = mapping.warp
    return {
        "ow_layer_rot": layer.rotation,
        "ow_layer_kind": layer.kind,
        "ow_layer_slot": layer.slot,
        "ow_mapped": 0 if mapping.is_identity else 1,
        "ow_warp_size": warp_size if warp is not None else 0,
        "ow_warp_shear": (max_shear(warp.rows), max_shear(warp.cols)) if warp is not None else (0.0, 0.0),
        "ow_dilate": FOOTPRINT_DILATE_TEXELS,
        "ow_edge_on_distance": footprint.EDGE_ON_SCENE * geometry.far,
        "ow_crop": mapping.crop_vec4(),
        "ow_near": geometry.near,
        "ow_far": geometry.far,
        "ow_clip_near": geometry.far * CLIP_NEAR_RELATIVE,
        "ow_resolution": float(res),
        "ow_tile_origin": (float(origin[0]), float(origin[1])),
        "ow_unfold_split": -1,
        "ow_unfold_halves": 1,
        "ow_projective": 0,
        "ow_map_inverted": 0,
        "ow_map_matrix": np.eye(4),
    }


# Most draw calls one object gets per layer (runs of points and quads); beyond it the
# shortest point runs are drawn as quads, which are right for any triangle.
MAX_RUNS = 32


def _slopes(table: np.ndarray) -> np.ndarray:
    """(A,) each function's steepest d(offset)/d(along), at least 0."""
    return np.maximum(np.diff(table, axis=1).max(axis=1) * table.shape[0], 0.0)


def map_stretch(mapping: LayerMapping) -> float:
    """An upper bound of how much the crop and warp widen a box of the plain map (map uv
    per plain uv, on the box's longer side), as footprint.warp_box widens it.

    A plain box of side d is at most s d a side after the crop (s: its larger scale).
    The row warp widens it by its offsets' steepest slope along the rows and by the shear
    across them: W <= s d (1 + slope_r + shear_r). The column warp then takes the box's
    height and the new width: H <= s d (1 + slope_c) + shear_c W. Bounding the two in turn,
    not their product, keeps more chunks within a point sprite on a warped layer.
    """
    scale = float(np.max(mapping.scale))
    warp = mapping.warp
    if warp is None:
        return scale
    width = scale * (1.0 + float(_slopes(warp.rows).max()) + max_shear(warp.rows))
    height = scale * (1.0 + float(_slopes(warp.cols).max())) + max_shear(warp.cols) * width
    return max(width, height)


def _chunk_spheres(obj, light: LightSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Light-centred chunk centres (C, 3), radii and longest edges (C,), in world units;
    None for an object without chunks."""
    chunks = obj.chunks
    if chunks is None:
        return None
    linear = obj.matrix[:3, :3]
    scale = float(np.linalg.norm(linear, 2))
    return chunks.centres @ linear.T + obj.offset(light.position), chunks.radii * scale, chunks.edges * scale


def _chunk_texels(centres: np.ndarray, radii: np.ndarray, edges: np.ndarray, layer: Layer,
                  stretch: np.ndarray | float, res: int) -> np.ndarray:
    """(C,) a bound of each chunk's triangles' footprint boxes, in texels a side, on this
    layer; inf where the bound does not apply."""
    distance = np.maximum(np.linalg.norm(centres, axis=1) - radii, 0.0)
    with np.errstate(divide="ignore"):
        # Two points of a triangle with edges <= e, all >= d from the light, are at most
        # 2 atan(e / 2d) apart as seen from it.
        angle = np.where(distance > 0.0, 2.0 * np.arctan(edges / np.maximum(2.0 * distance, 1e-300)), np.pi)
    if layer.kind == projection.PARABOLOID:
        # Conformal, scale 1 / (1 + z) <= 1 on the layer's hemisphere: uv moves at most
        # half the angle (and the box's arcs and sag stay within the image's hull).
        per_radian = 0.5
    else:
        # Where |x|, |y| <= k z the gnomonic map stretches at most 1 + 2 k^2 (sec^2 at the
        # corner): 1.5 uv per radian on the face (k = 1), 4.5 out to k = 2. A chunk wholly
        # inside that frustum has its clamped box bounded so; outside it, not at all.
        local = centres @ layer.rotation.T
        x, y, z = np.abs(local[:, 0]), np.abs(local[:, 1]), local[:, 2]
        per_radian = np.full(len(radii), np.inf)
        for k, bound in ((2.0, 4.5), (1.0, 1.5)):
            inside = (np.minimum(k * z - x, k * z - y) / np.sqrt(1.0 + k * k)) > radii
            per_radian = np.where(inside, bound, per_radian)
    return res * stretch * per_radian * angle + 2.0 * FOOTPRINT_DILATE_TEXELS + 2.0


def _chunks_outside(centres: np.ndarray, radii: np.ndarray, layer: Layer | None, region: dict) -> np.ndarray:
    """(C,) chunks no triangle of which the footprint pass would draw on this layer: wholly
    behind the paraboloid's hemisphere or beside the cube face, or beyond a plane of the
    occluder region (the same tests the vertex stage makes per triangle); with no layer,
    only the region's test."""
    outside = np.zeros(len(radii), dtype=bool)
    if layer is not None:
        local = centres @ layer.rotation.T
        x, y, z = local[:, 0], local[:, 1], local[:, 2]
        outside |= z < -radii
        if layer.kind == projection.CUBE:
            for side in (x - z, -x - z, y - z, -y - z):
                outside |= side / np.sqrt(2.0) > radii
    count = int(region.get("ow_region_count", 0))
    if count:
        planes = np.asarray(region["ow_region_planes"], dtype=np.float64)[:count]
        distance = centres @ planes[:, :3].T - planes[:, 3] - float(region["ow_region_slack"])
        outside |= np.any(distance / np.linalg.norm(planes[:, :3], axis=1) > radii[:, None], axis=1)
    return outside


SKIP, POINTS, QUADS = 0, 1, 2  # how a chunk is drawn on a layer


_VERTEX_COST = np.array([0, 1, FOOTPRINT_VERTICES])  # vertices a triangle costs, by kind (SKIP, POINTS, QUADS)


def _run_bounds(kinds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) chunk of each run of equal kinds."""
    edges = np.flatnonzero(np.diff(kinds)) + 1
    return np.concatenate([[0], edges]), np.concatenate([edges, [len(kinds)]])


def _runs(kinds: np.ndarray) -> list[tuple[int, int, int]]:
    """(start, end, kind) runs of equal kinds, merged down to about MAX_RUNS drawn runs at
    little added vertex work: a skipped run between drawn ones takes its cheaper
    neighbour's kind (its triangles are culled per triangle anyway), and a point run
    becomes quads, which are right for any triangle. Vectorised: a few passes, each
    converting the cheapest runs at once."""
    kinds = np.asarray(kinds, dtype=np.int64).copy()
    for _ in range(16):
        start, end = _run_bounds(kinds)
        kind = kinds[start]
        excess = int(np.count_nonzero(kind != SKIP)) - MAX_RUNS
        if excess <= 0:
            break
        before = np.concatenate([[QUADS], kind[:-1]])
        after = np.concatenate([kind[1:], [QUADS]])
        neighbour = np.where(_VERTEX_COST[before] <= _VERTEX_COST[after], before, after)
        inner = (np.arange(len(kind)) > 0) & (np.arange(len(kind)) < len(kind) - 1)
        target = np.where(kind == SKIP, neighbour, QUADS)
        cost = np.where(kind == QUADS, np.inf, (end - start) * (_VERTEX_COST[target] - _VERTEX_COST[kind]))
        cost = np.where((kind == SKIP) & ~inner, np.inf, cost)
        chosen = np.argsort(cost, kind="stable")[:max(1, excess // 2)]
        chosen = chosen[np.isfinite(cost[chosen])]
        if not len(chosen):
            break
        for i in chosen:
            kinds[start[i]:end[i]] = target[i]
    start, end = _run_bounds(kinds)
    return [(int(a), int(b), int(kinds[a])) for a, b in zip(start, end)]


def footprint_ranges(draw: FootprintDraw, spheres: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
                     layer: Layer, stretch: float, res: int, region: dict | None = None,
                     reach: float = 0.0) -> list[FootprintDraw]:
    """One object's draw on one layer, by chunks of CHUNK_TRIANGLES: chunks that cannot
    reach the layer are left out; chunks whose footprint bound fits MAX_POINT_SIZE draw
    one point sprite a triangle instead of a six-vertex quad. `spheres` are the object's
    `_chunk_spheres` (None: draw it whole as quads), `stretch` the layer's `map_stretch`.
    With a sized light's `reach` (the exact soft pass) footprints grow past a point sprite
    and past the layer's own half-space, so every chunk draws quads and only the region
    (already widened by the reach) leaves chunks out.
    Host work per chunk, not per triangle; the vertex stage still culls each triangle."""
    if spheres is None or not len(spheres[1]):
        return [draw]
    centres, radii, edges = spheres
    if reach > 0.0:
        kinds = np.full(len(radii), QUADS)
        kinds[_chunks_outside(centres, radii, None, region or {})] = SKIP
    else:
        small = _chunk_texels(centres, radii, edges, layer, stretch, res) <= MAX_POINT_SIZE
        kinds = np.where(small, POINTS, QUADS)
        kinds[_chunks_outside(centres, radii, layer, region or {})] = SKIP
    total = draw.first + draw.count
    out = []
    for a, b, kind in _runs(kinds):
        first = draw.first + a * CHUNK_TRIANGLES
        count = min(b * CHUNK_TRIANGLES, total - draw.first) - a * CHUNK_TRIANGLES
        if kind != SKIP and count > 0:
            out.append(FootprintDraw(draw.key, first, count, draw.uniforms, kind == POINTS))
    return out


def footprint_draws(scene: ResidentScene, light: LightSpec) -> list[FootprintDraw]:
    """One draw per resident object: its matrix, and the light in its frame as double-single."""
    draws = []
    for key, obj in scene.objects.items():
        if obj.triangles:
            hi, lo = obj.light_split(light.position)
            uniforms = {"ow_object_linear": obj.matrix[:3, :3], "ow_light_hi": hi, "ow_light_lo": lo}
            if obj.alpha is not None:
                uniforms["ow_alpha_mode"] = obj.alpha.mode  # the see-through variant's
            draws.append(FootprintDraw(key, 0, obj.triangles, uniforms))
    return draws


def region_uniforms(plan: Plan, light: LightSpec, cull: bool) -> dict:
    """The occluder region (plan.occluder_planes) light-centred, for the GPU's object culling.

    A triangle with all corners beyond one plane (by outside_region's slack) is not drawn.
    """
    planes = plan.occluder_planes if cull else None
    table = np.zeros((REGION_PLANES, 4))
    if planes is None or len(planes) == 0:
        return {"ow_region_planes": table, "ow_region_count": 0, "ow_region_slack": 0.0}
    if len(planes) > REGION_PLANES:
        log.debug("occluder region has %d planes, more than the GPU table's %d: not culled",
                  len(planes), REGION_PLANES)
        return {"ow_region_planes": table, "ow_region_count": 0, "ow_region_slack": 0.0}
    planes = np.asarray(planes, dtype=np.float64)
    table[:len(planes), :3] = planes[:, :3]
    table[:len(planes), 3] = planes[:, 3] - planes[:, :3] @ light.position
    slack = REGION_SLACK * (float(np.abs(planes[:, 3]).max()) + 1.0)
    return {"ow_region_planes": table, "ow_region_count": len(planes), "ow_region_slack": slack}


def _measurer(scene: ResidentScene, light: LightSpec, plan: Plan, settings: ShadowSettings, plan_far: float):
    """Host counts of a resident frame, for measurement only: the triangles the footprint
    pass keeps, summed over the drawn layers (not edge-on, inside the occluder region,
    in front of the layer: a paraboloid's hemisphere, a cube face's frustum), and the
    triangles seen edge-on, which cover nothing."""

    def measure() -> tuple[int, int]:
        kept, edge_on = [], 0
        for obj in scene.objects.values():
            tris = obj.light_centred(light.position)
            if plan.projective is None and len(tris):
                _, orientation = footprint.edge_planes(tris, footprint.GPU_EDGE_ON,
                                                       footprint.EDGE_ON_SCENE * plan_far)
                edge_on += int(np.count_nonzero(orientation == 0.0))
                tris = tris[orientation != 0.0]
            kept.append(tris)
        tris = np.concatenate(kept) if kept else np.zeros((0, 3, 3))
        if settings.cull and len(tris):
            tris = tris[~outside_region(tris + light.position, plan.occluder_planes)]
        if plan.projective is not None:
            return len(tris), edge_on
        total = 0
        for layer in plan.drawn:
            local = tris @ layer.rotation.T
            z = local[..., 2]
            front = np.any(z > 0.0, axis=1)
            if layer.kind == projection.CUBE:
                x, y = local[..., 0], local[..., 1]
                front &= ~(np.all(x > z, axis=1) | np.all(-x > z, axis=1) | np.all(y > z, axis=1)
                           | np.all(-y > z, axis=1))
            total += int(np.count_nonzero(front))
        return total, edge_on

    return measure


def slot_rotations_and_crops(plan: Plan, mappings: dict[int, LayerMapping]) -> tuple[np.ndarray, np.ndarray]:
    """Per-slot layer rotations (6, 3, 3) and crop vec4s (6, 4) for the GLSL tables.

    Unused slots keep the identity rotation and the whole map; a layer missing from
    `mappings` is uncropped.
    """
    rotations = np.tile(np.eye(3), (SLOTS, 1, 1))
    crops = np.tile([0.0, 0.0, 1.0, 1.0], (SLOTS, 1))
    for layer in plan.all_layers:
        rotations[layer.slot] = layer.rotation
    for slot, mapping in mappings.items():
        crops[slot] = mapping.crop_vec4()
    return rotations, crops


def scissor_boxes(plan: Plan, light: LightSpec, settings: ShadowSettings,
                  mappings: dict[int, LayerMapping]) -> dict[int, tuple[int, int, int, int]]:
    """Slot -> texel box the shadow test can read, for the plain layers culling bounds
    (plan.layer_scissor); only with culling. A crop or warp already fits the map to the
    samples, so mapped layers get none."""
    if not settings.cull:
        return {}
    boxes = {}
    for layer in plan.drawn:
        if mappings.get(layer.slot, LayerMapping.identity()).is_identity:
            box = layer_scissor(layer, light.position, plan.sample_polytope, settings.resolution)
            if box is not None:
                boxes[layer.slot] = box
    return boxes


def ipsm_mapping(half_angle: float, resolution: int) -> LayerMapping:
    """IPSM's zoom 1/tan(theta/2) as a centred crop: the cone's edge lands on the map's rim.

    A paraboloid maps a ray at angle a from its axis to radius tan(a/2), so cropping
    to [-t, t]^2 with t = tan(theta/2) scales the coordinates by 1/t. The crop grows by
    2 % and 4 texels so the shadow test's normal offset stays inside the map.
    """
    t = min(1.0, math.tan(half_angle / 2.0) * 1.02 + 4.0 / resolution)
    return LayerMapping(np.full(2, 0.5 - 0.5 * t), np.full(2, 0.5 + 0.5 * t), None)


def cut_mapping(plan: Plan, light: LightSpec, resolution: int) -> LayerMapping:
    """Cut parameters (min/max x, y) of the skewed cut: the bounding box of the sample
    polytope's edges projected into the skewed paraboloid, grown by 2 % and 4 texels.

    The image of a convex body seen from outside is bounded by the images of its
    edges, so the box holds every view sample.
    """
    layer = plan.drawn[0]
    edges = plan.sample_polytope.edge_points(SCISSOR_EDGE_POINTS)
    xy = projection.paraboloid_project(layer.to_local(edges - light.position))
    lo, hi = xy.min(axis=0) * 0.5 + 0.5, xy.max(axis=0) * 0.5 + 0.5
    grow = (hi - lo) * 0.02 + 4.0 / resolution
    lo, hi = np.clip(lo - grow, 0.0, 1.0), np.clip(hi + grow, 0.0, 1.0)
    return LayerMapping(lo, hi, None)
