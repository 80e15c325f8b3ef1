"""One object per parameterization: how each plans a frame, maps and draws its layers,
and what its shadow test needs.

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
from ..core.plan import SCISSOR_EDGE_POINTS, Plan, layer_scissor, plan_frame, plan_projective, sun_upstream_reach
from ..core.samples import SampleStats
from ..core.scene import CameraSpec, LightSpec
from ..core.warping import LayerMapping
from .backend import AtlasLayout, FootprintDraw, ShadowBackend
from .footprint_runs import (  # noqa: F401  (map_stretch: the tests')
    FOOTPRINT_DILATE_TEXELS, RunMemo, chunk_spheres, measurer, footprint_ranges, map_stretch, sprites_pay)
from .frame import PreparedGeometry, ShadowSettings
from .pacing import Steps, drive
from .passes import exact as exact_rounds
from .passes.exact import EXACT_LIFT
from .resident import ResidentScene
from .shaders import EXACT_SOFT_KEY, NO_SPLIT, SLOTS
from .soft import exact_soft_uniforms, light_reach, sample_far
from .unfold import VERTEX_FLOATS, edge_aa_parameters, prepare_unfold

log = logging.getLogger(__name__)

# Near clip of cube faces, relative to far: geometry closer to the light than this
# is lost to clipping; 1e-6 keeps it far below a texel at any supported resolution.
CLIP_NEAR_RELATIVE = 1e-6





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
    runs: RunMemo | None = None  # the pipeline's kept chunk runs (footprint_runs.RunMemo)


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
                                measure=measurer(scene, light, plan, settings, near_far[1]))

    def scissor(self, plan: Plan, light: LightSpec, settings: ShadowSettings,
                mappings: dict[int, LayerMapping]) -> dict[int, tuple[int, int, int, int]]:
        return scissor_boxes(plan, light, settings, mappings)

    def draw(self, backend: ShadowBackend, inputs: DrawInputs) -> int:
        return drive(self.draw_steps(backend, inputs))

    def draw_steps(self, backend: ShadowBackend, inputs: DrawInputs) -> Steps[int]:
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
        spheres = {draw.key: chunk_spheres(inputs.scene.objects[draw.key], inputs.light) for draw in inputs.draws}
        passes = []  # (tile, draws, uniforms, scissor) per drawn layer
        for layer in inputs.plan.drawn:
            tile = inputs.tile_of_slot[layer.slot]
            mapping = inputs.mappings.get(layer.slot, LayerMapping.identity())
            uniforms = {**layer_uniforms(layer, inputs.geometry, res, inputs.layout.origin(tile), mapping,
                                         inputs.warp_size), **region}
            if exact:
                # The irregular z-buffer: the tile's lists are strip tile `tile` (link_lists).
                uniforms.update({**exact_rounds.map_uniforms(tile, inputs.count_work), **soft})
            elif mapping.warp is not None:
                yield from backend.build_ray_table_steps(tile, uniforms)
            # Only objects in chunks may draw point sprites, and only then is the stretch
            # needed: a GPU-built warp reads its numbers for it (footprint_runs.sprites_pay).
            sprites = reach == 0.0 and sprites_pay(mapping, inputs.draws, spheres)
            stretch = map_stretch(mapping) if sprites else math.inf
            ranges = inputs.runs.ranges if inputs.runs is not None else footprint_ranges
            draws = [run for draw in inputs.draws
                     for run in ranges(draw, spheres[draw.key], layer, stretch, res, region, reach)]
            scissor = inputs.boxes.get(layer.slot)
            yield from backend.draw_footprints_steps(tile, draws, uniforms, scissor=scissor, exact=exact)
            passes.append((tile, draws, uniforms, scissor))
        if exact:
            exact_rounds.hold_rounds(backend, inputs.layout, passes)
        return 0

    def test_uniforms(self, plan: Plan) -> dict:
        return {}


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

    def draw_steps(self, backend: ShadowBackend, inputs: DrawInputs) -> Steps[int]:
        yield from ()  # one draw of the unfolded stream: nothing to step between
        return self.draw(backend, inputs)

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
        return drive(self.draw_steps(backend, inputs))

    def draw_steps(self, backend: ShadowBackend, inputs: DrawInputs) -> Steps[int]:
        plan = inputs.plan
        # A sun's parallel rays: pieces' fragments run their texel's ray from the map's near
        # plane, not from the light (lib/footprint_ray.glsl's ow_piece_depth).
        uniforms = {**layer_uniforms(plan.drawn[0], inputs.geometry, inputs.settings.resolution,
                                     inputs.layout.origin(0), LayerMapping.identity(), 0),
                    **inputs.region, **self.test_uniforms(plan), "ow_sun": int(inputs.light.emission == "sun"),
                    "ow_light_axis": inputs.light.axis}  # a sun's media: places along its axis
        if inputs.settings.exact:
            self._draw_exact(backend, inputs, uniforms)
            return 0
        yield from backend.draw_footprints_steps(0, inputs.draws, uniforms)
        return 0

    @staticmethod
    def _draw_exact(backend: ShadowBackend, inputs: DrawInputs, uniforms: dict) -> None:
        """The irregular z-buffer over the map: every triangle over a conservative
        cover of its image (footprint.vert's ow_projective_quad), walking the lists of the
        map's texels (tile 0, linked through the map's matrix). A spot's triangle is clipped
        to the map's front, w >= CLIP_NEAR_RELATIVE * far (the map's w is the depth along the
        spot's axis); a sun's map has w = 1 and clips nothing. The covers are quads: their
        size in texels has no bound here that would fit a point sprite."""
        light = inputs.light
        sun = light.emission == "sun"
        soft = exact_soft_uniforms(light, inputs.settings, sample_far(inputs.plan, light))
        uniforms = {**uniforms, **exact_rounds.map_uniforms(0, inputs.count_work), "ow_sun": int(sun),
                    "ow_light_axis": light.axis,
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
        exact_rounds.hold_rounds(backend, inputs.layout, [(0, inputs.draws, uniforms, None)])

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
        "ow_dilate": FOOTPRINT_DILATE_TEXELS,
        "ow_edge_on_distance": footprint.EDGE_ON_SCENE * geometry.far,
        "ow_crop": mapping.crop_vec4(),
        "ow_near": geometry.near,
        "ow_far": geometry.far,
        "ow_clip_near": geometry.far * CLIP_NEAR_RELATIVE,
        "ow_resolution": float(res),
        "ow_tile_origin": (float(origin[0]), float(origin[1])),
        "ow_unfold_split": NO_SPLIT,
        "ow_unfold_halves": 1,
        "ow_projective": 0,
        "ow_map_inverted": 0,
        "ow_map_matrix": np.eye(4),
    }


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
