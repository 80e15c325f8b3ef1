"""The shadow pipeline of one frame, over any `ShadowBackend` (DESIGN.md section 3).

  plan -> prepare geometry (sanitise, seam split, tessellate, cull per layer)
       -> shadow maps (one atlas tile per drawn layer) -> shadow test per sample.

Everything is light-centred before it is turned into float32: subtracting the
light position in float64 keeps precision at large scene scales.
"""
from __future__ import annotations

import logging
import math
import time
import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..core import footprint, frames, perspective, projection, tessellate, validate
from ..core import methods as method_registry
from ..core.errors import InputError
from ..core.frames import POINT_PARAMETERIZATIONS, PROJECTIVE_PARAMETERIZATIONS, Layer, Parameterization
from ..core.plan import (
    REGION_SLACK,
    SCISSOR_EDGE_POINTS,
    Plan,
    hit_points,
    layer_scissor,
    outside_region,
    plan_frame,
    plan_projective,
)
from ..core.scene import CameraSpec, LightSpec
from ..core.warping import (
    FLOOR_SHARE,
    MAX_SLOPE,
    LayerMapping,
    Warp,
    WarpParams,
    dv_crop_from_counts,
    max_shear,
    notw_cols,
    notw_rows,
    rtw_from_counts,
    singular_values_2x2,
)
from .backend import AtlasLayout, FootprintDraw, ShadowBackend
from .resident import ResidentScene
from .shaders import REGION_PLANES

log = logging.getLogger(__name__)

MIN_RESOLUTION = 16
MAX_RESOLUTION = 4096
# Floats per vertex of a depth-pass stream: light-centred position (3), then the
# triangle's plane (unit normal, offset), repeated on its three vertices.
VERTEX_FLOATS = 7
# Near clip of cube faces, relative to far: geometry closer to the light than this
# is lost to clipping; 1e-6 keeps it far below a texel at any supported resolution.
CLIP_NEAR_RELATIVE = 1e-6


WARP_KINDS = ("none", "notw", "rtw")
_PARAM_CODES = {"dpsm": 0, "cube": 1, "ipsm": 2, "unfold": 3, "sm": 4, "psm": 5}  # ow_param (lib/layers.glsl)
# A triangle drawn whole into the unfold half of its nearer pole must keep clear of
# the opposite pole, where the projection is singular (the pole becomes the rim).
# Beyond this angle from the pole, or covering the opposite pole, it is split at the
# seam instead (docs/unfold_psm.md).
UNFOLD_WHOLE_MAX_ANGLE = math.radians(120.0)


def analysis_size_for(resolution: int) -> int:
    """Count-map side A for a map resolution: an eighth of the map, within [64, 256].

    The chosen smoothing windows span tens of rows even at A = 128 (docs/warping.md),
    so a finer count map adds cost (scatter, read-back, per-row work, tessellation
    against more kinks) without changing the measured error beyond noise.
    """
    return int(min(256, max(64, resolution // 8)))


# The largest bias accepted, in texel footprints: far beyond any useful value (the UI's
# soft range ends at 4), and below it Blender's FLT_MAX for an infinite value is refused.
MAX_BIAS = 100.0


@dataclass(frozen=True)
class BiasSettings:
    """Bias in units of one texel's footprint at the sample (see shadow_test.frag)."""

    constant: float = 0.3
    slope: float = 0.7
    normal: float = 0.7

    def __post_init__(self) -> None:
        # NaN or inf would shadow (or light) every pixel without a word: refuse it by name.
        for name in ("constant", "slope", "normal"):
            value = validate.finite_number(f"bias {name}", getattr(self, name), 0.0, MAX_BIAS)
            object.__setattr__(self, name, value)


@dataclass(frozen=True)
class ShadowSettings:
    parameterization: Parameterization
    resolution: int
    bias: BiasSettings = BiasSettings()
    cull: bool = True
    tessellation_tolerance: float = 1.0  # texels of chord-to-arc bend
    warp: str = "none"  # "none", "notw" or "rtw"
    analysis_size: int | None = None  # count-map side A; None = analysis_size_for(resolution)
    cut: bool = False  # ipsm only: skewed axis and a crop fitted to the frustum (thesis 4.1.4)
    edge_aa: bool = False  # unfold only: the paper's edge-distance antialiasing (edge_aa_parameters)

    def __post_init__(self) -> None:
        known = POINT_PARAMETERIZATIONS + PROJECTIVE_PARAMETERIZATIONS
        if self.parameterization not in known:
            raise InputError(f"unknown parameterization {self.parameterization!r}; use one of {', '.join(known)}")
        if self.warp != "none" and not frames.takes_warp(self.parameterization):
            raise InputError(f"{self.parameterization} takes no warp; warps apply to "
                             f"{', '.join(frames.WARPABLE_PARAMETERIZATIONS)}")
        if self.edge_aa and self.parameterization != "unfold":
            raise InputError("edge-distance antialiasing is the unfold method's option (unfold+aa)")
        if self.warp not in WARP_KINDS:
            raise InputError(f"unknown warp {self.warp!r}; use one of {', '.join(WARP_KINDS)}")
        if not (MIN_RESOLUTION <= int(self.resolution) <= MAX_RESOLUTION):
            raise InputError(f"resolution {self.resolution} out of range [{MIN_RESOLUTION}, {MAX_RESOLUTION}]")
        if not isinstance(self.bias, BiasSettings):
            raise InputError(f"bias must be a BiasSettings, got {type(self.bias).__name__}")
        validate.finite_number("tessellation tolerance (texels)", self.tessellation_tolerance, 1e-3, 1e3)


def settings_for(method: str, resolution: int, **fields) -> ShadowSettings:
    """The `ShadowSettings` of a registered pipeline method (`core/methods.py`) at `resolution`.

    `fields` sets the other settings (cull, bias, ...); the method's own ones
    (parameterization, warp, cut, edge_aa) come from its registry entry only.
    """
    entry = method_registry.method(method)
    if entry.parameterization is None:
        raise InputError(f"{method} is measured outside the pipeline; it has no shadow-map settings")
    return ShadowSettings(entry.parameterization, resolution, warp=entry.warp, cut=entry.cut,
                          edge_aa=entry.edge_aa, **fields)


# Largest importance weight one view sample may carry: weights travel in a float32
# (the positions' w), exact for integers far beyond this, and relative weights need
# no more range.
MAX_IMPORTANCE = 65536.0
# The scatter sums weights in 32-bit unsigned counters; all samples may land in one
# texel (stress_one_texel), so the total over the frame must fit one.
MAX_IMPORTANCE_TOTAL = 2**32 - 1


@dataclass
class ViewSamples:
    """Per-pixel view samples; row 0 is the TOP image row (as the reference stores it).

    `importance` weights each sample in the warp analysis (thesis 4.2.1: the warp
    follows an importance, and the count map is its plain stand-in): a sample of
    weight k counts as k samples in the count maps the warps are built from. None
    means 1 everywhere, the thesis's count map. The count statistics of a frame
    (max_count_before/after) always count samples, not weights.
    """

    positions: np.ndarray  # (H, W, 3) world
    normals: np.ndarray  # (H, W, 3) world, unit
    hit: np.ndarray  # (H, W) bool
    camera: CameraSpec | None  # None: no camera (no view frustum), so no layer culling
    importance: np.ndarray | None = None  # (H, W) weights in [1, MAX_IMPORTANCE], rounded to integers

    def importance_weights(self) -> np.ndarray | None:
        """The importance as rounded float32 weights, checked; None when not given.

        Raises InputError naming the problem: a shape other than the hit mask's, a
        weight that is not finite or lies outside [1, MAX_IMPORTANCE] on a hit pixel,
        or hit weights that sum past MAX_IMPORTANCE_TOTAL.
        """
        if self.importance is None:
            return None
        weights = np.asarray(self.importance, dtype=np.float64)
        if weights.shape != self.hit.shape:
            raise InputError(f"importance has shape {weights.shape}; the view samples are {self.hit.shape}")
        used = weights[self.hit]
        bad = ~(np.isfinite(used) & (used >= 1.0) & (used <= MAX_IMPORTANCE))
        if bad.any():
            raise InputError(f"importance weights must be finite and in [1, {MAX_IMPORTANCE:g}]; "
                             f"{int(bad.sum())} hit pixels are not (first: {used[bad][0]!r})")
        rounded = np.rint(weights)
        total = float(rounded[self.hit].sum())
        if total > MAX_IMPORTANCE_TOTAL:
            raise InputError(f"importance weights sum to {total:.0f}; a count-map texel holds at most "
                             f"{MAX_IMPORTANCE_TOTAL} (2^32 - 1), and every sample may land in one")
        return rounded.astype(np.float32)


@dataclass
class PreparedGeometry:
    """What a frame drew: the depth range, and either resident footprints or (unfold)
    host-built vertex streams."""

    streams: dict[int, np.ndarray]  # unfold: slot 0 -> (n, VERTEX_FLOATS) float32, both halves
    near: float
    far: float
    skipped_at_upload: int  # unfold: every sanitised triangle; resident: non-finite and zero-area ones
    tessellated_triangles: int  # triangles added by tessellation (unfold only)
    unfold_split: int = -1  # unfold: the first vertex of half 1 in the one stream; -1 otherwise
    # Resident frames: counts, on the host and only when asked (a measurement, never part
    # of a timed frame), the triangles past the GPU's culling and those seen edge-on.
    measure: Callable[[], tuple[int, int]] | None = None
    _measured: tuple[int, int] | None = None

    def _counts(self) -> tuple[int, int]:
        if self._measured is None:
            self._measured = self.measure()
        return self._measured

    @property
    def triangles_drawn(self) -> int:
        """Triangles drawn, summed over the layers (after culling and, for unfold, tessellation)."""
        if self.measure is None:
            return int(sum(len(s) for s in self.streams.values()) // 3)
        return self._counts()[0]

    @property
    def skipped_triangles(self) -> int:
        """Triangles that cannot cast a shadow: non-finite, zero-area, or seen edge-on from the light."""
        return self.skipped_at_upload + (self._counts()[1] if self.measure is not None else 0)


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
    mappings: dict[int, LayerMapping] = field(default_factory=dict)
    count_maps: dict[int, np.ndarray] = field(default_factory=dict)  # analysis count map per slot
    boxes: dict[int, tuple[int, int, int, int]] = field(default_factory=dict)  # slot -> readable texel box

    @property
    def passes(self) -> int:
        return self.plan.passes


def _vertex_stream(tris_centred: np.ndarray) -> np.ndarray:
    """(n*3, VERTEX_FLOATS) float32: position and plane (normal, offset) per vertex."""
    if len(tris_centred) == 0:
        return np.zeros((0, VERTEX_FLOATS), dtype=np.float32)
    normal = np.cross(tris_centred[:, 1] - tris_centred[:, 0], tris_centred[:, 2] - tris_centred[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    offset = np.einsum("ij,ij->i", normal, tris_centred[:, 0])
    per_tri = np.concatenate([normal, offset[:, None]], axis=1)
    stream = np.concatenate([tris_centred, np.repeat(per_tri[:, None, :], 3, axis=1)], axis=2)
    return stream.reshape(-1, VERTEX_FLOATS).astype(np.float32)


def _map_texels(kind: int, mapping: LayerMapping, res: int):
    """Layer-local points -> texel coordinates of the final (cropped, warped) map."""

    def to_texels(points: np.ndarray) -> np.ndarray:
        return mapping.forward(projection.project(kind, points)) * res

    return to_texels


# Seam-cut pieces reach this many texels past the seam (tessellate.split_at_seam):
# one for the texel ring straddling the rim, one for the chord's sag (the bend
# tolerance), half for the normal offset.
SEAM_OVERLAP_TEXELS = 2.5


def seam_overlap(kind: int, res: int) -> float:
    """Angle (radians) that a side's seam-cut pieces reach past the seam: SEAM_OVERLAP_TEXELS
    texels of that map at the seam (a paraboloid's rim, an unfold half's equator)."""
    at_seam = np.array([[1.0, 0.0]]) if kind == projection.PARABOLOID else np.array([[0.5, 0.0]])
    return SEAM_OVERLAP_TEXELS * float(projection.texel_angle(kind, at_seam, res)[0])


def texel_angle_floor(kind: int, mapping: LayerMapping, res: int) -> float:
    """A lower bound of one texel's angle anywhere inside a (cropped, warped) map.

    Plain maps: 2/res at a paraboloid's rim, (2/res)/sqrt(3) at a cube face's corner.
    The crop and the warp shrink it by at most their largest stretch; the warp's is
    taken at the cell centres and doubled, as its Jacobian is piecewise bilinear.
    """
    if kind == projection.UNFOLD:
        # Tangentially pi sin(theta)/theta per unit of map radius, smallest at the widest
        # angle a drawn triangle reaches (UNFOLD_WHOLE_MAX_ANGLE; split pieces stay within 90).
        theta = UNFOLD_WHOLE_MAX_ANGLE
        base = 2.0 / res * math.pi * math.sin(theta) / theta
    else:
        base = 2.0 / res if kind == projection.PARABOLOID else 2.0 / res / math.sqrt(3.0)
    stretch = float(np.max(mapping.scale))
    if mapping.warp is not None:
        size = mapping.warp.size
        centres = (np.arange(size) + 0.5) / size
        grid = np.stack(np.meshgrid(centres, centres), axis=-1).reshape(-1, 2)
        stretch *= 2.0 * float(singular_values_2x2(mapping.warp.jacobian(grid))[0].max())
    return base / stretch


def prepare_unfold(light: LightSpec, triangles: np.ndarray, plan: Plan, settings: ShadowSettings,
                   depth_range: tuple[float, float]) -> PreparedGeometry:
    """The unfold method's one vertex stream, built on the host: sanitised, culled, split
    and tessellated (the other point methods draw resident footprints instead).

    The unfold draw picks each triangle's half in the vertex stage and interpolates its
    projection, so its coverage still comes from tessellated chords (docs/unfold_psm.md).
    """
    near, far = depth_range
    tris, report = tessellate.sanitize(triangles, light.position, scale=max(far, 1e-30))
    if settings.cull:
        # Object culling: only triangles inside conv(light, view frustum) can shadow
        # something in view (docs/culling.md).
        tris = tris[~outside_region(tris, plan.occluder_planes)]
    stream, split, added = _unfold_stream(tris - light.position, plan, settings)
    return PreparedGeometry({0: stream} if plan.drawn else {}, near, far, report.skipped, added, split)


def _contains_ray(tris: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """(T,) True where the ray from the origin along `direction` meets the triangle
    (Moller-Trumbore with the origin as ray start; edges count as inside)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = b - a, c - a
    pvec = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, pvec)
    ok = np.abs(det) > 1e-300
    inv = 1.0 / np.where(ok, det, 1.0)
    tvec = -a
    u = np.einsum("ij,ij->i", tvec, pvec) * inv
    qvec = np.cross(tvec, e1)
    v = (qvec @ direction) * inv
    t = np.einsum("ij,ij->i", e2, qvec) * inv
    return ok & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > 0.0)


def _unfold_stream(centred: np.ndarray, plan: Plan, settings: ShadowSettings) -> tuple[np.ndarray, int, int]:
    """One vertex stream for both unfold halves: half 0's triangles, then half 1's.

    Dual sphere-unfolding draws each triangle whole into the half of its nearer pole
    (by the mean of its corner directions). Alone that leaves pinholes along the
    edges shared by triangles of different halves: a direction on such an edge is
    looked up in one half, whose texel centre may fall on the neighbour's side,
    which that half never drew. So each half also gets the pieces, cut at the seam
    (reaching a little past it, see `seam_overlap`), of the triangles on its side that
    went to the other half; a lookup in the half of
    the direction's own hemisphere then sees every occluder. Triangles reaching past
    UNFOLD_WHOLE_MAX_ANGLE from their pole, or covering the opposite pole, are cut at
    the seam instead of drawn whole. All of it is still one draw call.
    """
    res = settings.resolution
    local = plan.all_layers[0].to_local(centred)  # half 0's frame: +z is its pole
    if len(plan.drawn) == 1:
        # Hemispherical light: only half 0; nothing behind the light plane can shadow.
        halves = [tessellate.split_at_seam(local, seam_overlap(projection.UNFOLD, res))[0]]
    else:
        z = projection.unit_directions(local)[..., 2]
        nearer0 = z.mean(axis=1) >= 0.0
        limit = math.cos(UNFOLD_WHOLE_MAX_ANGLE)
        reach = np.where(nearer0, z.min(axis=1) < limit, -z.max(axis=1) < limit)
        reach |= np.where(nearer0, _contains_ray(local, np.array([0.0, 0.0, -1.0])),
                          _contains_ray(local, np.array([0.0, 0.0, 1.0])))
        straddle = (z.max(axis=1) > 0.0) & (z.min(axis=1) < 0.0)
        whole0, whole1 = nearer0 & ~reach, ~nearer0 & ~reach
        overlap = seam_overlap(projection.UNFOLD, res)
        front_of_1, _ = tessellate.split_at_seam(local[(whole1 & straddle) | reach], overlap)
        _, back_of_0 = tessellate.split_at_seam(local[(whole0 & straddle) | reach], overlap)
        halves = [np.concatenate([local[whole0], front_of_1]),
                  np.concatenate([local[whole1], back_of_0]) * np.array([1.0, -1.0, -1.0])]
    streams, added = [], 0
    mapping = LayerMapping.identity()
    for layer, tris in zip(plan.drawn, halves):
        refined, n_added = tessellate.tessellate(tris, _map_texels(layer.kind, mapping, res),
                                                 settings.tessellation_tolerance, window=float(res),
                                                 texel_angle_floor=texel_angle_floor(layer.kind, mapping, res))
        added += n_added
        streams.append(_vertex_stream(refined @ layer.rotation))
    split = len(streams[0]) if streams else 0
    return (np.concatenate(streams) if streams else np.zeros((0, VERTEX_FLOATS), np.float32)), split, added


def _layer_uniforms(layer: Layer, geometry: PreparedGeometry, res: int, origin: tuple[int, int],
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


# Texels a footprint box grows by on each side: its float32 corners may fall short of the
# exact box by rounding (about 1e-4 map units, 2e-3 next to the light), and a texel
# centre left outside would lose its triangle (lib/footprint.glsl).
FOOTPRINT_DILATE_TEXELS = 1.0


def footprint_draws(scene: ResidentScene, light: LightSpec) -> list[FootprintDraw]:
    """One draw per resident object: its matrix, light-centred in float64 on the host."""
    return [FootprintDraw(key, 0, obj.triangles, {"ow_object_linear": obj.matrix[:3, :3],
                                                  "ow_object_offset": obj.offset(light.position),
                                                  "ow_edge_on_distance": obj.edge_on_distance(light.position)})
            for key, obj in scene.objects.items() if obj.triangles]


def _region_uniforms(plan: Plan, light: LightSpec, cull: bool) -> dict:
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


def _measurer(scene: ResidentScene, light: LightSpec, plan: Plan, settings: ShadowSettings):
    """Host counts of a resident frame, for measurement only: the triangles the footprint
    pass keeps, summed over the drawn layers (not edge-on, inside the occluder region,
    in front of the layer: a paraboloid's hemisphere, a cube face's frustum), and the
    triangles seen edge-on, which cover nothing."""

    def measure() -> tuple[int, int]:
        kept, edge_on = [], 0
        for obj in scene.objects.values():
            tris = obj.world_triangles() - light.position
            if plan.projective is None and len(tris):
                _, orientation = footprint.edge_planes(tris, obj.edge_on_distance(light.position))
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


def _stack_tables(mappings: dict[int, LayerMapping], size: int) -> tuple[np.ndarray, np.ndarray]:
    """Slot-major (6 * A, A + 1) tables of every layer's row and column offsets."""
    rows = np.zeros((6 * size, size + 1), dtype=np.float32)
    cols = np.zeros((6 * size, size + 1), dtype=np.float32)
    for slot, mapping in mappings.items():
        if mapping.warp is not None:
            rows[slot * size:(slot + 1) * size] = mapping.warp.rows
            cols[slot * size:(slot + 1) * size] = mapping.warp.cols
    return rows, cols


# Read-only triangle arrays a pipeline keeps resident at once (ShadowPipeline._scene_of):
# a few lights, each with its own selection of blockers.
MAX_HELD_SOUPS = 8


class ShadowPipeline:
    """Runs frames on one backend."""

    def __init__(self, backend: ShadowBackend) -> None:
        self.backend = backend
        # Read-only triangle arrays seen lately (the viewport's per-light selections, which
        # stay the same object while the scene is unchanged) -> their resident scenes.
        self._soups: OrderedDict[int, tuple[weakref.ref, ResidentScene]] = OrderedDict()

    def _scene_of(self, triangles: np.ndarray) -> tuple[ResidentScene, bool]:
        """A resident scene for a triangle array, and whether it is for this frame only.

        A read-only array cannot change in place, so the same array object gets the same
        scene (nothing uploaded again); any other array is uploaded for one frame.
        """
        array = np.asarray(triangles)
        if array is not triangles or array.flags.writeable:
            return ResidentScene.of_triangles(array), True
        held = self._soups.get(id(array))
        if held is not None and held[0]() is array:
            self._soups.move_to_end(id(array))
            return held[1], False
        scene = ResidentScene.of_triangles(array)
        self._soups[id(array)] = (weakref.ref(array), scene)
        while len(self._soups) > MAX_HELD_SOUPS:
            _, (_, old) = self._soups.popitem(last=False)
            self.backend.release_scene(old)
        return scene, False

    def release(self) -> None:
        """Free the resident scenes this pipeline made for read-only arrays."""
        for _, scene in self._soups.values():
            self.backend.release_scene(scene)
        self._soups.clear()

    def count_maps(self, light: LightSpec, plan: Plan, mappings: dict[int, LayerMapping], size: int,
                   mode: int, weighted: bool = False) -> dict[int, np.ndarray]:
        """GPU count maps (row 0 = v = 0) of the uploaded samples, one per drawn layer of `plan`.

        mode 0: after each layer's crop only; 1: through the row warps; 2: through the
        full warp. A layer missing from `mappings` counts uncropped. The warp tables must
        already be uploaded for modes 1 and 2. All layers share one dispatch.
        `weighted` sums the samples' importance weights instead of counting them.
        """
        slots = plan.drawn_slots
        rotations, crops = _slot_rotations_and_crops(plan, mappings)
        tiles = np.full(SLOTS, -1, dtype=np.int64)
        tiles[slots] = np.arange(len(slots))
        warp_size = max((m.warp.size for m in mappings.values() if m.warp is not None), default=0)
        uniforms = {
            "ow_light_rot": light.rotation.T,
            "ow_layer_rot": rotations,
            "ow_layer_crop": crops,
            "ow_slot_tile": tiles,
            "ow_layer_kind": plan.layer_kind,
            "ow_param": _PARAM_CODES[plan.parameterization],
            "ow_hemi": 1 if light.emission == "hemi" else 0,
            "ow_warp_size": warp_size,
            "ow_scatter_mode": mode,
            "ow_count_size": size,
            "ow_weighted": int(weighted),
        }
        strip = self.backend.scatter_counts(size, max(len(slots), 1), uniforms)
        return {slot: strip[:, tile * size:(tile + 1) * size].copy() for tile, slot in enumerate(slots)}

    def _analyse(self, light: LightSpec, settings: ShadowSettings, plan: Plan) -> tuple[dict, dict]:
        """DV crop and warp construction for every drawn layer (Algorithm 3, steps 2-7).

        Each step scatters all layers at once: 3 dispatches for NoTW, 2 for RTW. The
        counts sum the samples' importance weights (1 each unless ViewSamples.importance
        says otherwise); the DV crop only asks which cells are occupied.
        """
        size = settings.analysis_size or analysis_size_for(settings.resolution)
        whole = self.count_maps(light, plan, {}, size, 0)  # mode 0 reads no warp table
        crops = {slot: LayerMapping(*dv_crop_from_counts(counts), None) for slot, counts in whole.items()}
        counts = self.count_maps(light, plan, crops, size, 0, weighted=True)
        mappings: dict[int, LayerMapping] = {}
        if settings.warp == "rtw":
            for slot, crop in crops.items():
                mappings[slot] = LayerMapping(crop.lo, crop.hi, rtw_from_counts(counts[slot]))
        else:
            rows = {slot: notw_rows(counts[slot]) for slot in crops}
            row_only = {slot: LayerMapping(crop.lo, crop.hi, _warp_of(rows[slot][0], None, size))
                        for slot, crop in crops.items()}
            self.backend.set_warp_tables(*_stack_tables(row_only, size))
            after_rows = self.count_maps(light, plan, row_only, size, 1, weighted=True)
            for slot, crop in crops.items():
                cols, col_window = notw_cols(after_rows[slot])
                row_table, row_window = rows[slot]
                mappings[slot] = LayerMapping(crop.lo, crop.hi,
                                              _warp_of(row_table, cols, size, row_window, col_window))
        self.backend.set_warp_tables(*_stack_tables(mappings, size))
        return mappings, counts

    def render(self, light: LightSpec, scene: ResidentScene | np.ndarray, samples: ViewSamples,
               settings: ShadowSettings, keep_atlas: bool = False) -> FrameResult:
        """One frame: plan, analysis, maps, test. Times each stage with a GPU sync.

        `scene` is a `ResidentScene`, whose unchanged objects stay on the GPU between
        frames, or a (T, 3, 3) world triangle array: a read-only one stays resident for
        as long as the same array comes back (the viewport's per-light selections), any
        other is uploaded for this frame only.
        """
        one_frame = False
        if not isinstance(scene, ResidentScene):
            scene, one_frame = self._scene_of(scene)
        try:
            return self._render(light, scene, samples, settings, keep_atlas)
        finally:
            if one_frame:
                self.backend.release_scene(scene)

    def _render(self, light: LightSpec, scene: ResidentScene, samples: ViewSamples, settings: ShadowSettings,
                keep_atlas: bool) -> FrameResult:
        backend = self.backend
        timings: dict[str, float] = {}
        t0 = time.perf_counter()
        self._upload_samples(light, samples)
        backend.finish()
        t_upload = time.perf_counter() - t0

        t1 = time.perf_counter()
        check_light_fits(light, settings.parameterization)
        backend.sync_scene(scene)  # uploads only objects whose geometry changed
        bounds = scene.bounds()  # per object, from its box and matrix
        near_far = (projection.depth_range(None, light.position, bounds=bounds) if bounds is not None
                    else (0.0, 1.0))
        if settings.parameterization in PROJECTIVE_PARAMETERIZATIONS:
            # With nothing finite to draw, any box around the light will do.
            scene_lo, scene_hi = bounds if bounds is not None else (light.position - 1.0, light.position + 1.0)
            plan = plan_projective(light, settings.parameterization, samples.camera, samples.positions,
                                   samples.hit, scene_lo, scene_hi, settings.resolution, cull=settings.cull)
        else:
            plan = plan_frame(light, settings.parameterization, samples.camera, samples.positions, samples.hit,
                              near_far[1], cull=settings.cull, cut=settings.cut)
        t_plan = time.perf_counter() - t1

        t2 = time.perf_counter()
        mappings: dict[int, LayerMapping] = {}
        counts: dict[int, np.ndarray] = {}
        if settings.warp != "none" and plan.drawn:
            mappings, counts = self._analyse(light, settings, plan)
        else:
            backend.set_warp_tables(None, None)
            if plan.ipsm_half_angle is not None:
                mappings = {0: (cut_mapping(plan, light, settings.resolution) if settings.cut
                                else ipsm_mapping(plan.ipsm_half_angle, settings.resolution))}
        backend.finish()
        t3 = time.perf_counter()
        timings["analysis"] = (t3 - t2) * 1e3

        if plan.parameterization == "unfold":
            geometry = prepare_unfold(light, scene.world_triangles(), plan, settings, near_far)
        else:
            geometry = PreparedGeometry({}, near_far[0], near_far[1], scene.skipped, 0,
                                        measure=_measurer(scene, light, plan, settings))
        res = settings.resolution
        size = settings.analysis_size or analysis_size_for(res)
        tile_of_slot = {layer.slot: i for i, layer in enumerate(plan.drawn)}
        layout = AtlasLayout.for_tiles(res, len(plan.drawn), backend.max_texture_size())
        boxes = readable_boxes(plan, light, settings, mappings)
        draws = footprint_draws(scene, light)
        region = _region_uniforms(plan, light, settings.cull)
        t4 = time.perf_counter()
        timings["prepare"] = (t4 - t3 + t_plan) * 1e3

        # Texels outside a layer's box are neither cleared nor drawn (map-space culling).
        backend.begin_atlas(layout, {tile_of_slot[slot]: box for slot, box in boxes.items()})
        if plan.parameterization == "unfold" and plan.drawn:
            # Both halves in one draw over two side-by-side tiles; the vertex stage
            # picks the half from the vertex index (Stockli Contreras et al.).
            uniforms = _layer_uniforms(plan.drawn[0], geometry, res, layout.origin(0), LayerMapping.identity(), 0)
            uniforms["ow_unfold_split"] = geometry.unfold_split
            uniforms["ow_unfold_halves"] = len(plan.drawn)
            backend.draw_layer(0, geometry.streams.get(0, np.zeros((0, VERTEX_FLOATS), np.float32)), uniforms,
                               span=len(plan.drawn))
        elif plan.projective is not None:
            uniforms = {**_layer_uniforms(plan.drawn[0], geometry, res, layout.origin(0), LayerMapping.identity(), 0),
                        **region, "ow_projective": 1, "ow_map_inverted": int(plan.projective.inverted),
                        "ow_map_matrix": plan.projective.matrix}
            backend.draw_footprints(0, draws, uniforms)
        else:
            for layer in plan.drawn:
                origin = layout.origin(tile_of_slot[layer.slot])
                mapping = mappings.get(layer.slot, LayerMapping.identity())
                uniforms = {**_layer_uniforms(layer, geometry, res, origin, mapping, size), **region}
                if mapping.warp is not None:
                    backend.build_ray_table(tile_of_slot[layer.slot], uniforms)
                backend.draw_footprints(tile_of_slot[layer.slot], draws, uniforms, scissor=boxes.get(layer.slot))
        edge_radius = 0
        if settings.edge_aa and plan.drawn:
            edge_radius, edge_eps = edge_aa_parameters(res, geometry.near, geometry.far)
            backend.edge_distance(edge_radius, edge_eps)
        backend.finish()
        t5 = time.perf_counter()
        timings["shadow_maps"] = (t5 - t4) * 1e3

        result = self._shadow_test(light, settings, plan, geometry, layout, tile_of_slot, mappings, size,
                                   edge_radius, boxes)
        backend.finish()
        t6 = time.perf_counter()
        timings["shadow_test"] = (t6 - t5 + t_upload) * 1e3
        timings["total"] = (t6 - t0) * 1e3

        atlas = _mask_unread_texels(backend.read_atlas(), layout, tile_of_slot, boxes) if keep_atlas else None
        visibility = result[..., 0][::-1].copy()
        flags = result[..., 1][::-1].astype(np.int8)
        return FrameResult(visibility, flags, timings, plan, geometry, layout,
                           texels=len(plan.drawn) * res * res, atlas=atlas, tile_of_slot=tile_of_slot,
                           mappings=mappings, count_maps=counts, boxes=boxes)

    def _upload_samples(self, light: LightSpec, samples: ViewSamples) -> None:
        height, width = samples.hit.shape
        # GL textures start at the bottom row and the samples at the top, so the arrays
        # are filled upside down, in place: a third of the time of building them with
        # np.where and flipping a copy (every frame, every method).
        hit = (samples.hit & projection.finite_points(samples.positions))[::-1]
        pos = np.empty((height, width, 4), dtype=np.float32)
        nrm = np.empty((height, width, 4), dtype=np.float32)
        with np.errstate(over="ignore", invalid="ignore"):  # misses are zeroed below
            np.subtract(samples.positions[::-1], light.position, out=pos[..., :3], casting="same_kind")
            nrm[..., :3] = samples.normals[::-1]
        weights = samples.importance_weights()
        pos[..., 3] = hit if weights is None else weights[::-1]
        pos[~hit] = 0.0
        nrm[~hit] = 0.0
        self.backend.upload_samples(pos, nrm)

    def _shadow_test(self, light: LightSpec, settings: ShadowSettings, plan: Plan, geometry: PreparedGeometry,
                     layout: AtlasLayout, tile_of_slot: dict[int, int], mappings: dict[int, LayerMapping],
                     warp_size: int, edge_radius: int = 0,
                     boxes: dict[int, tuple[int, int, int, int]] | None = None) -> np.ndarray:
        rotations, crops = _slot_rotations_and_crops(plan, mappings)
        tiles = np.zeros((SLOTS, 4))
        res = float(settings.resolution)
        readable = np.tile([0.0, 0.0, res, res], (SLOTS, 1))
        for slot, box in (boxes or {}).items():
            readable[slot] = box
        for slot, tile in tile_of_slot.items():
            x, y = layout.origin(tile)
            tiles[slot] = (x, y, 1.0, 0.0)
        uniforms = {
            "ow_light_rot": light.rotation.T,
            "ow_layer_rot": rotations,
            "ow_layer_tile": tiles,
            "ow_layer_crop": crops,
            "ow_layer_box": readable,
            "ow_param": _PARAM_CODES[plan.parameterization],
            "ow_layer_kind": plan.layer_kind,
            "ow_hemi": 1 if light.emission == "hemi" else 0,
            "ow_warp_size": warp_size if any(m.warp is not None for m in mappings.values()) else 0,
            "ow_resolution": float(settings.resolution),
            "ow_near": geometry.near,
            "ow_far": geometry.far,
            "ow_bias_const": settings.bias.constant,
            "ow_bias_slope": settings.bias.slope,
            "ow_bias_normal": settings.bias.normal,
            "ow_projective": 0,
            "ow_map_inverted": 0,
            "ow_map_matrix": np.eye(4),
            "ow_depth_offset": 0.0,
            "ow_sun": 1 if light.emission == "sun" else 0,
            "ow_light_axis": light.axis,
            "ow_spot_cos": math.cos(light.spot_size / 2.0) if light.emission == "spot" else -2.0,
            "ow_edge_radius": int(edge_radius),
        }
        if plan.projective is not None:
            uniforms.update(ow_projective=1, ow_map_inverted=int(plan.projective.inverted),
                            ow_map_matrix=plan.projective.matrix, ow_depth_offset=plan.projective.depth_offset)
        return self.backend.shadow_test(uniforms)


# Layer slots the GLSL tables hold (ow_layer_rot[6] and the like): a cube's six faces.
SLOTS = 6


def _slot_rotations_and_crops(plan: Plan, mappings: dict[int, LayerMapping]) -> tuple[np.ndarray, np.ndarray]:
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


def readable_boxes(plan: Plan, light: LightSpec, settings: ShadowSettings,
                   mappings: dict[int, LayerMapping]) -> dict[int, tuple[int, int, int, int]]:
    """Slot -> texel box the shadow test can read, for the plain layers culling bounds.

    Only with culling, and only for plain point-light layers: a crop or warp already
    fits the map to the samples, an unfold draw spans both halves, and a projective map
    is fitted to the view by its matrix (plan.layer_scissor gives the box).
    """
    if not settings.cull or plan.projective is not None or plan.parameterization == "unfold":
        return {}
    boxes = {}
    for layer in plan.drawn:
        if mappings.get(layer.slot, LayerMapping.identity()).is_identity:
            box = layer_scissor(layer, light.position, plan.sample_polytope, settings.resolution)
            if box is not None:
                boxes[layer.slot] = box
    return boxes


def _mask_unread_texels(atlas: np.ndarray, layout: AtlasLayout, tile_of_slot: dict[int, int],
                        boxes: dict[int, tuple[int, int, int, int]]) -> np.ndarray:
    """The atlas with every texel outside its layer's readable box set to 1 (empty).

    Those texels were neither cleared nor drawn this frame, so they hold stale values;
    images and checks of the read-back see them as the empty texels they stand for.
    """
    for slot, box in boxes.items():
        x, y = layout.origin(tile_of_slot[slot])
        res = layout.resolution
        keep = np.zeros((res, res), dtype=bool)
        x0, y0, x1, y1 = (min(max(int(v), 0), res) for v in box)
        keep[y0:y1, x0:x1] = True  # rows are y (row 0 at the bottom, as GL stores it)
        tile = atlas[y:y + res, x:x + res]
        tile[~keep] = 1.0
    return atlas


# Edge-distance antialiasing (unfold+aa): the steepest receiver whose own depth change
# must not read as an edge, as the tangent of its angle to the light ray (80 degrees).
EDGE_AA_MAX_TAN = math.tan(math.radians(80.0))


def edge_aa_parameters(resolution: int, near: float, far: float) -> tuple[int, float]:
    """R (texels) and eps (normalised depth) of the unfold map's edge-distance antialiasing.

    R = max(2, res / 256): the soft band keeps the same angular width (about 4 texels
    at 1024) at every resolution. eps: within R texels a smooth surface tilted up to 80
    degrees from the light ray changes its distance by at most R tan(80) (pi 2/res) L;
    with L <= far that is below eps, so only true steps towards a nearer occluder count.
    """
    radius = max(2, int(resolution) // 256)
    texel_angle = math.pi * 2.0 / resolution  # the unfold map's bound (projection.texel_angle)
    eps = radius * EDGE_AA_MAX_TAN * texel_angle * far / max(far - near, 1e-30)
    return radius, float(eps)


def check_light_fits(light: LightSpec, parameterization: str) -> None:
    """InputError unless the method suits the light: the omnidirectional methods take a
    point light (omni or hemi), sm and psm a spot (cone below 180 degrees) or a sun."""
    fitting = frames.parameterizations_for(light.emission)
    if parameterization not in fitting:
        needs = ("a spot (cone below 180 degrees) or sun light" if parameterization in PROJECTIVE_PARAMETERIZATIONS
                 else "a point light (omni or 180 degree spot)")
        raise InputError(f"{parameterization} needs {needs}; a {light.emission} light takes {', '.join(fitting)}")


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


def _warp_of(rows: np.ndarray, cols: np.ndarray | None, size: int, row_window: int = 0, col_window: int = 0) -> Warp:
    """A NoTW warp from its tables; no column warps yet means identity columns."""
    return Warp(rows, np.zeros((size, size + 1)) if cols is None else cols,
                WarpParams(FLOOR_SHARE, MAX_SLOPE, row_window, col_window), "notw")


@dataclass
class CountStatistics:
    """View samples per shadow texel, before and after the layer mappings (DESIGN.md 4)."""

    before: dict[int, np.ndarray]  # slot -> count map of the plain projection, map resolution
    after: dict[int, np.ndarray]  # slot -> importance map: counts through crop and warp

    @property
    def max_count_before(self) -> float:
        return float(max((m.max() for m in self.before.values()), default=0.0))

    @property
    def max_count_after(self) -> float:
        return float(max((m.max() for m in self.after.values()), default=0.0))

    @property
    def texel_utilization(self) -> float:
        """Share of the drawn texels that resolve at least one view sample."""
        total = sum(m.size for m in self.after.values())
        used = sum(int(np.count_nonzero(m)) for m in self.after.values())
        return used / total if total else 0.0


def projective_counts(projective: perspective.ProjectiveMap, light: LightSpec, samples: ViewSamples,
                      resolution: int) -> np.ndarray:
    """Count map (row 0 = v = 0) of the view samples through a spot or sun map, in numpy."""
    pts = hit_points(samples.positions, samples.hit) - light.position
    uv, _, w = perspective.project(projective, pts)
    inside = (w > 0.0) & np.all((uv >= 0.0) & (uv < 1.0), axis=1)
    texel = np.floor(uv[inside] * resolution).astype(np.int64)
    flat = np.bincount(texel[:, 1] * resolution + texel[:, 0], minlength=resolution * resolution)
    return flat.reshape(resolution, resolution).astype(np.float32)


def count_statistics(pipeline: ShadowPipeline, light: LightSpec, settings: ShadowSettings,
                     result: FrameResult, samples: ViewSamples | None = None) -> CountStatistics:
    """Scatter the samples (still uploaded from the last frame) at the map resolution.

    Not part of the timed frame: this is measurement. The warp tables of the frame
    must still be bound, which holds right after `render`. Spot and sun maps count
    in numpy and need `samples`.
    """
    res = settings.resolution
    if result.plan.projective is not None:
        if samples is None:
            raise InputError("count statistics of a spot or sun map need the view samples")
        counts = projective_counts(result.plan.projective, light, samples, res)
        return CountStatistics({0: counts}, {0: counts})
    before = pipeline.count_maps(light, result.plan, {}, res, 0)
    # A frame maps all its drawn layers or none (a warp, an ipsm zoom or a cut), and
    # count_maps counts an unmapped layer plainly anyway.
    after = pipeline.count_maps(light, result.plan, result.mappings, res, 2) if result.mappings else before
    return CountStatistics(before, after)
