"""Which chunks of each resident object a layer's footprint pass draws, and how: point
sprites, quads or not at all (chunk culling), and the occluder region's
uniforms; plus the host's counts of what the pass keeps, for measurement."""
from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from ..core import footprint, projection
from ..core.frames import Layer
from ..core.plan import REGION_SLACK, Plan, outside_region
from ..core.scene import LightSpec
from ..core.warping import LayerMapping, box_stretch, max_shear
from .frame import ShadowSettings
from .passes.footprints import FootprintDraw
from .passes.media import NO_MEDIA, MediaFrame
from .passes.warp import GpuWarp
from .resident import CHUNK_TRIANGLES, ResidentScene
from .shaders import FOOTPRINT_VERTICES, MAX_POINT_SIZE, REGION_PLANES

log = logging.getLogger(__name__)

# Texels a footprint box grows by on each side: its float32 corners may fall short of the
# exact box by rounding (about 1e-4 map units, 2e-3 next to the light), and a texel
# centre left outside would lose its triangle (lib/footprint.glsl).
FOOTPRINT_DILATE_TEXELS = 1.0

# Chunked triangles a layer must draw before a GPU-built warp's numbers are read back to
# size point sprites (GpuWarp.stretch): below it quads cost less than the read's wait.
GPU_SPRITE_TRIANGLES = 16384

# Most draw calls one object gets per layer (runs of points and quads); beyond it the
# shortest point runs are drawn as quads, which are right for any triangle.
MAX_RUNS = 32


def _slopes(table: np.ndarray) -> np.ndarray:
    """(A,) each function's steepest d(offset)/d(along), at least 0."""
    return np.maximum(np.diff(table, axis=1).max(axis=1) * table.shape[0], 0.0)


def map_stretch(mapping: LayerMapping) -> float:
    """An upper bound of how much the crop and warp widen a box of the plain map
    (core.warping.box_stretch): from the host's tables, or from the numbers a GPU build left."""
    warp = mapping.warp
    if isinstance(warp, GpuWarp):
        return warp.stretch()  # from the shears and crop the GPU left (a small read)
    scale = float(np.max(mapping.scale))
    if warp is None:
        return scale
    return box_stretch(scale, float(_slopes(warp.rows).max()), max_shear(warp.rows),
                       float(_slopes(warp.cols).max()), max_shear(warp.cols))


def chunk_spheres(obj, light: LightSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
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


def sprites_pay(mapping: LayerMapping, draws: list[FootprintDraw], spheres: dict) -> bool:
    """Whether a layer's chunked objects may draw point sprites: always under a host-built
    mapping (its numbers are at hand), under a GPU-built warp only from GPU_SPRITE_TRIANGLES
    chunked triangles on (its numbers cost a read)."""
    chunked = sum(draw.count for draw in draws if spheres.get(draw.key) is not None)
    if not chunked:
        return False
    return not isinstance(mapping.warp, GpuWarp) or chunked >= GPU_SPRITE_TRIANGLES


class RunMemo:
    """The runs `footprint_ranges` chose for an object on a layer, by every number they
    depend on: a steady frame draws the same runs without the host's chunk tests (about
    50 to 100 microseconds an object and layer, in numpy calls). Bounded: it starts over
    past MAX_ENTRIES."""

    MAX_ENTRIES = 4096

    def __init__(self) -> None:
        self._runs: dict[tuple, list[tuple[int, int, bool]]] = {}

    def ranges(self, draw: FootprintDraw, spheres: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
               layer: Layer, stretch: float, res: int, region: dict | None = None,
               reach: float = 0.0) -> list[FootprintDraw]:
        """`footprint_ranges`, kept."""
        if spheres is None:
            return [draw]
        region = region or {}
        planes = region.get("ow_region_planes")
        key = (draw.key, draw.first, draw.count, *(a.tobytes() for a in spheres), layer.kind,
               np.asarray(layer.rotation).tobytes(), float(stretch), int(res), float(reach),
               None if planes is None else np.asarray(planes).tobytes(),
               int(region.get("ow_region_count", 0)), float(region.get("ow_region_slack", 0.0)))
        runs = self._runs.get(key)
        if runs is None:
            if len(self._runs) >= self.MAX_ENTRIES:
                self._runs.clear()
            runs = self._runs[key] = [(run.first, run.count, run.points) for run in
                                      footprint_ranges(draw, spheres, layer, stretch, res, region, reach)]
        return [replace(draw, first=first, count=count, points=points) for first, count, points in runs]


def footprint_ranges(draw: FootprintDraw, spheres: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
                     layer: Layer, stretch: float, res: int, region: dict | None = None,
                     reach: float = 0.0) -> list[FootprintDraw]:
    """One object's draw on one layer, by chunks of CHUNK_TRIANGLES: chunks that cannot
    reach the layer are left out; chunks whose footprint bound fits MAX_POINT_SIZE draw
    one point sprite a triangle instead of a six-vertex quad. `spheres` are the object's
    `chunk_spheres` (None: draw it whole as quads), `stretch` the layer's `map_stretch`.
    With a sized light's `reach` (the exact soft pass) footprints grow past a point sprite
    and past the layer's own half-space, so every chunk draws quads and only the region
    (already widened by the reach) leaves chunks out.
    Host work per chunk, not per triangle; the vertex stage still culls each triangle."""
    if spheres is None or not len(spheres[1]):
        return [draw]
    if draw.medium:
        region = {}  # a medium's crossings all count, past the receivers too (footprint_draws)
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
            out.append(replace(draw, first=first, count=count, points=kind == POINTS))
    return out


def footprint_draws(scene: ResidentScene, light: LightSpec, media: MediaFrame = NO_MEDIA) -> list[FootprintDraw]:
    """One draw per resident object: its matrix, and the light in its frame as double-single.
    A medium's part is drawn only in a frame that draws media (`media.on`), with its
    extinction in the frame's units and no occluder region: the maps' haze needs every
    crossing of a texel's ray, the ones past the receivers too (lib/media.glsl)."""
    draws = []
    for key, obj in scene.objects.items():
        if obj.triangles and (obj.medium is None or media.on):
            hi, lo = obj.light_split(light.position)
            uniforms = {"ow_object_linear": obj.matrix[:3, :3], "ow_light_hi": hi, "ow_light_lo": lo}
            if obj.alpha is not None:
                uniforms["ow_alpha_mode"] = obj.alpha.mode  # the see-through variant's
            if obj.medium is not None:
                uniforms.update(ow_medium_sigma=media.sigma_uniform(obj.medium), ow_region_count=0,
                                ow_media_offset=media.offset, **media.share_uniforms())
            draws.append(FootprintDraw(key, 0, obj.triangles, uniforms, pieces=obj.pieces,
                                       medium=obj.medium is not None))
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


def measurer(scene: ResidentScene, light: LightSpec, plan: Plan, settings: ShadowSettings, plan_far: float):
    """Host counts of a resident frame, for measurement only: the triangles the footprint
    pass keeps, summed over the drawn layers (not edge-on, inside the occluder region,
    in front of the layer: a paraboloid's hemisphere, a cube face's frustum), and the
    triangles seen edge-on, which cover nothing."""

    def measure() -> tuple[int, int]:
        kept, edge_on = [], 0
        for obj in scene.objects.values():
            if obj.pieces:
                continue  # counts of triangles: hair and points are not among them
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
