"""Faces laid over other faces: coplanar triangles whose insides overlap (a Mirror or Array
modifier that lays a copy onto the original, a boolean that leaves a face over another).

Cycles' shadow ray skips only the primitive it leaves from, so a point on such a face is
shadowed by the other one whenever float32 rounding leaves it on or behind that face's
plane (always on a face along the axes, whose points share the plane's coordinate). The
exact pass follows that for the triangles flagged here (lib/exact_walk.glsl's
ow_exact_twin); neighbours that only share an edge, or meet at a fold, are not flagged.
"""
from __future__ import annotations

import numpy as np

# Planes closer than this share of the set's extent (offset) or in direction (unit normal)
# are one plane; an overlap thinner than this share of the extent is a shared edge.
PLANE_SHARE = 1e-6
# Most candidate pairs checked at once (memory: a few arrays of this many float64).
_BATCH = 1_000_000


def overlapping_faces(tris: np.ndarray) -> np.ndarray:
    """(T,) bool: the triangles of (T, 3, 3) that another coplanar triangle of the set
    overlaps with a positive area (either facing)."""
    tris = np.asarray(tris, dtype=np.float64).reshape(-1, 3, 3)
    out = np.zeros(len(tris), dtype=bool)
    if len(tris) < 2:
        return out
    extent = float(np.ptp(tris.reshape(-1, 3), axis=0).max())
    if not np.isfinite(extent) or extent <= 0.0:
        return out
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    length = np.linalg.norm(normal, axis=1)
    ok = length > 0.0
    normal = normal / np.where(ok, length, 1.0)[:, None]
    axis = np.argmax(np.abs(normal), axis=1)
    normal *= np.sign(normal[np.arange(len(tris)), axis])[:, None]  # one direction for both facings
    offset = np.einsum("ij,ij->i", normal, tris[:, 0])
    key = np.column_stack([np.round(normal / PLANE_SHARE), np.round(offset / (PLANE_SHARE * extent)),
                           axis]).astype(np.int64)
    key[~ok] = np.arange(int((~ok).sum()))[:, None] - (1 << 40)  # degenerate: a plane of its own
    # Planes by one 64-bit hash of their key (a sort of rows costs several times more); a
    # pair of triangles is compared only if their keys are equal, so a collision costs
    # a few pair tests, never a wrong flag.
    mix = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9, 0x27D4EB2F165667C5,
                    0x94D049BB133111EB], dtype=np.uint64)
    hashed = (key.astype(np.uint64) * mix).sum(axis=1, dtype=np.uint64)
    _, group, counts = np.unique(hashed, return_inverse=True, return_counts=True)
    group = group.reshape(-1)
    shared = np.flatnonzero(counts[group] > 1)
    if not len(shared):
        return out
    # Within each plane: 2D triangles (the plane's dominant axis dropped), candidate pairs
    # from the cells of a grid that their boxes touch (cells about a triangle's size, so a
    # tiled floor gives a few pairs a triangle), then separating axes.
    flat = _flat(tris[shared], axis[shared])
    lo, hi = flat.min(axis=1), flat.max(axis=1)
    tol = PLANE_SHARE * extent
    cell = max(float(np.median(np.max(hi - lo, axis=1))), tol)
    first, second = _cell_pairs(group[shared], np.floor(lo / cell).astype(np.int64),
                                np.floor(hi / cell).astype(np.int64))
    for begin in range(0, len(first), _BATCH):
        i, j = first[begin:begin + _BATCH], second[begin:begin + _BATCH]
        boxes = np.all((lo[i] < hi[j] - tol) & (lo[j] < hi[i] - tol), axis=1) & np.all(
            key[shared[i]] == key[shared[j]], axis=1)
        i, j = i[boxes], j[boxes]
        hit = _overlap(flat[i], flat[j], tol)
        out[shared[i[hit]]] = True
        out[shared[j[hit]]] = True
    return out


def _flat(tris: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """(T, 3, 2): each triangle without its dominant normal axis."""
    keep = np.array([[1, 2], [0, 2], [0, 1]])[axis]  # (T, 2)
    return np.take_along_axis(tris, keep[:, None, :].repeat(3, axis=1), axis=2)


def _cell_pairs(plane: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs of triangles of one plane (`plane`, N) whose cell ranges lo..hi (N, 2)
    share a cell (a pair may come more than once). A triangle over more than 4 x 4 cells is
    entered only in the cells of its box's corners and centre: a large face laid over a
    copy of itself shares those, but a small face over the middle of a large one is missed
    (left unflagged, so lit, as without this check)."""
    size = hi - lo + 1
    small = np.all(size <= 4, axis=1)
    idx, big = np.flatnonzero(small), np.flatnonzero(~small)
    parts = []
    for dx in range(4):
        for dy in range(4):
            keep = idx[(dx < size[idx, 0]) & (dy < size[idx, 1])]
            parts.append((keep, lo[keep, 0] + dx, lo[keep, 1] + dy))
    for cx, cy in ((lo[big, 0], lo[big, 1]), (hi[big, 0], lo[big, 1]), (lo[big, 0], hi[big, 1]),
                   (hi[big, 0], hi[big, 1]), ((lo[big, 0] + hi[big, 0]) // 2, (lo[big, 1] + hi[big, 1]) // 2)):
        parts.append((big, cx, cy))
    tri = np.concatenate([part[0] for part in parts])
    cx = np.concatenate([part[1] for part in parts])
    cy = np.concatenate([part[2] for part in parts])
    order = np.lexsort((tri, cy, cx, plane[tri]))
    tri, cx, cy, pl = tri[order], cx[order], cy[order], plane[tri[order]]
    new_cell = np.concatenate([[True], (cx[1:] != cx[:-1]) | (cy[1:] != cy[:-1]) | (pl[1:] != pl[:-1])])
    cell_end = np.searchsorted(np.cumsum(new_cell), np.cumsum(new_cell), side="right")
    starts = np.arange(len(tri)) + 1
    spans = cell_end - starts
    first = np.repeat(np.arange(len(tri)), spans)
    second = np.repeat(starts - np.concatenate([[0], np.cumsum(spans)[:-1]]), spans) + np.arange(int(spans.sum()))
    return tri[first], tri[second]


def _overlap(a: np.ndarray, b: np.ndarray, tol: float) -> np.ndarray:
    """(N,) bool: whether 2D triangles a and b (N, 3, 2) overlap by more than `tol` along
    every one of their six edge normals (no separating axis)."""
    overlap = np.ones(len(a), dtype=bool)
    for tri in (a, b):
        for k in range(3):
            edge = tri[:, (k + 1) % 3] - tri[:, k]
            n = np.stack([-edge[:, 1], edge[:, 0]], axis=1)
            n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
            pa, pb = np.einsum("nkd,nd->nk", a, n), np.einsum("nkd,nd->nk", b, n)
            overlap &= (pa.max(axis=1) > pb.min(axis=1) + tol) & (pb.max(axis=1) > pa.min(axis=1) + tol)
    return overlap
