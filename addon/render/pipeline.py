"""The shadow pipeline of one frame, over any `ShadowBackend` (DESIGN.md section 3).

  plan -> prepare geometry (sanitise, seam split, tessellate, cull per layer)
       -> shadow maps (one atlas tile per drawn layer) -> shadow test per sample.

Everything is light-centred before it is turned into float32: subtracting the
light position in float64 keeps precision at large scene scales.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..core import frames, projection, tessellate
from ..core.errors import InputError
from ..core.frames import Layer, Parameterization
from ..core.plan import Plan, plan_frame
from ..core.scene import CameraSpec, LightSpec
from .backend import AtlasLayout, ShadowBackend

log = logging.getLogger(__name__)

MIN_RESOLUTION = 16
MAX_RESOLUTION = 4096
# Near clip of cube faces, relative to far: geometry closer to the light than this
# is lost to clipping; 1e-6 keeps it far below a texel at any supported resolution.
CLIP_NEAR_RELATIVE = 1e-6


@dataclass(frozen=True)
class BiasSettings:
    """Bias in units of one texel's footprint at the sample (see shadow_test.frag)."""

    constant: float = 0.3
    slope: float = 0.7
    normal: float = 0.7


@dataclass(frozen=True)
class ShadowSettings:
    parameterization: Parameterization
    resolution: int
    bias: BiasSettings = BiasSettings()
    cull: bool = True
    tessellation_tolerance: float = 1.0  # texels of chord-to-arc bend

    def __post_init__(self) -> None:
        if self.parameterization not in ("dpsm", "cube"):
            raise InputError(f"unknown parameterization {self.parameterization!r}; use 'dpsm' or 'cube'")
        if not (MIN_RESOLUTION <= int(self.resolution) <= MAX_RESOLUTION):
            raise InputError(f"resolution {self.resolution} out of range [{MIN_RESOLUTION}, {MAX_RESOLUTION}]")


@dataclass
class ViewSamples:
    """Per-pixel view samples; row 0 is the TOP image row (as the reference stores it)."""

    positions: np.ndarray  # (H, W, 3) world
    normals: np.ndarray  # (H, W, 3) world, unit
    hit: np.ndarray  # (H, W) bool
    camera: CameraSpec


@dataclass
class PreparedGeometry:
    """Per-layer float32 vertex streams and counts, ready to draw."""

    streams: dict[int, np.ndarray]  # slot -> (n, 9) float32
    near: float
    far: float
    skipped_triangles: int
    tessellated_triangles: int  # triangles added by tessellation

    @property
    def triangles_drawn(self) -> int:
        return int(sum(len(s) for s in self.streams.values()) // 3)


@dataclass
class FrameResult:
    visibility: np.ndarray  # (H, W) float32, 1 lit / 0 shadowed, row 0 at the top
    flags: np.ndarray  # (H, W) int8: 0 tested, 1 no geometry, 2 outside emission, 3 layer not drawn
    time_ms: dict[str, float]
    plan: Plan
    geometry: PreparedGeometry
    layout: AtlasLayout | None
    texels: int
    atlas: np.ndarray | None = None
    tile_of_slot: dict[int, int] = field(default_factory=dict)

    @property
    def passes(self) -> int:
        return len(self.plan.drawn)


def _vertex_stream(tris_centred: np.ndarray) -> np.ndarray:
    """(n*3, 9) float32: position, plane (normal, offset) and distance range per vertex."""
    if len(tris_centred) == 0:
        return np.zeros((0, 9), dtype=np.float32)
    normal = np.cross(tris_centred[:, 1] - tris_centred[:, 0], tris_centred[:, 2] - tris_centred[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    offset = np.einsum("ij,ij->i", normal, tris_centred[:, 0])
    # Distance bounds over the triangle: the plane distance below (the nearest point
    # may be interior), the farthest corner above (distance is convex).
    lo = np.abs(offset)
    hi = np.linalg.norm(tris_centred, axis=2).max(axis=1)
    per_tri = np.concatenate([normal, offset[:, None], lo[:, None], hi[:, None]], axis=1)
    stream = np.concatenate([tris_centred, np.repeat(per_tri[:, None, :], 3, axis=1)], axis=2)
    return stream.reshape(-1, 9).astype(np.float32)


def _cull_to_face(local_tris: np.ndarray) -> np.ndarray:
    """Keep triangles not entirely outside one side plane of a 90 degree face frustum."""
    x, y, z = local_tris[..., 0], local_tris[..., 1], local_tris[..., 2]
    outside = (np.all(x > z, axis=1) | np.all(-x > z, axis=1) | np.all(y > z, axis=1)
               | np.all(-y > z, axis=1) | np.all(z <= 0.0, axis=1))
    return ~outside


def prepare_geometry(light: LightSpec, triangles: np.ndarray, plan: Plan, settings: ShadowSettings) -> PreparedGeometry:
    """Sanitise, split, tessellate and cull the scene's triangles for every drawn layer."""
    light_pos = light.position
    near, far = projection.depth_range(triangles, light_pos)
    tris, report = tessellate.sanitize(triangles, light_pos, scale=max(far, 1e-30))
    centred = tris - light_pos
    streams: dict[int, np.ndarray] = {}
    added = 0
    res = settings.resolution
    if settings.parameterization == "dpsm":
        # Split once at the seam plane of side 0 (whose +z is the light's -Z axis).
        side0 = frames.light_layers(light, "dpsm")[0]
        front, back = tessellate.split_at_seam(side0.to_local(centred))
        # Side 1's frame is diag(1, -1, -1) times side 0's, so flip y and z of the back pieces.
        pieces = {0: front, 1: back * np.array([1.0, -1.0, -1.0])}

        def to_texels(points: np.ndarray) -> np.ndarray:
            return projection.xy_to_texel(projection.paraboloid_project(points), res)

        for layer in plan.drawn:
            local = pieces[layer.slot]
            refined, n_added = tessellate.tessellate(local, to_texels, settings.tessellation_tolerance)
            added += n_added
            world_dir = refined @ layer.rotation  # layer local -> light-centred world
            streams[layer.slot] = _vertex_stream(world_dir)
    else:
        for layer in plan.drawn:
            local = layer.to_local(centred)
            keep = _cull_to_face(local) if settings.cull else np.ones(len(local), dtype=bool)
            streams[layer.slot] = _vertex_stream(centred[keep])
    return PreparedGeometry(streams, near, far, report.skipped, added)


def _layer_uniforms(layer: Layer, geometry: PreparedGeometry, res: int, origin: tuple[int, int]) -> dict:
    return {
        "ow_layer_rot": layer.rotation,
        "ow_layer_kind": layer.kind,
        "ow_near": geometry.near,
        "ow_far": geometry.far,
        "ow_clip_near": geometry.far * CLIP_NEAR_RELATIVE,
        "ow_resolution": float(res),
        "ow_tile_origin": (float(origin[0]), float(origin[1])),
    }


class ShadowPipeline:
    """Runs frames on one backend."""

    def __init__(self, backend: ShadowBackend) -> None:
        self.backend = backend

    def render(self, light: LightSpec, triangles: np.ndarray, samples: ViewSamples, settings: ShadowSettings,
               keep_atlas: bool = False) -> FrameResult:
        """One frame: plan, maps, test. Times each stage with a GPU sync."""
        backend = self.backend
        timings: dict[str, float] = {"analysis": 0.0}
        t0 = time.perf_counter()
        _, far_estimate = projection.depth_range(triangles, light.position)
        plan = plan_frame(light, settings.parameterization, samples.camera, samples.positions, samples.hit,
                          far_estimate, cull=settings.cull)
        geometry = prepare_geometry(light, triangles, plan, settings)
        t1 = time.perf_counter()
        timings["prepare"] = (t1 - t0) * 1e3

        res = settings.resolution
        tile_of_slot = {layer.slot: i for i, layer in enumerate(plan.drawn)}
        layout = AtlasLayout.for_tiles(res, len(plan.drawn), backend.max_texture_size())
        backend.begin_atlas(layout)
        for layer in plan.drawn:
            origin = layout.origin(tile_of_slot[layer.slot])
            backend.draw_layer(tile_of_slot[layer.slot], geometry.streams[layer.slot],
                               _layer_uniforms(layer, geometry, res, origin))
        backend.finish()
        t2 = time.perf_counter()
        timings["shadow_maps"] = (t2 - t1) * 1e3

        result = self._shadow_test(light, samples, settings, plan, geometry, layout, tile_of_slot)
        backend.finish()
        t3 = time.perf_counter()
        timings["shadow_test"] = (t3 - t2) * 1e3
        timings["total"] = (t3 - t0) * 1e3

        atlas = backend.read_atlas() if keep_atlas else None
        visibility = result[..., 0][::-1].copy()
        flags = result[..., 1][::-1].astype(np.int8)
        return FrameResult(visibility, flags, timings, plan, geometry, layout,
                           texels=len(plan.drawn) * res * res, atlas=atlas, tile_of_slot=tile_of_slot)

    def _shadow_test(self, light: LightSpec, samples: ViewSamples, settings: ShadowSettings, plan: Plan,
                     geometry: PreparedGeometry, layout: AtlasLayout, tile_of_slot: dict[int, int]) -> np.ndarray:
        n_slots = 6
        rotations = np.tile(np.eye(3), (n_slots, 1, 1))
        tiles = np.zeros((n_slots, 4))
        for layer in plan.all_layers:
            rotations[layer.slot] = layer.rotation
        for slot, tile in tile_of_slot.items():
            x, y = layout.origin(tile)
            tiles[slot] = (x, y, 1.0, 0.0)
        kind = projection.PARABOLOID if settings.parameterization == "dpsm" else projection.CUBE
        uniforms = {
            "ow_light_rot": light.rotation.T,
            "ow_layer_rot": rotations,
            "ow_layer_tile": tiles,
            "ow_param": 0 if settings.parameterization == "dpsm" else 1,
            "ow_layer_kind": kind,
            "ow_hemi": 1 if light.emission == "hemi" else 0,
            "ow_resolution": float(settings.resolution),
            "ow_near": geometry.near,
            "ow_far": geometry.far,
            "ow_bias_const": settings.bias.constant,
            "ow_bias_slope": settings.bias.slope,
            "ow_bias_normal": settings.bias.normal,
        }
        height, width = samples.hit.shape
        pos = np.zeros((height, width, 4), dtype=np.float32)
        nrm = np.zeros((height, width, 4), dtype=np.float32)
        hit = samples.hit & np.all(np.isfinite(samples.positions), axis=-1)
        centred = np.where(hit[..., None], samples.positions - light.position, 0.0)
        pos[..., :3] = centred
        pos[..., 3] = hit
        nrm[..., :3] = np.where(hit[..., None], samples.normals, 0.0)
        # GL textures start at the bottom row; the samples start at the top.
        return self.backend.shadow_test(pos[::-1], nrm[::-1], uniforms)
