"""What the shadow test and the exact pass read for a sized light: one place that
turns a light's shape and the frame's settings into the frame's sized-light mode
(`sized_mode`), and that into the soft filter's uniforms (lib/soft.glsl) or the exact soft
pass's (lib/exact_soft.glsl)."""
from __future__ import annotations

import enum
import functools
import math

import numpy as np

from ..core.light_shape import Area, LightShape, Sphere, SunDisk, stratified_points, stratified_unit_square
from ..core.plan import Plan
from ..core.scene import LightSpec
from .frame import MIN_RESOLUTION, ShadowSettings
from .shaders import (EXACT_SOFT_CLUSTER, EXACT_SOFT_KEY, EXACT_SOFT_MAX_POINTS, LIGHT_KINDS, NO_SPOT, NO_SPREAD,
                      OUTLINES, SOFT_MAX_POINTS, SOFT_MAX_SEARCH)

# The exact soft pass lists its samples at 1 / EXACT_SOFT_LIST_SHARE of the map resolution
# (list_resolution).
EXACT_SOFT_LIST_SHARE = 4


@functools.lru_cache(maxsize=32)
def _points(shape: LightShape, count: int, size: int) -> np.ndarray:
    """The light's fixed pattern of `count` points as a uniform array (size, 4), zero-padded."""
    out = np.zeros((size, 4))
    out[:count, :3] = stratified_points(shape, count)
    out.setflags(write=False)
    return out


class SizedMode(enum.Enum):
    """How a frame's shadows follow the light's size."""

    HARD = "hard"  # not at all: a light without a size, or a shape its maps cannot follow
    FILTERED = "filtered"  # the shadow test filters the maps by the light's points (lib/soft.glsl)
    EXACT_SOFT = "exact_soft"  # the exact pass marks the light's points per sample (lib/exact_soft.glsl)


def _follows_size(light: LightSpec) -> bool:
    """Whether the frame's maps can follow the light's size: a sphere or area light of omni
    or hemi emission (a point light's maps), a spot's sphere or a sun's disk (the light's
    own projective map)."""
    if not light.sized:
        return False
    if light.is_point:
        return isinstance(light.shape, (Sphere, Area))
    return ((light.emission == "spot" and isinstance(light.shape, Sphere))
            or (light.emission == "sun" and isinstance(light.shape, SunDisk)))


def sized_mode(light: LightSpec, settings: ShadowSettings) -> SizedMode:
    """The frame's one answer to how its shadows follow the light's size: the exact pass
    samples the light itself, other methods filter their maps by it, and a light without a
    size (or of a shape the maps cannot follow) keeps hard shadows."""
    if not _follows_size(light):
        return SizedMode.HARD
    return SizedMode.EXACT_SOFT if settings.exact else SizedMode.FILTERED


def light_reach(shape: LightShape) -> float:
    """The radius of the sphere about the light's centre that holds the whole light (0 for
    a sun: its disk is a cone of directions, not a place)."""
    if isinstance(shape, Sphere):
        return float(shape.radius)
    if isinstance(shape, Area):
        if shape.outline == "ellipse":
            return 0.5 * max(shape.size_x, shape.size_y)
        return 0.5 * math.hypot(shape.size_x, shape.size_y)
    return 0.0


def spread_tangent(shape: LightShape) -> float:
    """tan(spread / 2) of an area light whose spread is below 180 degrees, else NO_SPREAD (no
    spread: the GLSL's OW_NO_SPREAD). Cycles weighs the light an area light sends towards a
    direction at angle a from its normal by max(tan(spread / 2) - tan a, 0) (a soft box's
    grid of slats), so the shadow's share weighs each light point by it too."""
    if isinstance(shape, Area) and shape.spread < math.pi:
        return math.tan(0.5 * shape.spread)
    return NO_SPREAD


def spot_cone(light: LightSpec) -> tuple[float, float]:
    """(cos of the half cone, smoothness) of a spot, as Cycles attenuates the light a sample
    point sends along a direction at angle a from the axis: smoothstep((cos a - cos half) *
    smoothness), smoothness 1 / ((1 - cos half) * blend); 0 for a blend of 0 (a step).
    (NO_SPOT, 0) for any other light (lib/spot_cone.glsl's OW_NO_SPOT). A hemi sphere is
    Blender's 180 degree spot: its cone is the half space in front of it."""
    if not (light.emission == "spot" or (light.emission == "hemi" and isinstance(light.shape, Sphere))):
        return NO_SPOT, 0.0
    cos_half = math.cos(0.5 * float(light.spot_size))
    width = (1.0 - cos_half) * float(light.spot_blend)
    return cos_half, (1.0 / width if width > 0.0 else 0.0)


def light_points(light: LightSpec, settings: ShadowSettings) -> int | None:
    """The light's points a view sample's soft shadow follows (the filter's taps, or the
    exact pass's points), or None where the frame's shadows are hard."""
    mode = sized_mode(light, settings)
    if mode is SizedMode.EXACT_SOFT:
        return int(settings.exact_samples)
    return int(settings.light_samples) if mode is SizedMode.FILTERED else None


def soft_uniforms(light: LightSpec, settings: ShadowSettings) -> dict:
    """The shadow test's soft uniforms: the filter's, or the exact pass's weighing of its
    marks; ow_soft_count 0 and no exact points (the hard test) for a hard light."""
    mode = sized_mode(light, settings)
    if mode is SizedMode.EXACT_SOFT:
        return {"ow_soft_count": 0, **exact_soft_uniforms(light, settings)}
    if mode is SizedMode.HARD:
        return {"ow_soft_count": 0}
    count, search = settings.light_samples, settings.search_samples
    return {"ow_soft_points": _points(light.shape, count, SOFT_MAX_POINTS), "ow_soft_count": count,
            "ow_soft_search_points": _points(light.shape, search, SOFT_MAX_SEARCH), "ow_soft_search": search,
            "ow_soft_kind": LIGHT_KINDS[light.shape.kind], "ow_soft_spread": spread_tangent(light.shape),
            "ow_soft_spot": spot_cone(light)}


def sample_far(plan: Plan, light: LightSpec) -> float:
    """The farthest a view sample lies from the light's centre, a little over: the farthest
    vertex of the plan's sample polytope, or else of its strictly truncated view frustum
    (each convex, and holding every sample); 0 (not known) without either. The exact soft
    pass grows its footprints for a receiver that far (lib/soft_reach.glsl)."""
    polytope = plan.sample_polytope
    vertices = polytope.vertices if polytope is not None else plan.frustum_corners
    if vertices is None or len(vertices) == 0:
        return 0.0
    far = float(np.linalg.norm(np.asarray(vertices) - light.position, axis=1).max())
    return far * (1.0 + 1e-4) if math.isfinite(far) else 0.0


def exact_soft_uniforms(light: LightSpec, settings: ShadowSettings, far: float = 0.0) -> dict:
    """The exact soft pass's uniforms (footprint pass and shadow test alike), or
    {EXACT_SOFT_KEY: 0} (the hard pass) unless the frame's mode is EXACT_SOFT. `far` is
    `sample_far`'s bound for the footprint pass (0: not known)."""
    if sized_mode(light, settings) is not SizedMode.EXACT_SOFT:
        return {EXACT_SOFT_KEY: 0}
    shape = light.shape
    if isinstance(shape, Sphere):
        described = (LIGHT_KINDS["sphere"], shape.radius, 0.0, 0.0)
    elif isinstance(shape, SunDisk):
        half = 0.5 * shape.angle
        described = (LIGHT_KINDS["sun_disk"], half, math.sin(half), math.tan(half))
    else:
        described = (LIGHT_KINDS["area"], shape.size_x, shape.size_y, OUTLINES[shape.outline])
    count = int(settings.exact_samples)
    return {"ow_exact_light": np.array(described, dtype=np.float64), "ow_exact_reach": light_reach(shape),
            "ow_exact_spread": spread_tangent(shape), "ow_exact_spot": spot_cone(light),
            "ow_exact_frame": light.rotation, EXACT_SOFT_KEY: count,
            "ow_exact_pattern": _exact_pattern(shape, count), "ow_exact_bounds": _exact_bounds(shape, count),
            "ow_exact_far": float(far)}


def cluster_order(count: int) -> np.ndarray:
    """The order the exact pass keeps `count` stratified points in: by tiles of 4 x 4 cells
    of their grid (light_shape.stratified_unit_square's), so that each run of
    EXACT_SOFT_CLUSTER points lies close together on the light and a triangle's edge
    crosses few of them. The order only makes the pass faster: each cluster's bounds are
    taken from its own points, whatever they are."""
    cols = int(math.ceil(math.sqrt(count)))
    index = np.arange(count)
    col, row = index % cols, index // cols
    tile = 4
    return np.lexsort((col % tile, row % tile, col // tile, row // tile))


@functools.lru_cache(maxsize=64)
def share_points(count: int, share: int) -> tuple[int, ...]:
    """The indices, in the exact pass's table of a light's `count` points
    (`_exact_pattern`, in cluster order), of `share` of them spread over the light as the
    whole pattern is: the point nearest each cell centre of a near-square grid of `share`
    cells over the pattern's unit square (light_shape.stratified_unit_square, which the
    table maps onto the light area for area). A table order taken every k-th point would
    leave each 4 x 4 tile's first corner, a share biased towards the light's centre and
    its edges' sharper shadows."""
    if share >= count:
        return tuple(range(count))
    uv = stratified_unit_square(count)[cluster_order(count)]
    cols = int(math.ceil(math.sqrt(share)))
    rows = int(math.ceil(share / cols))
    taken: list[int] = []
    for i in range(share):
        target = np.array([(i % cols + 0.5) / cols, (i // cols + 0.5) / rows])
        distance = np.sum((uv - target) ** 2, axis=1)
        distance[taken] = np.inf
        taken.append(int(np.argmin(distance)))
    return tuple(taken)


@functools.lru_cache(maxsize=32)
def _exact_pattern(shape: LightShape, count: int) -> np.ndarray:
    """The exact pass's table of `count` light points (lib/exact_soft.glsl), zero-padded to
    EXACT_SOFT_MAX_POINTS: a sphere's (u, cos phi, sin phi, 0) on its cap, an area light's
    (x, y, 0, 0) in its frame, a sun's unit direction towards it (x, y, z, 0) in its frame
    (light_shape.stratified_points), in `cluster_order`."""
    out = np.zeros((EXACT_SOFT_MAX_POINTS, 4))
    if isinstance(shape, Sphere):
        uv = stratified_unit_square(count)
        phi = 2.0 * math.pi * uv[:, 1]
        table = np.column_stack([uv[:, 0], np.cos(phi), np.sin(phi)])
    elif isinstance(shape, SunDisk):
        table = stratified_points(shape, count)
    else:
        table = np.column_stack([stratified_points(shape, count)[:, :2], np.zeros(count)])
    out[:count, :3] = table[cluster_order(count)]
    out.setflags(write=False)
    return out


@functools.lru_cache(maxsize=32)
def _exact_bounds(shape: LightShape, count: int) -> np.ndarray:
    """Each cluster's box over its points' table entries: rows 2c (the least x, y, z) and
    2c + 1 (the greatest) for cluster c, the points 16c.. of `_exact_pattern`; zero past
    the last cluster. lib/exact_soft_mark.glsl turns a box into bounds on the segments' sides."""
    table = _exact_pattern(shape, count)
    out = np.zeros((2 * EXACT_SOFT_MAX_POINTS // EXACT_SOFT_CLUSTER, 4))
    for c, first in enumerate(range(0, count, EXACT_SOFT_CLUSTER)):
        points = table[first:min(count, first + EXACT_SOFT_CLUSTER), :3]
        out[2 * c, :3] = points.min(axis=0)
        out[2 * c + 1, :3] = points.max(axis=0)
    out.setflags(write=False)
    return out


def list_resolution(light: LightSpec, settings: ShadowSettings) -> int:
    """The resolution a frame's maps and lists run at: the settings', but a quarter of it
    (at least MIN_RESOLUTION) for the exact pass of a sized light. Its footprints grow by the
    light's angle, so a texel-fine list grid gives each triangle many fragments over few
    samples; coarser lists hold more samples each, so the same entries are walked by
    fewer fragments. The exact pass's answer does not depend on it."""
    if sized_mode(light, settings) is not SizedMode.EXACT_SOFT:
        return settings.resolution
    return max(MIN_RESOLUTION, min(settings.resolution, settings.resolution // EXACT_SOFT_LIST_SHARE))


def hit_words(light: LightSpec, settings: ShadowSettings) -> int:
    """32-bit words the exact pass keeps per view sample: one (the hard pass's mark), or one
    bit per light point of a sized light."""
    return -(-int(settings.exact_samples) // 32) if sized_mode(light, settings) is SizedMode.EXACT_SOFT else 1
