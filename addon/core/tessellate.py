"""Geometry preparation: sanitising, seam splitting and adaptive tessellation.

All functions take and return triangle arrays of shape (T, 3, 3), float64.

Why tessellate: the rasteriser interpolates linearly between projected vertices,
but the paraboloid maps straight edges to circular arcs (it is a stereographic
projection). An edge whose arc departs from its chord by more than about a texel
would leave holes or overlaps in the map, so only those edges are split.

Refinement is conforming: whether an edge is split depends on its two end points
only (midpoints are computed symmetrically), so the two triangles sharing an edge
always agree and no T-junction (a pinhole leak in a shadow map) can appear.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .projection import MAX_COORDINATE

log = logging.getLogger(__name__)

MAX_LEVELS = 12
MAX_TRIANGLES = 4_000_000


@dataclass
class SanitizeReport:
    """What `sanitize` removed, by reason."""

    nonfinite: int = 0
    degenerate: int = 0
    edge_on: int = 0

    @property
    def skipped(self) -> int:
        return self.nonfinite + self.degenerate + self.edge_on


def sanitize(triangles: np.ndarray, light_position: np.ndarray, scale: float) -> tuple[np.ndarray, SanitizeReport]:
    """Drop triangles that cannot cast a shadow or cannot be projected.

    - non-finite corners (NaN, inf, or beyond `projection.MAX_COORDINATE`, which is how
      Blender stores an inf): skipped and counted;
    - zero area (relative to `scale`^2): skipped and counted;
    - planes passing through the light (e.g. a vertex exactly at the light): seen
      edge-on they cover no solid angle, so they occlude nothing, and projecting
      them would normalise a zero vector.
    """
    tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    report = SanitizeReport()
    finite = np.all(np.isfinite(tris) & (np.abs(tris) < MAX_COORDINATE), axis=(1, 2))
    report.nonfinite = int(np.count_nonzero(~finite))
    tris = tris[finite]
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area2 = np.linalg.norm(normal, axis=1)
    tiny = (1e-12 * scale) ** 2
    degenerate = area2 <= tiny
    report.degenerate = int(np.count_nonzero(degenerate))
    tris, normal, area2 = tris[~degenerate], normal[~degenerate], area2[~degenerate]
    unit = normal / area2[:, None]
    plane_distance = np.abs(np.einsum("ij,ij->i", unit, tris[:, 0] - light_position))
    edge_on = plane_distance <= 1e-9 * scale
    report.edge_on = int(np.count_nonzero(edge_on))
    return tris[~edge_on], report


def clip_halfspace(triangles: np.ndarray, signed: np.ndarray) -> np.ndarray:
    """Keep the part of each triangle where the per-vertex value `signed` >= 0.

    `signed` has shape (T, 3) and must be affine in position (a plane distance),
    so the cut points are exact. A triangle with one corner inside becomes one
    triangle, with two corners inside a quad split into two.
    """
    tris = np.asarray(triangles, dtype=np.float64)
    d = np.asarray(signed, dtype=np.float64)
    # A triangle with no corner strictly inside only touches the boundary: no area.
    touches_only = ~np.any(d > 0.0, axis=1)
    tris, d = tris[~touches_only], d[~touches_only]
    inside = d >= 0.0
    n_in = inside.sum(axis=1)
    out = [tris[n_in == 3]]

    def rotate(sel: np.ndarray, first: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        order = (first[:, None] + np.arange(3)[None, :]) % 3
        rows = np.arange(len(order))[:, None]
        return tris[sel][rows, order], d[sel][rows, order]

    def cut(p, q, dp, dq):
        t = dp / (dp - dq)  # dp >= 0 > dq, so the denominator is positive
        return p + t[:, None] * (q - p)

    one = n_in == 1
    if np.any(one):
        t, dd = rotate(one, np.argmax(inside[one], axis=1))  # the inside corner first
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        out.append(np.stack([a, cut(a, b, dd[:, 0], dd[:, 1]), cut(a, c, dd[:, 0], dd[:, 2])], axis=1))
    two = n_in == 2
    if np.any(two):
        t, dd = rotate(two, (np.argmin(inside[two], axis=1) + 1) % 3)  # corner after the outside one first
        a, b, c = t[:, 0], t[:, 1], t[:, 2]  # a, b inside; c outside
        pbc = cut(b, c, dd[:, 1], dd[:, 2])
        pca = cut(a, c, dd[:, 0], dd[:, 2])
        out.append(np.stack([a, b, pbc], axis=1))
        out.append(np.stack([a, pbc, pca], axis=1))
    pieces = np.concatenate(out, axis=0)
    # A corner exactly on the boundary makes one piece of the quad split degenerate.
    area2 = np.linalg.norm(np.cross(pieces[:, 1] - pieces[:, 0], pieces[:, 2] - pieces[:, 0]), axis=1)
    return pieces[area2 > 0.0]


def split_at_seam(local_triangles: np.ndarray, overlap: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Split light-centred triangles (in a frame whose z is the seam normal) at z = 0.

    Returns (front, back): the parts with z >= 0 and with z <= 0. Triangles lying
    in the plane itself subtend no solid angle and are dropped from both.

    With `overlap` (radians), each part of a triangle that crosses the seam reaches
    past it: a cut edge is drawn as a straight chord, and texels whose centre lies just
    past the rim would otherwise stay empty, so lookups right at the seam found no
    occluder (light leaking along grazing floors). The cut is the plane z = -c (front)
    or z = c (back), exact and affine, with c = sin(overlap) times the farthest point
    where the triangle meets the seam: the reach is at least `overlap` along the whole
    cut. c is capped at sin(2 overlap) times the distance from the light to the
    triangle's plane, so no piece reaches more than twice the overlap past the seam
    (a piece must never approach the opposite pole, where the projections are
    singular); a crossing triangle nearly edge-on to the light gets less reach. Triangles wholly
    on one side are not extended: a receiver would then meet itself in the other map.
    """
    tris = np.asarray(local_triangles, dtype=np.float64)
    z = tris[..., 2]
    flat = np.all(z == 0.0, axis=1)
    tris, z = tris[~flat], z[~flat]
    if overlap <= 0.0:
        return clip_halfspace(tris, z), clip_halfspace(tris, -z)
    crossing = (z.max(axis=1) > 0.0) & (z.min(axis=1) < 0.0)
    reach = _seam_reach(tris[crossing], overlap)[:, None]
    front = np.concatenate([clip_halfspace(tris[~crossing], z[~crossing]),
                            clip_halfspace(tris[crossing], z[crossing] + reach)])
    back = np.concatenate([clip_halfspace(tris[~crossing], -z[~crossing]),
                           clip_halfspace(tris[crossing], reach - z[crossing])])
    return front, back


def _seam_reach(tris: np.ndarray, overlap: float) -> np.ndarray:
    """Per crossing triangle, the plane offset c of `split_at_seam`'s overlap."""
    if len(tris) == 0:
        return np.zeros(0)
    a, b = tris, np.roll(tris, -1, axis=1)
    za, zb = a[..., 2], b[..., 2]
    cuts = (za > 0.0) != (zb > 0.0)  # each crossing triangle has two such edges
    t = np.where(cuts, za / np.where(za != zb, za - zb, 1.0), 0.0)
    points = a + t[..., None] * (b - a)  # (T, 3, 3): where each edge meets z = 0
    dist = np.where(cuts, np.linalg.norm(points, axis=2), 0.0)
    farthest = dist.max(axis=1)
    # Every point of the triangle is at least its plane's distance from the light, so
    # capping c there bounds the reach everywhere, not only along the cut.
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    nearest = np.abs(np.einsum("ij,ij->i", normal, tris[:, 0]))
    return np.minimum(math.sin(overlap) * farthest, math.sin(2.0 * overlap) * nearest)


def _edge_marks(tris: np.ndarray, project_texels: Callable[[np.ndarray], np.ndarray], tolerance: float,
                window: float | None = None) -> np.ndarray:
    """(T, 3) bool: edge k (corner k to corner k+1) bends by more than `tolerance` texels.

    The bend is measured at the quarter, half and three-quarter points. The midpoint
    alone misses arcs symmetric about it, e.g. a floor diagonal passing right under
    the light, whose midpoint lands on its chord. The three points form a set that is
    the same for (a, b) and (b, a), bit for bit, so neighbours always agree.

    With `window` (the map side in texels), an edge whose five points all lie beyond
    the same side of the map, by more than its bend plus the tolerance, is left alone:
    the GPU clips it, and its curvature outside the map changes no texel.
    """
    a = tris
    b = np.roll(tris, -1, axis=1)
    n = len(tris)
    pa = project_texels(a.reshape(-1, 3)).reshape(n, 3, 2)
    pb = np.roll(pa, -1, axis=1)
    bend = np.zeros((n, 3))
    # Per texel axis, the smallest and largest of the five points (for the window test).
    # Components are handled one by one: numpy reduces a short last axis slowly.
    low = np.minimum(pa, pb)
    high = np.maximum(pa, pb)
    for wa, wb in ((0.75, 0.25), (0.5, 0.5), (0.25, 0.75)):
        point = project_texels((a * wa + b * wb).reshape(-1, 3)).reshape(n, 3, 2)
        off = point - (pa * wa + pb * wb)
        bend = np.maximum(bend, np.sqrt(off[..., 0] * off[..., 0] + off[..., 1] * off[..., 1]))
        np.minimum(low, point, out=low)
        np.maximum(high, point, out=high)
    marks = bend > tolerance
    if window is not None:
        margin = bend + tolerance
        outside = ((high[..., 0] < -margin) | (low[..., 0] > window + margin)
                   | (high[..., 1] < -margin) | (low[..., 1] > window + margin))
        marks &= ~outside
    return marks


def _refine_once(tris: np.ndarray, marks: np.ndarray) -> np.ndarray:
    pattern = marks.sum(axis=1)
    out = [tris[pattern == 0]]
    rows_of = lambda sel: np.arange(np.count_nonzero(sel))[:, None]  # noqa: E731

    one = pattern == 1
    if np.any(one):
        k = np.argmax(marks[one], axis=1)
        t = tris[one][rows_of(one), (k[:, None] + np.arange(3)) % 3]  # marked edge is now 0-1
        m01 = (t[:, 0] + t[:, 1]) * 0.5
        out += [np.stack([t[:, 0], m01, t[:, 2]], 1), np.stack([m01, t[:, 1], t[:, 2]], 1)]
    two = pattern == 2
    if np.any(two):
        k = (np.argmin(marks[two], axis=1) + 1) % 3  # unmarked edge becomes 2-0
        t = tris[two][rows_of(two), (k[:, None] + np.arange(3)) % 3]
        m01 = (t[:, 0] + t[:, 1]) * 0.5
        m12 = (t[:, 1] + t[:, 2]) * 0.5
        out += [np.stack([m01, t[:, 1], m12], 1), np.stack([t[:, 0], m01, m12], 1),
                np.stack([t[:, 0], m12, t[:, 2]], 1)]
    three = pattern == 3
    if np.any(three):
        t = tris[three]
        m01 = (t[:, 0] + t[:, 1]) * 0.5
        m12 = (t[:, 1] + t[:, 2]) * 0.5
        m20 = (t[:, 2] + t[:, 0]) * 0.5
        out += [np.stack([t[:, 0], m01, m20], 1), np.stack([m01, t[:, 1], m12], 1),
                np.stack([m20, m12, t[:, 2]], 1), np.stack([m01, m12, m20], 1)]
    return np.concatenate(out, axis=0)


def _short_edges(tris: np.ndarray, min_angle: float) -> np.ndarray:
    """(T,) True where every edge spans less than `min_angle` as seen from the origin.

    From the light, the points of a segment sweep the great circle between its end
    directions and no further, so an edge spanning less than one texel's angle has an
    image within one texel: its bend cannot exceed the tolerance, and it need not be
    projected at all (the saving that matters for million-triangle meshes).
    """
    norms = np.linalg.norm(tris, axis=2, keepdims=True)
    unit = tris / np.maximum(norms, 1e-300)
    cos_edges = np.einsum("tki,tki->tk", unit, np.roll(unit, -1, axis=1))
    return np.all(cos_edges > np.cos(min_angle), axis=1)


def tessellate(triangles: np.ndarray, project_texels: Callable[[np.ndarray], np.ndarray],
               tolerance_texels: float = 1.0, window: float | None = None,
               texel_angle_floor: float | None = None) -> tuple[np.ndarray, int]:
    """Subdivide only the triangles with an edge bending by more than the tolerance.

    `project_texels` maps (n, 3) points to (n, 2) texel coordinates of the map;
    `window`, the map side in texels, lets edges wholly outside the map stay coarse;
    `texel_angle_floor`, a lower bound of one texel's angle anywhere in the map, lets
    triangles whose edges all span less than the tolerance skip the bend test.
    Returns the new triangles and how many triangles were added.
    """
    tris = np.asarray(triangles, dtype=np.float64)
    start = len(tris)
    done: list[np.ndarray] = []
    if texel_angle_floor is not None and len(tris):
        short = _short_edges(tris, tolerance_texels * texel_angle_floor)
        done.append(tris[short])
        tris = tris[~short]
    for level in range(MAX_LEVELS):
        if len(tris) == 0:
            break
        marks = _edge_marks(tris, project_texels, tolerance_texels, window)
        if not marks.any():
            break
        if start + 3 * int(marks.any(axis=1).sum()) + len(tris) > MAX_TRIANGLES:
            log.warning("tessellation stopped at level %d: triangle budget %d reached", level, MAX_TRIANGLES)
            break
        # Triangles with no marked edge are final: later levels never need to see them.
        settled = ~marks.any(axis=1)
        done.append(tris[settled])
        tris = _refine_once(tris[~settled], marks[~settled])
    done.append(tris)
    result = np.concatenate(done, axis=0) if done else np.zeros((0, 3, 3))
    return result, len(result) - start
