"""Paraboloid and cube-face projections, forward and inverse (numpy, float64).

Every layer works in its own local frame with the layer axis along +Z
(docs/design.md section 4). Map coordinates `xy` lie in [-1, 1]^2; texture
coordinates are uv = 0.5 + 0.5 * xy, texel (i, j) = floor(uv * res).

Paraboloid (Brabec et al. 2002, eq. 1-3): for a unit direction v with v_z >= 0,
    (x, y) = (v_x, v_y) / (1 + v_z)
which is the stereographic projection from the opposite pole, so the front
hemisphere fills the unit disk. It is singular only at v_z = -1, which a side
never sees because triangles are split at the seam plane first.

Cube face: a 90 degree perspective view, (x, y) = (p_x, p_y) / p_z.

Sphere unfolding (Stockli Contreras et al., eq. 1): the azimuthal equidistant
projection about the layer's +Z pole, (x, y) = (theta / pi) (v_x, v_y) / |v_xy| with
theta the angle from the pole. The whole sphere fills the unit disk; the opposite
pole is singular (it becomes the rim circle). Eq. 1 writes the same map about the
y- pole: theta = arcsin(y) + pi/2, so its y is our -z.
"""
from __future__ import annotations

import numpy as np

PARABOLOID = 0
CUBE = 1
UNFOLD = 2
PROJECTIVE = 3  # a spot or sun map: one 4x4 matrix (addon/core/perspective.py), no function here

_TINY = float(np.finfo(np.float64).tiny)
# Coordinates beyond this are treated like inf: Blender stores an inf vertex as FLT_MAX,
# and one such vertex would otherwise set the scene's depth range and every tolerance.
MAX_COORDINATE = 1e15
# Squared lengths safely inside float64's normal range (see unit_directions).
_SQUARE_MIN = 1e-290
_SQUARE_MAX = 1e290


def unit_directions(points: np.ndarray) -> np.ndarray:
    """Unit vectors of points (..., 3); the origin gives (0, 0, 0).

    Points whose squared length would under- or overflow (coordinates beyond about
    1e±150) are divided by their largest component first. The rest, nearly always all
    of them, take the direct path, which is several times faster (tessellation
    projects hundreds of thousands of points a frame).
    """
    p = np.asarray(points, dtype=np.float64)
    squared = np.einsum("...i,...i->...", p, p)
    direct = (squared > _SQUARE_MIN) & (squared < _SQUARE_MAX)
    if np.all(direct):
        return p / np.sqrt(squared)[..., None]
    out = np.zeros(p.shape)
    out[direct] = p[direct] / np.sqrt(squared[direct])[..., None]
    rest = p[~direct]
    scale = np.max(np.abs(rest), axis=-1, keepdims=True)
    nonzero = scale > 0.0
    q = rest / np.where(nonzero, scale, 1.0)
    out[~direct] = np.where(nonzero, q / np.where(nonzero, np.linalg.norm(q, axis=-1, keepdims=True), 1.0), 0.0)
    return out


def paraboloid_project(local: np.ndarray) -> np.ndarray:
    """Map layer-local points (..., 3) to paraboloid coordinates (..., 2).

    The point is normalised first, so the result depends only on direction.
    Points at the origin map to the centre (they subtend no solid angle).
    """
    p = np.asarray(local, dtype=np.float64)
    squared = np.einsum("...i,...i->...", p, p)
    if np.all((squared > _SQUARE_MIN) & (squared < _SQUARE_MAX)):
        # v.xy / (1 + v.z) with v = p / |p|, without normalising all three components.
        length = np.sqrt(squared)
        return p[..., :2] / np.maximum(length + p[..., 2], _TINY * length)[..., None]
    v = unit_directions(p)
    denom = 1.0 + v[..., 2:3]
    return v[..., :2] / np.maximum(denom, _TINY)


def paraboloid_unproject(xy: np.ndarray) -> np.ndarray:
    """Inverse of `paraboloid_project`: unit directions for map points (..., 2).

    Inverse stereographic projection: v = (2x, 2y, 1 - r^2) / (1 + r^2).
    """
    q = np.asarray(xy, dtype=np.float64)
    r2 = np.sum(q * q, axis=-1, keepdims=True)
    return np.concatenate([2.0 * q, 1.0 - r2], axis=-1) / (1.0 + r2)


def cube_project(local: np.ndarray) -> np.ndarray:
    """Map face-local points (..., 3) with p_z > 0 to face coordinates (..., 2)."""
    p = np.asarray(local, dtype=np.float64)
    z = p[..., 2:3]
    # Only p_z > 0 is meaningful; the guard and the clamp keep points on or behind
    # the face plane (or grazing it) finite.
    return np.clip(p[..., :2] / np.where(z > 0.0, z, 1e-300), -1e30, 1e30)


def cube_unproject(xy: np.ndarray) -> np.ndarray:
    """Unit directions for cube-face coordinates (..., 2)."""
    q = np.asarray(xy, dtype=np.float64)
    d = np.concatenate([q, np.ones(q.shape[:-1] + (1,))], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def unfold_project(local: np.ndarray) -> np.ndarray:
    """Map layer-local points (..., 3) to sphere-unfolding coordinates (..., 2) in the unit disk.

    The angle from the pole comes from atan2, which stays accurate at both poles
    (arccos(v_z) loses half its digits there). The pole itself maps to the centre;
    the opposite pole, whose azimuth is undefined, to (1, 0) on the rim.
    """
    v = unit_directions(local)
    rho = np.hypot(v[..., 0], v[..., 1])
    theta = np.arctan2(rho, v[..., 2])
    # theta / (pi rho) -> 1/pi as rho -> 0 on the near side (theta ~ rho there).
    near_pole = rho <= 1e-300
    scale = np.where(near_pole, 1.0 / np.pi, theta / (np.pi * np.where(near_pole, 1.0, rho)))
    xy = v[..., :2] * scale[..., None]
    far_pole = near_pole & (v[..., 2] < 0.0)
    return np.where(far_pole[..., None], np.array([1.0, 0.0]), xy)


def unfold_unproject(xy: np.ndarray) -> np.ndarray:
    """Inverse of `unfold_project`: unit directions for points (..., 2) of the unit disk."""
    q = np.asarray(xy, dtype=np.float64)
    r = np.linalg.norm(q, axis=-1, keepdims=True)
    theta = np.pi * r
    # sin(pi r) / r -> pi at the centre.
    ratio = np.where(r > 1e-300, np.sin(theta) / np.where(r > 1e-300, r, 1.0), np.pi)
    return np.concatenate([q * ratio, np.cos(theta)], axis=-1)


def project(kind: int, local: np.ndarray) -> np.ndarray:
    """Project with the layer kind (PARABOLOID, CUBE or UNFOLD)."""
    if kind == PARABOLOID:
        return paraboloid_project(local)
    return unfold_project(local) if kind == UNFOLD else cube_project(local)


def unproject(kind: int, xy: np.ndarray) -> np.ndarray:
    """Inverse projection with the layer kind."""
    if kind == PARABOLOID:
        return paraboloid_unproject(xy)
    return unfold_unproject(xy) if kind == UNFOLD else cube_unproject(xy)


def xy_to_texel(xy: np.ndarray, resolution: int) -> np.ndarray:
    """Continuous texel coordinates (texel centres at i + 0.5) of map points."""
    return (np.asarray(xy, dtype=np.float64) * 0.5 + 0.5) * resolution


def texel_index(xy: np.ndarray, resolution: int) -> np.ndarray:
    """Integer texel (column, row) containing each map point, clamped to the map."""
    idx = np.floor(xy_to_texel(xy, resolution)).astype(np.int64)
    return np.clip(idx, 0, resolution - 1)


def texel_angle(kind: int, xy: np.ndarray, resolution: int) -> np.ndarray:
    """Angular size (radians) of one texel at map point `xy`, to first order.

    For the cube it is the larger of the two directions (tangential); over a whole
    texel step the true angle can exceed it by about 2/res relative.

    Paraboloid: r = tan(theta/2), so d(theta)/dr = 2 / (1 + r^2); one texel spans
    2/res in r. Cube: a step dx on the plane z = 1 at distance rho = sqrt(1 + r^2)
    turns the ray by at most dx / rho (the tangential direction). Unfold: theta = pi r,
    so radially pi per unit of r; tangentially sin(pi r) / r <= pi: pi * step bounds both.
    """
    q = np.asarray(xy, dtype=np.float64)
    r2 = np.sum(q * q, axis=-1)
    step = 2.0 / resolution
    if kind == UNFOLD:
        return np.full(r2.shape, np.pi * step)
    if kind == PARABOLOID:
        return step * 2.0 / (1.0 + r2)
    return step / np.sqrt(1.0 + r2)


def normalized_depth(distance: np.ndarray, near: float, far: float) -> np.ndarray:
    """Normalised radial depth (L - near) / (far - near)."""
    return (np.asarray(distance, dtype=np.float64) - near) / (far - near)


def finite_points(points: np.ndarray, limit: float = np.inf) -> np.ndarray:
    """(...) bool: the points (..., 3) whose three coordinates are finite and below `limit`.

    Component by component: numpy reduces a short last axis (np.all(..., axis=-1)) many
    times slower, and this runs over every view sample each frame.
    """
    p = np.asarray(points)
    mask = np.isfinite(p[..., 0]) & np.isfinite(p[..., 1]) & np.isfinite(p[..., 2])
    if limit < np.inf:
        for k in range(3):
            mask &= np.abs(p[..., k]) < limit
    return mask


def finite_bounds(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """World bounding box (lo, hi) of the finite corners, or None when there is none.

    Coordinates beyond MAX_COORDINATE count as infinite (Blender's inf is FLT_MAX).
    """
    pts = np.asarray(triangles, dtype=np.float64).reshape(-1, 3)
    pts = pts[finite_points(pts, MAX_COORDINATE)]
    if len(pts) == 0:
        return None
    # Column by column, for the same reason as in finite_points.
    return (np.array([pts[:, k].min() for k in range(3)]), np.array([pts[:, k].max() for k in range(3)]))


def depth_range(triangles: np.ndarray, light_position: np.ndarray, margin: float = 0.01,
                bounds: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[float, float]:
    """Near and far radial distances from the light to the scene's bounding box.

    near is the distance from the light to the box (0 when the light is inside),
    far the distance to its farthest corner; both get a relative margin so that
    geometry on the box surface stays strictly inside (0, 1) depth. `bounds`, from
    `finite_bounds`, saves scanning the triangles again.
    """
    light = np.asarray(light_position, dtype=np.float64)
    if bounds is None:
        bounds = finite_bounds(triangles)
    if bounds is None:
        return 0.0, 1.0
    lo, hi = bounds
    nearest = np.clip(light, lo, hi)
    near = float(np.linalg.norm(nearest - light))
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    far = float(np.max(np.linalg.norm(corners - light, axis=1)))
    near = near * (1.0 - margin)
    far = far * (1.0 + margin)
    # A flat or point-like scene still needs a non-empty range.
    far = max(far, near + 1e-6 * max(1.0, far))
    return near, far
