"""Single projective shadow maps for spot and sun lights: uniform (SM) and perspective (PSM).

Stamminger and Drettakis 2002, "Perspective Shadow Maps" (PSM). A plain shadow map
(`sm_map`) is a perspective frustum along a spot's axis or an orthographic box along
the sun's direction. A perspective shadow map (`psm_map`) is a standard shadow map
taken in the camera's post-perspective space (PPS, NDC): the scene and the light are
mapped by C = camera projection @ world-to-view (sec. 2, 3), the light becomes a
point, an inverted point or a directional light there (sec. 3.1, 3.2), and the map
is fitted to the region H of every point that can cast a shadow into the view
(sec. 4.1), moving the camera back virtually when H reaches behind it (sec. 4.2).

Every point given or returned is LIGHT-CENTRED: world position minus
`light.position` (for a sun, the lamp's location, only an origin). The pipeline
subtracts it in float64 before going to float32, so each matrix maps
(p - light.position, 1) to map clip space, with the translation folded in.

Map conventions (OpenGL): uv = (clip.xy / clip.w) * 0.5 + 0.5, z01 = (clip.z /
clip.w) * 0.5 + 0.5, w > 0 in front of the map. Every vertex of the returned
`region` maps into [0, 1]^3 with w > 0.

Rules chosen here:
* spot SM window: tan half-width = tan(cone / 2) * (1 + SPOT_MARGIN), square;
* fitted windows (sun SM, PSM) grow by WINDOW_MARGIN of their extent on each side,
  fitted depth ranges by DEPTH_MARGIN of theirs (each with a tiny floor relative to
  the coordinates, so a flat or point-like region still gets a non-empty range);
* a perspective map's near plane is at least NEAR_FRACTION of its far plane; the
  region is cut there (occluders closer to the light than that are not covered);
* the scene box grows by a relative 1e-9 (faces stay inside, a collapsed box keeps a
  volume); a spot's H is cut a hair in front of the light, so that an H that is only
  the light itself (cone turned away from the view) counts as empty;
* H empty (the view misses the lit part of the box): fall back to V n S, then to S;
* winding: every map is mirrored if needed so that a surface facing the light,
  counter-clockwise seen from the light, is counter-clockwise in uv;
* depth offset: see `depth_offset_for`.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .scene import CameraSpec, LightSpec, orthonormalize

SPOT_MARGIN = 0.01  # spot SM: the window's tan half-width is tan(cone / 2) * (1 + SPOT_MARGIN)
WINDOW_MARGIN = 0.005  # fitted windows grow by this share of their extent on each side
DEPTH_MARGIN = 0.01  # fitted depth ranges grow by this share of their extent on each end
NEAR_FRACTION = 1e-3  # a perspective map's near plane is at least this share of its far plane
# The PPS light counts as directional when kappa * R <= DIRECTIONAL_EPS, kappa being
# 1 / (distance from the PPS light to H's centre) and R H's radius in PPS: the rays
# across H then differ from parallel ones by less than this angle.
DIRECTIONAL_EPS = 1e-9
_REL_TOL = 1e-12  # geometric tolerance, relative to the size of the coordinates involved
_BOX_GROWTH = 1e-9  # the scene box grows by this share of the coordinates' size
_DET_MIN = 1e-10  # plane triples with unit normals this close to dependent give no vertex
_TINY = 1e-300
_MIN_SCALE = 1e-30  # scale floor: a scene collapsed onto the light still gets finite tolerances


@dataclass(frozen=True)
class ProjectiveMap:
    """One single shadow map (SM or PSM) as a 4x4 matrix on light-centred points."""

    matrix: np.ndarray  # (4, 4) float64: light-centred world (x, y, z, 1) -> map clip space
    inverted: bool  # depth order reversed (inverted PPS point light): the occluder has the LARGER z01
    depth_offset: float  # constant depth offset in z01 units
    pps_light: str  # "world" for sm; "point", "inverted" or "directional" for psm
    camera_shift: float  # virtual camera shift in world units (0 when none, and for sm)
    region: np.ndarray  # (k, 3) light-centred vertices of H (or of the fitted box)


# ------------------------------------------------------------------ projection


def project(map_: ProjectiveMap, points_centred: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(uv (..., 2), z01 (...), w (...)) for light-centred points; w > 0 in front of the map."""
    p = np.asarray(points_centred, dtype=np.float64)
    m = np.asarray(map_.matrix, dtype=np.float64)
    clip = p @ m[:3, :3].T + m[:3, 3]
    w = p @ m[3, :3] + m[3, 3]
    # A point on the map's eye plane (w = 0) has no image; keep it finite and far out.
    safe = np.where(np.abs(w) > _TINY, w, _TINY)
    ndc = clip / safe[..., None]
    return ndc[..., :2] * 0.5 + 0.5, ndc[..., 2] * 0.5 + 0.5, w


def _jacobian(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """d(u, v, z01)/d(point) as (..., 3, 3), from the quotient rule on clip / w."""
    m = np.asarray(matrix, dtype=np.float64)
    p = np.asarray(points, dtype=np.float64)
    clip = p @ m[:3, :3].T + m[:3, 3]
    w = p @ m[3, :3] + m[3, 3]
    w = np.where(np.abs(w) > _TINY, w, _TINY)
    ndc = clip / w[..., None]
    d_ndc = (m[:3, :3] - ndc[..., :, None] * m[3, :3]) / w[..., None, None]
    return 0.5 * d_ndc


def texel_footprint(map_: ProjectiveMap, points_centred: np.ndarray, resolution: int) -> np.ndarray:
    """World size of one texel at each point: (1/resolution) / smallest singular value of d(uv)/d(point) (2x3 Jacobian)."""
    j = _jacobian(map_.matrix, points_centred)[..., :2, :]
    sigma = np.linalg.svd(j, compute_uv=False)[..., -1]
    # sigma = 0 would mean a texel of infinite size; a huge finite one keeps callers finite.
    return (1.0 / resolution) / np.maximum(sigma, 1e-300)


def depth_offset_for(matrix: np.ndarray, centre: np.ndarray, ray: np.ndarray, resolution: int) -> float:
    """Constant depth offset (z01 units) of a map at a region's centre.

    Rule: half the z01 change across one texel on a receiver tilted 45 degrees to the
    light ray through `centre`, tilted along the direction w (across the ray) where the
    texel is longest (the smallest singular direction of d(uv)/d(point) across the ray),
    the worse of +-w. A lookup lands at most half a texel from the centre of the texel
    whose depth it is compared with, so on such a receiver the stored depth differs from
    the looked-up one by at most this much (to first order); steeper receivers still
    need a slope bias or a normal offset. The map does not depend on the resolution, so
    the offset scales exactly as 1 / resolution.
    """
    d = _unit(np.asarray(ray, dtype=np.float64))
    e1, e2 = _perpendicular_pair(d)
    j = _jacobian(matrix, np.asarray(centre, dtype=np.float64))
    across = j[:2] @ np.stack([e1, e2], axis=1)  # d(uv) for unit steps across the ray
    _, _, vt = np.linalg.svd(across)
    w = vt[-1, 0] * e1 + vt[-1, 1] * e2
    along = np.stack([d + w, d - w]) / math.sqrt(2.0)  # 45 degrees to the ray
    duv = np.linalg.norm(along @ j[:2].T, axis=1)
    dz = np.abs(along @ j[2])
    step = (1.0 / resolution) / np.maximum(duv, 1e-300)  # world length of one texel along the receiver
    offset = float(np.max(0.5 * dz * step))
    if not math.isfinite(offset) or offset <= 0.0:
        return 0.5 / resolution  # degenerate map: half a texel of a unit-slope depth
    return offset


def face_light_ccw(matrix: np.ndarray, centre: np.ndarray, ray: np.ndarray) -> np.ndarray:
    """The matrix, mirrored in u (clip.x negated) if needed so that a surface facing the light,
    counter-clockwise seen from the light, is counter-clockwise in uv at `centre`.

    A standard light view keeps that winding; the camera projection flips handedness and an
    inverted PPS light looks at the scene from behind, so PSMs may need the mirror. With one
    convention for every map, face culling and continuity across the PPS light classes hold.
    """
    d = _unit(np.asarray(ray, dtype=np.float64))
    e1, e2 = _perpendicular_pair(-d)  # e1 x e2 = -d: counter-clockwise about the normal -d
    j = _jacobian(matrix, np.asarray(centre, dtype=np.float64))[:2]
    a, b = j @ e1, j @ e2
    if a[0] * b[1] - a[1] * b[0] < 0.0:
        matrix = matrix.copy()
        matrix[0] = -matrix[0]
    return matrix


# ------------------------------------------------------------ geometry helpers


def hull_planes(points: np.ndarray, tol: float | None = None) -> np.ndarray:
    """Outward unit planes (P, 4) = (n, d), n.x <= d inside, of the convex hull of a few points.

    Brute force over point triples (the paper used CGAL, sec. 4.1): a triple spans a face
    when every point lies on one side of its plane. A flat, straight or single-point set
    gets zero-thickness slabs across its missing dimensions (plus edge or end planes),
    so the hull stays bounded.
    """
    pts = _finite_rows(points)
    if len(pts) == 0:
        return np.zeros((0, 4))
    if tol is None:
        tol = _REL_TOL * (float(np.abs(pts).max()) + _TINY)
    centre = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - centre, full_matrices=True)
    coords = (pts - centre) @ vt.T
    flat = (coords.max(axis=0) - coords.min(axis=0)) <= tol
    parts = [_slab_planes(pts, np.concatenate([vt[flat], -vt[flat]]))]
    live = vt[~flat]
    if len(live) == 3:
        idx = np.asarray(list(itertools.combinations(range(len(pts)), 3)), dtype=np.int64)
        normals = np.cross(pts[idx[:, 1]] - pts[idx[:, 0]], pts[idx[:, 2]] - pts[idx[:, 0]])
        parts.append(_support_planes(pts, normals, pts[idx[:, 0]], tol))
    elif len(live) == 2:
        # Flat set: its edges' planes contain the set's normal.
        idx = np.asarray(list(itertools.combinations(range(len(pts)), 2)), dtype=np.int64)
        normals = np.cross(pts[idx[:, 1]] - pts[idx[:, 0]], vt[flat][0])
        parts.append(_support_planes(pts, normals, pts[idx[:, 0]], tol))
    elif len(live) == 1:
        parts.append(_slab_planes(pts, np.stack([live[0], -live[0]])))  # the segment's end caps
    return _unique_planes(np.concatenate(parts), tol)


def _slab_planes(pts: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Support planes (n, max n.p) of the points for given unit normals (always bounding)."""
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    if len(normals) == 0:
        return np.zeros((0, 4))
    return np.concatenate([normals, (pts @ normals.T).max(axis=0)[:, None]], axis=1)


def _support_planes(pts: np.ndarray, normals: np.ndarray, anchors: np.ndarray, tol: float) -> np.ndarray:
    """Planes through `anchors` with the candidate normals that have every point on one side.

    A plane is kept with the normal pointing away from the points; its offset is the
    support value max(n . p), so every point is inside it exactly.
    """
    length = np.linalg.norm(normals, axis=1)
    keep = length > 1e-12 * (float(length.max(initial=0.0)) + _TINY)
    if not np.any(keep):
        return np.zeros((0, 4))
    normals = normals[keep] / length[keep, None]
    value = np.sum(normals * anchors[keep], axis=1)
    proj = pts @ normals.T  # (N, K)
    below = proj.max(axis=0) <= value + tol  # all points on the normal's back side
    above = proj.min(axis=0) >= value - tol  # all points on its front side: flip it
    out = np.concatenate([normals[below], -normals[above]])
    if len(out) == 0:
        return np.zeros((0, 4))
    return np.concatenate([out, (pts @ out.T).max(axis=0)[:, None]], axis=1)


def _unique_planes(planes: np.ndarray, tol: float) -> np.ndarray:
    """Drop near-duplicate planes (same unit normal, offsets within tol)."""
    planes = np.asarray(planes, dtype=np.float64).reshape(-1, 4)
    if len(planes) <= 1:
        return planes
    key = np.round(np.concatenate([planes[:, :3] * 1e9, planes[:, 3:] / max(tol, _TINY)], axis=1))
    _, first = np.unique(key, axis=0, return_index=True)
    planes = planes[np.sort(first)]
    # Rounding can split a cluster at a grid line; merge those pairwise (few planes left).
    close = (np.linalg.norm(planes[:, None, :3] - planes[None, :, :3], axis=-1) <= 1e-8) & (
        np.abs(planes[:, None, 3] - planes[None, :, 3]) <= 2 * tol)
    return planes[~np.any(np.triu(close, k=1), axis=0)]


def _unique_points(points: np.ndarray, tol: float) -> np.ndarray:
    """Drop near-duplicate points (within tol of an earlier one)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) <= 1:
        return pts
    _, first = np.unique(np.round(pts / max(tol, _TINY)), axis=0, return_index=True)
    pts = pts[np.sort(first)]
    close = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=-1) <= 2 * tol
    return pts[~np.any(np.triu(close, k=1), axis=0)]


def halfspace_vertices(planes: np.ndarray, tol: float) -> np.ndarray:
    """Vertices (k, 3) of the intersection of half-spaces n.x <= d (planes (P, 4)).

    Brute force: every triple of planes is solved and its point kept when it lies in
    every half-space within `tol`. An empty (or vertex-free, unbounded) intersection
    gives (0, 3); nearly dependent triples are skipped rather than solved.
    """
    planes = _finite_rows(planes, width=4)
    length = np.linalg.norm(planes[:, :3], axis=1)
    if np.any((length == 0.0) & (planes[:, 3] < -tol)):
        return np.zeros((0, 3))  # 0 <= d < 0: infeasible
    planes = planes[length > 0.0] / length[length > 0.0, None]
    if len(planes) < 3:
        return np.zeros((0, 3))
    idx = np.asarray(list(itertools.combinations(range(len(planes)), 3)), dtype=np.int64)
    found = []
    for start in range(0, len(idx), 20000):  # chunks bound the (T, P) residual matrix
        chunk = idx[start:start + 20000]
        a, b = planes[chunk, :3], planes[chunk, 3]
        with np.errstate(divide="ignore", invalid="ignore"):  # exactly dependent triples: det 0
            ok = np.abs(np.linalg.det(a)) > _DET_MIN
        if not np.any(ok):
            continue
        x = np.linalg.solve(a[ok], b[ok][..., None])[..., 0]
        inside = np.all(x @ planes[:, :3].T - planes[:, 3] <= tol, axis=1) & np.all(np.isfinite(x), axis=1)
        found.append(x[inside])
    if not found:
        return np.zeros((0, 3))
    return _unique_points(np.concatenate(found), tol)


def box_planes(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 6 half-spaces of an axis-aligned box."""
    eye = np.eye(3)
    return np.concatenate([np.c_[eye, hi], np.c_[-eye, -np.asarray(lo, dtype=np.float64)]])


def box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 8 corners of an axis-aligned box."""
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])],
                    dtype=np.float64)


def cone_planes(light: LightSpec) -> np.ndarray:
    """The spot's light frustum L: the square pyramid around its cone, apex at the
    (light-centred) origin, as 4 half-spaces. In light local coordinates (axis -Z),
    |x| <= t (-z) and |y| <= t (-z) with t = tan(cone / 2)."""
    t = math.tan(float(light.spot_size) / 2.0)
    local = np.array([[1.0, 0.0, t], [-1.0, 0.0, t], [0.0, 1.0, t], [0.0, -1.0, t]]) / math.hypot(1.0, t)
    return np.c_[local @ light.rotation.T, np.zeros(4)]


def _finite_rows(values: np.ndarray, width: int = 3) -> np.ndarray:
    a = np.asarray(values, dtype=np.float64).reshape(-1, width)
    return a[np.all(np.isfinite(a), axis=1)]


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0.0 and math.isfinite(n) else np.array([0.0, 0.0, -1.0])


def _perpendicular_pair(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing unit `d` to an orthonormal basis."""
    helper = np.eye(3)[int(np.argmin(np.abs(d)))]
    e1 = _unit(np.cross(d, helper))
    return e1, np.cross(d, e1)


def _widen(lo: float, hi: float, share: float, floor: float) -> tuple[float, float]:
    """Grow [lo, hi] by `share` of its extent plus `floor` on each side."""
    pad = share * (hi - lo) + floor
    return lo - pad, hi + pad


# ------------------------------------------------------------- input checks


def _check(light: LightSpec, resolution: int) -> None:
    if light.emission not in ("spot", "sun"):
        raise InputError(f"single projective shadow maps take a spot or sun light, not {light.emission!r}; "
                         "use the omnidirectional methods for omni and hemi lights")
    if not int(resolution) >= 1:
        raise InputError(f"shadow map resolution must be a positive number of texels, got {resolution!r}")


def _box(light: LightSpec, scene_lo: np.ndarray, scene_hi: np.ndarray,
         frustum: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The scene box S, light-centred (float64), grown by a relative 1e-9.

    The growth keeps geometry on the box's faces inside, and gives a box collapsed to a
    point (even onto the light) some volume in front of a perspective map's near plane.
    """
    lo = np.asarray(scene_lo, dtype=np.float64).reshape(3)
    hi = np.asarray(scene_hi, dtype=np.float64).reshape(3)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise InputError(f"scene bounds must be finite, got {tuple(lo)} .. {tuple(hi)}")
    origin = light.position
    lo, hi = np.minimum(lo, hi) - origin, np.maximum(lo, hi) - origin
    pad = _BOX_GROWTH * _scale(lo, hi, *([] if frustum is None else [frustum]))
    return lo - pad, hi + pad


def _frustum(light: LightSpec, corners: np.ndarray) -> np.ndarray:
    """The truncated view frustum V (8 corners, near quad then far quad), light-centred."""
    v = np.asarray(corners, dtype=np.float64)
    if v.shape != (8, 3) or not np.all(np.isfinite(v)):
        raise InputError(f"frustum corners must be 8 finite world points (near quad, far quad), got shape {v.shape}")
    return v - light.position


def _scale(*point_sets: np.ndarray) -> float:
    """Magnitude of the coordinates involved; tolerances are relative to it."""
    return max([float(np.abs(p).max(initial=0.0)) for p in point_sets] + [_MIN_SCALE])


def _cut(region: np.ndarray, plane: np.ndarray) -> np.ndarray:
    """Cut a convex polytope, given by its vertices, with the half-space n.x <= d.

    The kept vertices and the crossings of every vertex pair straddling the plane span
    the cut polytope (crossings of non-edges lie inside it, so they change nothing).
    """
    h = plane[3] - region @ plane[:3]  # >= 0 inside
    keep = region[h >= 0.0]
    i, j = np.nonzero((h[:, None] > 0.0) & (h[None, :] < 0.0))
    s = h[i] / (h[i] - h[j])
    out = np.concatenate([keep, region[i] + s[:, None] * (region[j] - region[i])])
    return _unique_points(out, _REL_TOL * _scale(out))


def _region(light: LightSpec, frustum: np.ndarray | None, lo: np.ndarray, hi: np.ndarray,
            tol: float) -> np.ndarray:
    """Vertices of H = M n S n L (paper 4.1), light-centred; V n S, then S, when H is empty.

    M = conv(V, light): the light sits at the origin; for a sun (light at infinity) V is
    extruded toward it (along -axis) until it leaves the scene box.
    """
    s_planes = box_planes(lo, hi)
    if frustum is None:
        return box_corners(lo, hi)
    if light.emission == "spot":
        m_points = np.vstack([frustum, np.zeros((1, 3))])
        # The cone pyramid, cut a hair in front of the apex: an H that is only the light
        # itself (the cone points away from the view) counts as empty.
        reach = max(float((box_corners(lo, hi) @ light.axis).max()), 0.0)
        apex_cut = max(1e-6 * reach, 1e3 * tol)  # well beyond the vertex tolerance
        l_planes = np.concatenate([cone_planes(light), [np.append(-light.axis, -apex_cut)]])
    else:
        # Moving any point of the union box by more than its diagonal leaves S.
        span = np.maximum(hi, frustum.max(axis=0)) - np.minimum(lo, frustum.min(axis=0))
        reach = 1.5 * float(np.linalg.norm(span)) + tol
        m_points = np.vstack([frustum, frustum - light.axis * reach])
        l_planes = np.zeros((0, 4))
    tol = max(tol, _REL_TOL * _scale(m_points))
    h = halfspace_vertices(np.concatenate([hull_planes(m_points, tol), s_planes, l_planes]), tol)
    if len(h):
        return h
    v_in_s = halfspace_vertices(np.concatenate([hull_planes(frustum, tol), s_planes]), tol)
    return v_in_s if len(v_in_s) else box_corners(lo, hi)


# ------------------------------------------------------------------ uniform SM


def sm_map(light: LightSpec, scene_lo: np.ndarray, scene_hi: np.ndarray, resolution: int,
           frustum_corners: np.ndarray | None = None) -> ProjectiveMap:
    """A plain (uniform) shadow map.

    Spot: a perspective frustum along `light.axis`, square window of half-width
    tan(cone / 2) * (1 + SPOT_MARGIN), near/far fitted to S n L (the scene box inside
    the cone's pyramid) with DEPTH_MARGIN, near >= NEAR_FRACTION * far. The view
    frustum is not used (the map is view independent).
    Sun: an orthographic box along `light.axis`, window and depth fitted to H = M n S
    (paper 4.1; S alone without a camera), with WINDOW_MARGIN and DEPTH_MARGIN.
    """
    _check(light, resolution)
    frustum = None if frustum_corners is None else _frustum(light, frustum_corners)
    lo, hi = _box(light, scene_lo, scene_hi, frustum)
    tol = _REL_TOL * _scale(lo, hi, *([] if frustum is None else [frustum]))
    rot, axis = light.rotation, light.axis
    if light.emission == "spot":
        matrix, region = _spot_matrix(light, lo, hi, tol)
        centre = region.mean(axis=0)
        ray = centre if np.linalg.norm(centre) > tol else axis
    else:
        region = _region(light, frustum, lo, hi, tol)
        x, y, d = region @ rot[:, 0], region @ rot[:, 1], region @ axis
        # The floor keeps a flat or point-like region's window non-empty at its coordinates' precision.
        floor = 1e-9 * max(float(np.ptp(x)), float(np.ptp(y)), float(np.ptp(d)), _scale(region))
        x0, x1 = _widen(x.min(), x.max(), WINDOW_MARGIN, floor)
        y0, y1 = _widen(y.min(), y.max(), WINDOW_MARGIN, floor)
        d0, d1 = _widen(d.min(), d.max(), DEPTH_MARGIN, floor)
        # Orthographic rows; z01 = (d - d0) / (d1 - d0) grows along the light's travel,
        # so the occluder (upstream) has the smaller depth.
        matrix = np.zeros((4, 4))
        matrix[0, :3], matrix[0, 3] = 2.0 * rot[:, 0] / (x1 - x0), -(x0 + x1) / (x1 - x0)
        matrix[1, :3], matrix[1, 3] = 2.0 * rot[:, 1] / (y1 - y0), -(y0 + y1) / (y1 - y0)
        matrix[2, :3], matrix[2, 3] = 2.0 * axis / (d1 - d0), -(d0 + d1) / (d1 - d0)
        matrix[3, 3] = 1.0
        centre, ray = region.mean(axis=0), axis
    matrix = face_light_ccw(matrix, centre, ray)
    offset = depth_offset_for(matrix, centre, ray, resolution)
    return ProjectiveMap(matrix, False, offset, "world", 0.0, region)


def _spot_matrix(light: LightSpec, lo: np.ndarray, hi: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Spot SM matrix and its region S n L n {depth >= near}."""
    axis = light.axis
    s_and_l = np.concatenate([box_planes(lo, hi), cone_planes(light)])
    inside = halfspace_vertices(s_and_l, tol)
    depth = (inside if len(inside) else box_corners(lo, hi)) @ axis
    far = max(float(depth.max()) * (1.0 + DEPTH_MARGIN), 1e-6 * _scale(lo, hi))
    # The region is cut at `cut`; the map's near plane sits DEPTH_MARGIN before it.
    cut = min(max(float(depth.min()), NEAR_FRACTION * far), far / (1.0 + DEPTH_MARGIN))
    near = cut * (1.0 - DEPTH_MARGIN)
    region = halfspace_vertices(np.concatenate([s_and_l, [np.append(-axis, -cut)]]), tol) if len(inside) else inside
    cone = math.tan(float(light.spot_size) / 2.0)
    if len(region) == 0:
        # The cone misses the scene box: nothing is lit, the map only has to stay valid.
        # Its region is then the cone's pyramid between the cut and the far plane.
        square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]) * cone
        local = np.concatenate([np.c_[square * t, np.full(4, -t)] for t in (cut, far / (1.0 + DEPTH_MARGIN))])
        region = local @ light.rotation.T
    half = cone * (1.0 + SPOT_MARGIN)
    view = np.eye(4)
    view[:3, :3] = light.rotation.T  # light-centred: the light is the origin, no translation
    proj = np.array([
        [1.0 / half, 0.0, 0.0, 0.0],
        [0.0, 1.0 / half, 0.0, 0.0],
        [0.0, 0.0, -(far + near) / (far - near), -2.0 * far * near / (far - near)],
        [0.0, 0.0, -1.0, 0.0],
    ])
    return proj @ view, region


# ------------------------------------------------------------------ perspective SM


def camera_clip(camera: CameraSpec, near: float, far: float, origin: np.ndarray, shift: float = 0.0) -> np.ndarray:
    """C: light-centred points -> camera clip space, near/far given, camera moved back
    by `shift` along its view axis (paper 4.2: near kept, far grown by the shift).

    The camera's own projection: its window (lens shift, sensor fit, pixel aspect)
    stays, only the clip range changes."""
    m = np.asarray(camera.matrix_world, dtype=np.float64)
    rot = orthonormalize(m[:3, :3])
    view = np.eye(4)
    view[:3, :3] = rot.T
    # Translation folded in float64: view(p) = R^T (p - eye) with p = q + origin.
    view[:3, 3] = rot.T @ (np.asarray(origin, dtype=np.float64) - m[:3, 3])
    view[2, 3] -= shift  # view depth grows by the shift
    proj = dataclasses.replace(camera, clip_start=float(near), clip_end=float(far + shift)).projection()
    return proj @ view


def view_depth(camera: CameraSpec, origin: np.ndarray, points_centred: np.ndarray) -> np.ndarray:
    """Depth along the camera's view axis (-Z) of light-centred points."""
    m = np.asarray(camera.matrix_world, dtype=np.float64)
    forward = -orthonormalize(m[:3, :3])[:, 2]
    return (np.asarray(points_centred, dtype=np.float64) + (np.asarray(origin) - m[:3, 3])) @ forward


def classify_pps_light(light_pps: np.ndarray, centre: np.ndarray, radius: float) -> str:
    """Class of the homogeneous PPS light (l, lw): "directional", "point" or "inverted" (sec. 3).

    lw > 0: a point at l / lw; lw < 0: an inverted point (rays converge to it, found for
    lights behind the camera plane); directional when kappa * radius <= DIRECTIONAL_EPS,
    kappa = |lw| / |lw * centre - l| being the inverse distance from the light to `centre`
    (lw = 0 exactly: a sun parallel to the image plane or a point light in the camera plane).
    """
    ell, lam = np.asarray(light_pps[:3], dtype=np.float64), float(light_pps[3])
    g = float(np.linalg.norm(lam * np.asarray(centre) - ell))
    if abs(lam) * radius <= DIRECTIONAL_EPS * g or lam == 0.0:
        return "directional"
    return "point" if lam > 0.0 else "inverted"


def psm_map(light: LightSpec, camera: CameraSpec, near: float, far: float, frustum_corners: np.ndarray,
            scene_lo: np.ndarray, scene_hi: np.ndarray, resolution: int) -> ProjectiveMap:
    """A perspective shadow map (Stamminger and Drettakis 2002).

    1. H = M n S n L in world space (sec. 4.1), M = conv(V, light) (sun: V extruded
       toward it), L the spot's cone pyramid (none for a sun); fallbacks V n S, S.
    2. Virtual camera shift (sec. 4.2): if a vertex of H has view depth below `near`,
       the camera moves back along its view axis until every vertex is at least `near`
       in front; near is kept, far grows by the shift.
    3. C = projection(near, far + shift) @ view maps H to PPS by its vertices (convex
       and in front of the camera, so its image is the hull of the vertex images) and
       the light to L = C (0, 1) (spot, at the light-centred origin) or C (-axis, 0)
       (sun) (sec. 3).
    4. A standard shadow map in PPS from L, aimed at H's centre, window and depth
       fitted to H's image; see `_pps_fit`.
    The camera may be off-centre (lens shift, any fit or pixel aspect): C is its own
    projection. An orthographic camera is an InputError (`plan_projective` uses sm).
    """
    _check(light, resolution)
    if camera.ortho:
        # PPS of an orthographic camera is an affine image of the world: there is no
        # perspective to undo, and the sec. 4.2 shift assumes an eye. sm is that map.
        raise InputError("psm needs a perspective camera; with an orthographic camera use sm "
                         "(its post-perspective space is the world up to an affine map)")
    near, far = float(near), float(far)
    if not (math.isfinite(near) and math.isfinite(far) and 0.0 < near < far):
        raise InputError(f"view depths must satisfy 0 < near < far, got near={near!r}, far={far!r}")
    frustum = _frustum(light, frustum_corners)
    lo, hi = _box(light, scene_lo, scene_hi, frustum)
    origin = light.position
    tol = _REL_TOL * _scale(lo, hi, frustum)
    region = _region(light, frustum, lo, hi, tol)

    # Sec. 4.2: points behind the camera would land beyond PPS's infinity plane.
    depth = view_depth(camera, origin, region)
    shift = 0.0
    if float(depth.min()) < near * (1.0 - 1e-6):
        shift = near - float(depth.min())
    clip = camera_clip(camera, near, far, origin, shift)
    light_h = clip[:, 3].copy() if light.emission == "spot" else clip[:, :3] @ -light.axis

    fit, region = _pps_fit(clip, light_h, region)
    matrix = fit.matrix @ clip
    matrix /= float(np.abs(matrix).max())  # a positive scale changes nothing but the magnitudes
    centre = region.mean(axis=0)
    if light.emission == "spot":
        ray = centre if np.linalg.norm(centre) > tol else light.axis
    else:
        ray = light.axis
    matrix = face_light_ccw(matrix, centre, ray)
    offset = depth_offset_for(matrix, centre, ray, resolution)
    return ProjectiveMap(matrix, fit.inverted, offset, fit.kind, shift, region)


@dataclass(frozen=True)
class _PPSFit:
    matrix: np.ndarray  # (4, 4) on PPS homogeneous points
    kind: str
    inverted: bool


def _pps_fit(clip: np.ndarray, light_h: np.ndarray, region: np.ndarray) -> tuple[_PPSFit, np.ndarray]:
    """The shadow map in PPS for the homogeneous light `light_h` = (l, lw), fitted to H.

    One formula covers the three PPS lights (sec. 3): in an orthonormal frame (r1, r2, a)
    centred at c, with a the map's view axis and kappa = 1 / (distance from the light to
    c) (0 for a directional light), a point x has y = frame (x - c), u = y_3 and
        W = 1 + kappa u,  p = (y_1, y_2) / W,  zeta = u / W,
    i.e. a perspective from the light (an orthographic map when kappa = 0). The window is
    fitted to p and the depth to zeta (increasing with distance from the light) over H's
    vertices. Writing it in kappa, never with l / lw, keeps a far-away PPS light (tiny
    lw) well conditioned. For an inverted light (lw < 0) the map is the same perspective
    from l / lw; only the depth order of the occluder flips (sec. 3.1).
    Returns the fit and H's (possibly cut) vertices, light-centred.
    """
    hom = region @ clip[:, :3].T + clip[:, 3]
    pps = hom[:, :3] / hom[:, 3:]  # hom w = shifted view depth > 0
    c = pps.mean(axis=0)
    radius = max(float(np.linalg.norm(pps - c, axis=1).max()), 1e-12 * (float(np.abs(c).max()) + 1.0))
    ell, lam = light_h[:3], float(light_h[3])
    kind = classify_pps_light(light_h, c, radius)
    if kind == "directional":
        a, kappa = _unit(-ell), 0.0  # light travels along -l
    else:
        g = lam * c - ell  # = lw (c - l / lw)
        big_g = float(np.linalg.norm(g))
        if big_g > 1e-6 * abs(lam) * radius:  # else the light sits at H's centre (ill-conditioned aim)
            a, kappa = math.copysign(1.0, lam) * g / big_g, abs(lam) / big_g
        else:
            # The light sits at H's centre: aim along the mean direction to the vertices.
            light_pos = ell / lam
            dirs = pps - light_pos
            dirs = dirs / np.maximum(np.linalg.norm(dirs, axis=1, keepdims=True), _TINY)
            a = _unit(dirs.sum(axis=0))
            reach = float(((pps - light_pos) @ a).max())
            reach = reach if reach > 0.0 else radius
            c, kappa = light_pos + reach * a, 1.0 / reach
    up = np.array([0.0, 1.0, 0.0]) if abs(a[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    r2 = _unit(up - (up @ a) * a)
    r1 = np.cross(r2, -a)  # (r1, r2, -a) right-handed, like an OpenGL view
    frame = np.stack([r1, r2, a])
    affine = np.eye(4)
    affine[:3, :3], affine[:3, 3] = frame, -frame @ c

    w_row = kappa * (affine[2] @ clip)  # W - 1 as a row on light-centred (q, 1), times the view depth
    base = clip[3]

    def weights(points: np.ndarray) -> np.ndarray:
        h = points @ clip[:, :3].T + clip[:, 3]
        return 1.0 + kappa * (((h[:, :3] / h[:, 3:]) - c) @ a)

    w = weights(region)
    if kappa > 0.0 and float(w.min()) < NEAR_FRACTION * float(w.max()):
        # Near plane at NEAR_FRACTION of the far one: cut H there. W - w0 times the view
        # depth is linear in the light-centred point, so the cut is a plane there too.
        w0 = NEAR_FRACTION * float(w.max())
        row = base * (1.0 - w0) + w_row  # (W - w0) * depth as a row
        norm = float(np.linalg.norm(row[:3]))
        cut = _cut(region, np.append(-row[:3], row[3]) / norm) if norm > 0.0 else region
        if len(cut):
            region, w = cut, weights(cut)
    if not np.all(w > 0.0):
        # Only a region collapsed onto the light gets here: keep what the map can see,
        # or the point of the axis at the frame's centre (W = 1).
        region = region[w > 0.0]
        if len(region) == 0:
            q = np.linalg.solve(clip, np.append(c, 1.0))
            region = (q[:3] / q[3])[None]
        w = weights(region)
    hom = region @ clip[:, :3].T + clip[:, 3]
    y = (hom[:, :3] / hom[:, 3:] - c) @ frame.T
    p, zeta = y[:, :2] / w[:, None], y[:, 2] / w
    floor = 1e-9 * max(float(np.ptp(p[:, 0])), float(np.ptp(p[:, 1])), float(np.ptp(zeta)), radius,
                       float(np.abs(c).max()))
    x0, x1 = _widen(p[:, 0].min(), p[:, 0].max(), WINDOW_MARGIN, floor)
    y0, y1 = _widen(p[:, 1].min(), p[:, 1].max(), WINDOW_MARGIN, floor)
    z0, z1 = _widen(zeta.min(), zeta.max(), DEPTH_MARGIN, floor)
    sx, sy, sz = x1 - x0, y1 - y0, z1 - z0
    # Rows on (y1, y2, u, 1): clip.xyz / clip.w gives (2 p - (lo + hi)) / (hi - lo), same for zeta.
    k = np.array([
        [2.0 / sx, 0.0, -(x0 + x1) * kappa / sx, -(x0 + x1) / sx],
        [0.0, 2.0 / sy, -(y0 + y1) * kappa / sy, -(y0 + y1) / sy],
        [0.0, 0.0, (2.0 - (z0 + z1) * kappa) / sz, -(z0 + z1) / sz],
        [0.0, 0.0, kappa, 1.0],
    ])
    return _PPSFit(k @ affine, kind, kind == "inverted"), region
