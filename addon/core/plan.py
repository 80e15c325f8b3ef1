"""Planning: which layers a frame needs.

For a point light the occluder of a visible receiver lies on the segment from the
light to that receiver, inside the same layer (King and Newhall; thesis 3.3.1).
So a layer is needed exactly when its frustum meets the truncated view frustum,
the camera frustum cut at the nearest and farthest view-sample depth.

Paraboloid side: the closed half-space z >= 0 of its frame. The convex hull of the
truncated frustum's 8 corners meets it iff some corner has z >= 0.
Cube face: the pyramid |x| <= z, |y| <= z cut at `far`. Two convex polytopes are
disjoint iff a separating axis exists among their face normals and the cross
products of their edge directions (separating axis theorem), which is exact and
cheaper than the point-in-frustum / edge-plane tests of the thesis.
"""
from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from . import perspective, projection
from .frames import Layer, Parameterization, ipsm_layer, light_layers, projective_layer
from .perspective import hull_planes  # one convex-hull routine for culling and PSM
from .polytope import Polytope, sample_polytope
from .projection import CUBE, PARABOLOID
from .samples import FULL_WINDOW, SampleStats, Window
from .scene import CameraSpec, LightSpec

log = logging.getLogger(__name__)

# Relative slack: culling must be conservative, never drop a needed layer.
_SLACK = 1e-6
# IPSM needs the cone to stay well inside a hemisphere: beyond this half-angle the
# paraboloid's rim samples too coarsely, and both sides are used instead.
IPSM_MAX_HALF_ANGLE = math.radians(80.0)


@dataclass
class Plan:
    """Layers of a frame: all the emission could use, and those to draw."""

    parameterization: Parameterization
    all_layers: list[Layer]
    drawn: list[Layer]
    frustum_corners: np.ndarray | None  # (8, 3) world, None for an empty view
    culled_names: list[str] = field(default_factory=list)
    ipsm_half_angle: float | None = None  # set when one IPSM paraboloid covers the view
    requested: str = ""  # the parameterization asked for (ipsm may fall back to dpsm)
    occluder_planes: np.ndarray | None = None  # (P, 4) outward planes of conv(light, view frustum)
    projective: "perspective.ProjectiveMap | None" = None  # sm and psm: the map's matrix
    # The strictly truncated frustum cut by the samples' box (core.polytope): holds every sample.
    sample_polytope: Polytope | None = None

    @property
    def layer_kind(self) -> int:
        """The projection kind of the plan's layers: all of them share one (a projective
        plan never projects by kind)."""
        return self.all_layers[0].kind if self.all_layers else PARABOLOID

    @property
    def drawn_slots(self) -> list[int]:
        return [layer.slot for layer in self.drawn]

    @property
    def passes(self) -> int:
        """Render passes: one per drawn layer, but the halves of an unfold map share one."""
        if self.parameterization == "unfold":
            return min(1, len(self.drawn))
        return len(self.drawn)


def frustum_corners(camera: CameraSpec, near_depth: float, far_depth: float,
                    window: Window = FULL_WINDOW) -> np.ndarray:
    """World-space corners (8, 3) of the camera frustum between two view depths: the
    near quad then the far quad, each counter-clockwise from the bottom left.

    The camera's own window (shift, sensor fit, pixel aspect) fixes the frame; `window`
    narrows it to a rectangle of that frame (see `sample_window`). An orthographic
    camera's frustum is a box: its corners do not scale with depth.
    """
    x0, x1, y0, y1 = window
    quad = np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], dtype=np.float64)
    ndc = np.concatenate([quad, quad])
    depth = np.repeat(np.array([near_depth, far_depth], dtype=np.float64), 4)
    return camera.world_points(ndc, depth)


def hit_points(positions: np.ndarray, hit: np.ndarray) -> np.ndarray:
    """The finite world positions (N, 3) of the samples that hit geometry."""
    pts = np.asarray(positions, dtype=np.float64)
    return pts[np.asarray(hit, dtype=bool) & projection.finite_points(pts)]  # one mask, one copy


def frustum_from_range(camera: CameraSpec, depth: tuple[float, float] | None, margin: float = 0.02,
                       window: Window = FULL_WINDOW) -> np.ndarray | None:
    """The camera frustum between two view depths (None for no range), grown by `margin`
    of them and narrowed to `window`."""
    if depth is None:
        return None
    low, high = float(depth[0]), float(depth[1])
    if camera.ortho:
        # A box: depths may be zero or negative (Blender's orthographic viewport puts its
        # near plane behind the view point), so the margin is absolute here.
        pad = margin * max(high - low, abs(low), abs(high)) + 1e-9
        return frustum_corners(camera, low - pad, high + pad, window)
    near = max(low * (1.0 - margin), 1e-9)
    far = high * (1.0 + margin) + 1e-9
    return frustum_corners(camera, near, far, window)


def truncated_frustum(camera: CameraSpec, stats: SampleStats, margin: float = 0.02,
                      cut: bool = False) -> np.ndarray | None:
    """Camera frustum cut at the view depths of the samples (with a 2 % margin), and
    narrowed to the image rectangle that holds them (`samples.sample_window`).

    With `cut`, at the percentile depths (`SampleStats.cull_depth`) instead of the
    strict range, so a few stray samples (a distant sky-line object, a speck near the
    lens) do not stretch the frustum. None when no sample hits geometry (nothing needs
    a map).
    """
    return frustum_from_range(camera, stats.cull_depth if cut else stats.depth, margin, stats.window)


def _hull_axes(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Face normals and edge directions of a frustum given as near quad + far quad."""
    near, far = corners[:4], corners[4:]
    edges = [near[1] - near[0], near[3] - near[0], far[0] - near[0], far[1] - near[1],
             far[2] - near[2], far[3] - near[3]]
    faces = []
    for i in range(4):
        j = (i + 1) % 4
        faces.append(np.cross(near[j] - near[i], far[i] - near[i]))
    faces.append(np.cross(near[1] - near[0], near[3] - near[0]))
    return np.asarray(faces), np.asarray(edges)


def _separated(a: np.ndarray, b: np.ndarray, axes: np.ndarray) -> bool:
    norms = np.linalg.norm(axes, axis=1)
    axes = axes[norms > 1e-12] / norms[norms > 1e-12, None]
    pa, pb = a @ axes.T, b @ axes.T
    scale = max(float(np.abs(a).max()), float(np.abs(b).max()), 1e-30)
    gap = _SLACK * scale
    return bool(np.any((pa.max(axis=0) + gap < pb.min(axis=0)) | (pb.max(axis=0) + gap < pa.min(axis=0))))


def layer_meets_frustum(layer: Layer, light_position: np.ndarray, corners: np.ndarray, far: float) -> bool:
    """True when the layer's frustum (out to `far`) meets the convex hull of `corners`."""
    local = layer.to_local(np.asarray(corners, dtype=np.float64) - light_position)
    scale = float(np.abs(local).max()) + 1e-30
    if layer.kind != CUBE:
        return bool(local[:, 2].max() >= -_SLACK * scale)
    reach = max(far, float(np.linalg.norm(local, axis=1).max())) * 1.01
    pyramid = np.array([[0.0, 0.0, 0.0], [reach, reach, reach], [-reach, reach, reach],
                        [-reach, -reach, reach], [reach, -reach, reach]])
    pyr_faces = np.array([[1.0, 0, -1], [-1.0, 0, -1], [0, 1.0, -1], [0, -1.0, -1], [0, 0, 1.0]])
    pyr_edges = np.array([[1.0, 1, 1], [-1.0, 1, 1], [-1.0, -1, 1], [1.0, -1, 1], [1.0, 0, 0], [0, 1.0, 0]])
    fr_faces, fr_edges = _hull_axes(local)
    crosses = np.cross(pyr_edges[:, None, :], fr_edges[None, :, :]).reshape(-1, 3)
    axes = np.concatenate([pyr_faces, fr_faces, crosses])
    return not _separated(pyramid, local, axes)


def ipsm_cone(light_position: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, float]:
    """Cone axis C = normalize(sum of unit directions to the corners) and half-angle theta
    = the largest angle between C and a corner direction (thesis 4.1.1, eq. 4.1-4.2)."""
    d = np.asarray(corners, dtype=np.float64) - light_position
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    axis = d.sum(axis=0)
    norm = np.linalg.norm(axis)
    if norm < 1e-12:
        return np.array([0.0, 0.0, 1.0]), math.pi
    axis /= norm
    return axis, float(np.max(np.arccos(np.clip(d @ axis, -1.0, 1.0))))


def point_in_frustum(point: np.ndarray, corners: np.ndarray) -> bool:
    """True when `point` lies in the convex frustum (near quad + far quad) or on its boundary."""
    faces, _ = _hull_axes(corners)
    centre = corners.mean(axis=0)
    near, far = corners[:4], corners[4:]
    anchors = [near[i] for i in range(4)] + [near[0]]
    normals = list(faces)
    # The far face is parallel to the near one; test it with the opposite normal.
    normals.append(-faces[4])
    anchors.append(far[0])
    for normal, anchor in zip(normals, anchors):
        outward = normal if np.dot(normal, anchor - centre) > 0 else -normal
        scale = np.linalg.norm(outward) * (np.abs(corners).max() + 1.0)
        if np.dot(outward, point - anchor) > 1e-9 * scale:
            return False
    return True


def skewed_axis(light_position: np.ndarray, corners: np.ndarray, camera: CameraSpec) -> np.ndarray:
    """Axis of the skewed cut (thesis 4.1.4): the corner directions weighted by 1 / view depth.

    The near corners weigh (far / near) times more than the far ones, so the dense
    centre of the paraboloid turns towards the part of the view close to the camera,
    where a texel covers the most pixels. An orthographic camera's pixels have the same
    size at every depth, so there every corner weighs the same.
    """
    d = np.asarray(corners, dtype=np.float64) - light_position
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if camera.ortho:
        axis = d.sum(axis=0)
    else:
        depth = np.maximum(camera.view_depths(corners), 1e-9)
        axis = (d / depth[:, None]).sum(axis=0)
    return axis / np.linalg.norm(axis)


@dataclass
class _ViewRegion:
    """A frame's view samples as planning sees them, and what it derives from them.

    IPSM falls back to the dual paraboloid when the light is among the samples, and the
    fallback plans from the same region.
    """

    camera: CameraSpec
    stats: SampleStats

    @functools.cached_property
    def strict(self) -> np.ndarray | None:
        """The strictly truncated frustum: it holds every sample."""
        return truncated_frustum(self.camera, self.stats)

    @functools.cached_property
    def polytope(self) -> Polytope | None:
        return None if self.strict is None else sample_polytope(self.strict, self.stats.box)


def plan_frame(light: LightSpec, parameterization: Parameterization, camera: CameraSpec | None,
               stats: SampleStats, far: float, cull: bool = True, cut: bool = False) -> Plan:
    """Decide which layers to draw for one frame, from its samples' statistics.

    Without a camera (a projection `camera_from_matrices` cannot describe) there is no
    view frustum to test against, so every layer is drawn.
    """
    if parameterization == "ipsm":
        return _plan_ipsm(light, camera, stats, far, cull, cut)
    if camera is None:
        layers = light_layers(light, parameterization)
        return Plan(parameterization, layers, list(layers), None)
    return _plan_layers(light, parameterization, _ViewRegion(camera, stats), far, cull)


def _plan_layers(light: LightSpec, parameterization: Parameterization, region: _ViewRegion, far: float,
                 cull: bool) -> Plan:
    """`plan_frame` for the layered parameterizations, from the view region."""
    layers = light_layers(light, parameterization)
    corners = truncated_frustum(region.camera, region.stats, cut=True)
    if not cull:
        return Plan(parameterization, layers, list(layers), corners)
    if corners is None:
        return Plan(parameterization, layers, [], None, [layer.name for layer in layers])
    if parameterization == "unfold":
        # Each half holds the whole sphere and both go out in one draw, so there is no
        # layer to leave out; only objects are culled.
        return Plan(parameterization, layers, list(layers), corners,
                    occluder_planes=_occluder_planes(light, region.strict), sample_polytope=region.polytope)
    meets = {layer.slot for layer in layers if layer_meets_frustum(layer, light.position, corners, far)}
    if len(meets) < len(layers):
        # The percentile frustum may miss a stray sample; a layer that holds any sample
        # is always drawn, so culling never changes a shadow.
        meets |= region.stats.occupied(parameterization)
    drawn = [layer for layer in layers if layer.slot in meets]
    return Plan(parameterization, layers, drawn, corners, [layer.name for layer in layers if layer.slot not in meets],
                occluder_planes=_occluder_planes(light, region.strict), sample_polytope=region.polytope)


def sun_upstream_reach(scene_lo: np.ndarray, scene_hi: np.ndarray) -> float:
    """How far upstream of the view a sun's occluder region reaches: past the whole scene."""
    return 2.0 * float(np.linalg.norm(np.asarray(scene_hi) - np.asarray(scene_lo))) + 1.0


def plan_projective(light: LightSpec, parameterization: Parameterization, camera: CameraSpec | None,
                    stats: SampleStats, scene_lo: np.ndarray, scene_hi: np.ndarray,
                    resolution: int, cull: bool = True) -> Plan:
    """The one map of a spot or sun light: `sm` (uniform) or `psm` (Stamminger and
    Drettakis 2002, in the camera's post-perspective space).

    PSM needs the view: it is fitted to the strictly truncated view frustum (every
    sample must land in the map, so no percentile here). With no camera or no sample
    it falls back to the uniform map, and the plan says so in `requested`. So it does
    with an orthographic camera: its post-perspective space is an affine image of the
    world, so a PSM there would only be a uniform map seen through a skewed frame.
    """
    corners = truncated_frustum(camera, stats) if camera is not None else None
    layer = projective_layer(parameterization)
    if parameterization == "psm" and camera is not None and camera.ortho:
        log.info("psm with an orthographic camera is the uniform map: using sm")
    if parameterization == "psm" and corners is not None and not camera.ortho:
        depths = camera.view_depths(corners)
        near, far = float(depths.min()), float(depths.max())
        projective = perspective.psm_map(light, camera, near, far, corners, scene_lo, scene_hi, resolution)
        used = "psm"
    else:
        projective = perspective.sm_map(light, scene_lo, scene_hi, resolution, corners)
        used = "sm"
    planes = None
    if cull and corners is not None:
        # Object culling: an occluder of a visible receiver lies between it and the light.
        if light.emission == "sun":
            reach = sun_upstream_reach(scene_lo, scene_hi)
            planes = hull_planes(np.vstack([corners, corners - reach * light.axis]))
        else:
            planes = _occluder_planes(light, corners)
    return Plan(used, [layer], [layer], corners, requested=parameterization, occluder_planes=planes,
                projective=projective)


# Map-space culling (layer_scissor): the box of the sample polytope's image grows by
# this share of its size plus SCISSOR_MARGIN_TEXELS, for the shadow test's normal offset
# and for the curve of an edge's image between its sampled points.
SCISSOR_GROW = 0.02
SCISSOR_MARGIN_TEXELS = 4
SCISSOR_EDGE_POINTS = 64


def layer_scissor(layer: Layer, light_position: np.ndarray, polytope: Polytope | None,
                  resolution: int) -> tuple[int, int, int, int] | None:
    """Texel box (x0, y0, x1, y1) of a plain layer that can be looked up, or None (all of it).

    Every view sample lies in the sample polytope (the strictly truncated frustum cut by
    the samples' box), so the shadow test reads only texels in its image (plus the
    normal offset). Seen from a light outside it, the image of a convex body is bounded
    by the images of its edges. Conservative: None when the light is inside the
    polytope, when part of it lies behind the layer's plane (its image is unbounded
    there), or with no samples.
    """
    if polytope is None or polytope.contains(light_position):
        return None
    local = layer.to_local(polytope.edge_points(SCISSOR_EDGE_POINTS) - light_position)
    if np.any(local[:, 2] <= 1e-9 * (float(np.abs(local).max()) + 1e-30)):
        return None
    xy = projection.project(layer.kind, local)
    lo, hi = xy.min(axis=0) * 0.5 + 0.5, xy.max(axis=0) * 0.5 + 0.5
    grow = (hi - lo) * SCISSOR_GROW
    margin = SCISSOR_MARGIN_TEXELS / resolution
    lo = np.clip(lo - grow - margin, 0.0, 1.0)
    hi = np.clip(hi + grow + margin, 0.0, 1.0)
    x0, y0 = (int(v) for v in np.floor(lo * resolution))
    x1, y1 = (int(v) for v in np.ceil(hi * resolution))
    return x0, y0, x1, y1


def _plan_ipsm(light: LightSpec, camera: CameraSpec | None, stats: SampleStats, far: float, cull: bool,
               cut: bool = False) -> Plan:
    """IPSM (thesis 4.1): one paraboloid along the cone over the samples when the light is
    outside them; otherwise (or without culling) the dual paraboloid. With `cut`, the axis
    is skewed towards the camera and the map cropped to the samples' image.

    The thesis fits the cone to the truncated view frustum's corners. Here it fits the
    sample polytope (that frustum cut by the samples' box): it holds every sample too,
    and is often much smaller, so the cone is narrower and the zoom higher.
    """
    region = _ViewRegion(camera, stats) if camera is not None else None
    corners = region.strict if region is not None else None
    polytope = region.polytope if region is not None else None
    # Every sample lies in the sample polytope; a light outside it (a convex body) sees
    # them all within a cone of less than a hemisphere.
    if cull and polytope is not None and not polytope.contains(light.position):
        axis, theta = ipsm_cone(light.position, polytope.vertices)
        if theta < IPSM_MAX_HALF_ANGLE:
            if cut:
                axis = skewed_axis(light.position, polytope.vertices, camera)
                d = polytope.edge_points(SCISSOR_EDGE_POINTS) - light.position
                theta = float(np.max(np.arccos(np.clip((d / np.linalg.norm(d, axis=1, keepdims=True)) @ axis,
                                                       -1.0, 1.0))))
            layer = ipsm_layer(axis)
            if theta < IPSM_MAX_HALF_ANGLE:
                return Plan("ipsm", [layer], [layer], corners, ipsm_half_angle=theta, requested="ipsm",
                            occluder_planes=_occluder_planes(light, corners),
                            sample_polytope=polytope)
    fallback = (_plan_layers(light, "dpsm", region, far, cull) if region is not None
                else plan_frame(light, "dpsm", camera, stats, far, cull))
    fallback.requested = "ipsm"
    return fallback


def _occluder_planes(light: LightSpec, corners: np.ndarray | None) -> np.ndarray | None:
    """Outward planes of conv(light, frustum corners), or None without a frustum.

    Not the tighter sample polytope: a triangle outside conv(light, polytope) shadows no
    sample, but it can still cover the centre of a texel a sample reads, so leaving it
    out may change a shadow-map lookup (tried: one pixel of courtyard at test size
    turned from falsely shadowed to lit). Culling must not change any result.
    """
    return None if corners is None else hull_planes(np.vstack([corners, light.position[None]]))


# Relative slack of the occluder-region test: a corner counts as beyond a plane past
# REGION_SLACK * (max |plane offset| + 1); the GPU's cull (footprint.vert) uses the same.
REGION_SLACK = 1e-6


def outside_region(triangles: np.ndarray, planes: np.ndarray | None, slack: float = REGION_SLACK) -> np.ndarray:
    """(T,) True where all three corners lie beyond one plane (by a relative slack)."""
    tris = np.asarray(triangles, dtype=np.float64)
    if planes is None or len(planes) == 0 or len(tris) == 0:
        return np.zeros(len(tris), dtype=bool)
    scale = float(np.abs(planes[:, 3]).max()) + 1.0
    dist = tris @ planes[:, :3].T - planes[:, 3]  # (T, 3, P)
    return np.any(np.all(dist > slack * scale, axis=1), axis=1)
