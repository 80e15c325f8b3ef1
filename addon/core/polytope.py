"""The sample polytope: a convex polytope that holds every view sample of a frame.

It is the strictly truncated view frustum cut by the axis-aligned box of the samples
themselves. Both hold every sample, so their intersection does too, and it is often
much smaller than the frustum alone: a frustum looking down onto a courtyard spans
the air above the walls, the box of the samples ends at the wall tops.

Layer boxes (map-space culling), the IPSM cone and the skewed cut all need only the
polytope's image from the light. Seen from a point outside a convex body, that image is
bounded by the images of the body's edges, so the polytope keeps its vertices and edges.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

# Relative tolerance (of the polytope's extent) for a vertex to lie on a plane.
_ON_PLANE = 1e-9


@dataclass(frozen=True)
class Polytope:
    """A bounded convex polytope: outward planes n.x <= d, its vertices and edges."""

    planes: np.ndarray  # (P, 4): unit normal n and offset d per row
    vertices: np.ndarray  # (V, 3)
    edges: np.ndarray  # (E, 2) vertex index pairs

    def contains(self, point: np.ndarray) -> bool:
        """True when `point` lies inside or on the boundary."""
        p = np.asarray(point, dtype=np.float64)
        scale = float(np.abs(self.vertices).max()) + float(np.abs(p).max()) + 1e-30
        return bool(np.all(self.planes[:, :3] @ p - self.planes[:, 3] <= _ON_PLANE * scale))

    def edge_points(self, per_edge: int) -> np.ndarray:
        """Points along every edge, ends included, (E * per_edge, 3)."""
        a, b = self.vertices[self.edges[:, 0]], self.vertices[self.edges[:, 1]]
        t = np.linspace(0.0, 1.0, per_edge)[None, :, None]
        return (a[:, None, :] + t * (b - a)[:, None, :]).reshape(-1, 3)


def frustum_planes(corners: np.ndarray) -> np.ndarray:
    """Outward unit planes (6, 4) of a frustum given as near quad + far quad (8, 3)."""
    c = np.asarray(corners, dtype=np.float64)
    centre = c.mean(axis=0)
    faces = [(c[0], c[1], c[2]), (c[4], c[5], c[6])]  # near, far
    faces += [(c[i], c[(i + 1) % 4], c[4 + i]) for i in range(4)]  # sides
    planes = []
    for a, b, d in faces:
        n = np.cross(b - a, d - a)
        n /= np.linalg.norm(n)
        if np.dot(n, a - centre) < 0.0:
            n = -n
        planes.append([*n, float(np.dot(n, a))])
    return np.asarray(planes)


def box_planes(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Outward unit planes (6, 4) of the axis-aligned box [lo, hi]."""
    planes = []
    for axis in range(3):
        n = np.zeros(3)
        n[axis] = 1.0
        planes.append([*n, float(hi[axis])])
        planes.append([*(-n), float(-lo[axis])])
    return np.asarray(planes)


def polytope_of_planes(planes: np.ndarray) -> Polytope | None:
    """Vertices and edges of the bounded polytope {x: n.x <= d}, or None when it is empty.

    Vertex enumeration over every triple of planes: with the 12 planes of a frustum
    and a box that is 220 small solves, done at once.
    """
    planes = np.asarray(planes, dtype=np.float64)
    triples = np.array(list(itertools.combinations(range(len(planes)), 3)))
    normals = planes[triples, :3]  # (T, 3, 3)
    offsets = planes[triples, 3]  # (T, 3)
    det = np.linalg.det(normals)
    solvable = np.abs(det) > 1e-12
    if not np.any(solvable):
        return None
    points = np.linalg.solve(normals[solvable], offsets[solvable][..., None])[..., 0]
    scale = float(np.abs(planes[:, 3]).max()) + 1e-30
    slack = planes[:, :3] @ points.T - planes[:, 3:4]  # (P, T)
    inside = np.all(slack <= _ON_PLANE * scale, axis=0)
    points, slack = points[inside], slack[:, inside]
    if len(points) < 4:
        return None  # empty, or too flat to hold anything
    # Several triples meet at one vertex where more than three planes do: merge them.
    near = np.abs(points[:, None, :] - points[None, :, :]).max(axis=2) <= _ON_PLANE * scale * 10
    first = np.argmax(near, axis=1)  # the first point each point coincides with
    vertices = points[first == np.arange(len(points))]
    on_plane = np.abs(planes[:, :3] @ vertices.T - planes[:, 3:4]) <= _ON_PLANE * scale * 10  # (P, V)
    # Two vertices on two common planes that are not parallel lie on one edge line; the
    # polytope is convex, so the segment between them is on its boundary.
    normals = planes[:, :3]
    crossing = np.abs(np.cross(normals[:, None, :], normals[None, :, :])).max(axis=2) > 1e-9  # (P, P)
    shared = (on_plane[:, :, None] & on_plane[:, None, :]).astype(np.int64)  # (P, V, V)
    on_two = np.einsum("aij,ab,bij->ij", shared, crossing.astype(np.int64), shared) > 0
    i, j = np.nonzero(np.triu(on_two, k=1))
    return Polytope(planes, vertices, np.stack([i, j], axis=1))


def sample_polytope(corners: np.ndarray, box: tuple[np.ndarray, np.ndarray] | None) -> Polytope | None:
    """The frustum `corners` cut by the samples' axis-aligned `box` (lo, hi).

    The box is grown by a millionth of the scene's coordinates, so samples on its faces
    stay inside after rounding. None without a box (no samples).
    """
    if box is None:
        return None
    lo, hi = (np.asarray(v, dtype=np.float64) for v in box)
    reach = 1e-6 * (float(np.abs(corners).max()) + max(float(np.abs(lo).max()), float(np.abs(hi).max()))) + 1e-30
    frustum = frustum_planes(corners)
    polytope = polytope_of_planes(np.concatenate([frustum, box_planes(lo - reach, hi + reach)]))
    # The samples lie in both, so an empty cut can only come from rounding: keep the frustum.
    return polytope if polytope is not None else polytope_of_planes(frustum)
