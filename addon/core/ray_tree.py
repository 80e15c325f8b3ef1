"""A bounding-box tree over triangles for shadow segments: what a sample's segment to one
light point crosses, found in about log(T) box tests instead of one test per triangle.

The tree is complete and implicit: the leaves hold `LEAF` triangles each (the last ones
padded with empty slots), and the nodes are numbered as a heap from 1 (node j's children
are 2j and 2j + 1, leaves from `leaves` on), so a walk needs no stack and no links: after a
node is done, the next one is found from its number alone (`next_node`). That also makes a
walk resumable from one integer, which the GPU needs where a driver cuts long loops
(llvmpipe ends any loop after 65,535 iterations of one invocation).

Each node splits its triangles at the median of their centres along the longest axis of
those centres. Boxes are widened by a small share of their size so that float32 rounding
of a segment's slab test never loses a triangle the segment crosses. An empty leaf's box is
a point far outside every scene (`FAR`), which no segment reaches.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Triangles a leaf holds: of 2, 4 and 8, 4 walked the furnished interior's segments fastest
# on llvmpipe (notebook 2026-12-08).
LEAF = 4
# An empty leaf's box: one point no segment of a scene reaches.
FAR = 1e30
# Boxes grow by this share of their size, plus ABSOLUTE_PAD, against float32 rounding.
RELATIVE_PAD = 1e-5
ABSOLUTE_PAD = 1e-6


@dataclass(frozen=True)
class RayTree:
    """triangles: (leaves * LEAF, 3, 3) float32 in leaf order, empty slots all zero (a
    degenerate triangle no segment crosses); order: each slot's index into the input, -1 for
    an empty slot; lo, hi: (2 * leaves, 3) float32, node j's box at row j (row 0 unused)."""

    triangles: np.ndarray
    order: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    leaves: int

    @property
    def nodes(self) -> int:
        return 2 * self.leaves - 1


def build(triangles: np.ndarray) -> RayTree:
    """The tree over (T, 3, 3) triangles (any float type; T may be 0)."""
    tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    count = len(tris)
    leaves = 1 << max(0, int(np.ceil(np.log2(max(1, -(-count // LEAF))))))
    slots = leaves * LEAF
    centre = np.zeros((slots, 3))
    centre[:count] = tris.mean(axis=1)
    real = np.arange(slots) < count
    order = np.arange(slots)
    groups = 1
    while groups < leaves:  # every group of a level splits at its median, all at once
        c = centre[order].reshape(groups, -1, 3)
        r = real[order].reshape(groups, -1, 1)
        lo = np.where(r, c, np.inf).min(axis=1)
        hi = np.where(r, c, -np.inf).max(axis=1)
        axis = np.argmax(np.where(np.isfinite(hi - lo), hi - lo, -1.0), axis=1)
        key = np.take_along_axis(c, axis[:, None, None], axis=2)[..., 0]
        key = np.where(r[..., 0], key, np.inf)  # empty slots go last
        within = np.argsort(key, axis=1, kind="stable")
        order = np.take_along_axis(order.reshape(groups, -1), within, axis=1).reshape(-1)
        groups *= 2
    order = np.where(order < count, order, -1)
    slotted = np.zeros((slots, 3, 3))
    slotted[order >= 0] = tris[order[order >= 0]]
    lo = np.full((2 * leaves, 3), FAR)
    hi = np.full((2 * leaves, 3), FAR)
    filled = (order >= 0).reshape(leaves, LEAF)
    corners = slotted.reshape(leaves, LEAF * 3, 3)
    mask = np.repeat(filled, 3, axis=1)[..., None]
    any_filled = filled.any(axis=1)
    lo[leaves:][any_filled] = np.where(mask, corners, np.inf).min(axis=1)[any_filled]
    hi[leaves:][any_filled] = np.where(mask, corners, -np.inf).max(axis=1)[any_filled]
    first = leaves
    while first > 1:  # each level's boxes from its children's, bottom up
        parents = np.arange(first // 2, first)
        left, right = 2 * parents, 2 * parents + 1
        empty_l, empty_r = lo[left, 0] >= FAR, lo[right, 0] >= FAR
        lo[parents] = np.where(empty_l[:, None], lo[right], np.where(empty_r[:, None], lo[left],
                                                                     np.minimum(lo[left], lo[right])))
        hi[parents] = np.where(empty_l[:, None], hi[right], np.where(empty_r[:, None], hi[left],
                                                                     np.maximum(hi[left], hi[right])))
        first //= 2
    real_box = lo[:, 0] < FAR
    pad = ((hi - lo) + np.maximum(np.abs(lo), np.abs(hi))) * RELATIVE_PAD + ABSOLUTE_PAD
    lo[real_box] -= pad[real_box]
    hi[real_box] += pad[real_box]
    return RayTree(slotted.astype(np.float32), order, lo.astype(np.float32), hi.astype(np.float32), leaves)


def texels(tree: RayTree, width: int) -> tuple[np.ndarray, np.ndarray]:
    """The two tables as RGBA32F texture data `width` texels wide, (rows, width, 4) each:
    the boxes (node j's lo at texel 2j, hi at 2j + 1) and the slots' corners (three texels a
    slot, in leaf order)."""
    boxes = np.zeros((2 * len(tree.lo), 4), dtype=np.float32)
    boxes[0::2, :3], boxes[1::2, :3] = tree.lo, tree.hi
    corners = np.zeros((3 * len(tree.triangles), 4), dtype=np.float32)
    corners[:, :3] = tree.triangles.reshape(-1, 3)
    out = []
    for table in (boxes, corners):
        rows = -(-len(table) // width)
        padded = np.zeros((rows * width, 4), dtype=np.float32)
        padded[:len(table)] = table
        out.append(padded.reshape(rows, width, 4))
    return out[0], out[1]


def next_node(node: int) -> int:
    """The node after `node` and its subtree in the walk's order; 0 when none is left."""
    while node & 1:  # a right child: its parent's subtree is done too
        node >>= 1
    return node + 1 if node else 0


def segment_boxes(lo: np.ndarray, hi: np.ndarray, p: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Whether the segment p + t d, t in [0, 1], meets each box (slab test; arrays broadcast)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t0, t1 = (lo - p) * inv, (hi - p) * inv
    near = np.nan_to_num(np.minimum(t0, t1), nan=-np.inf)
    far = np.nan_to_num(np.maximum(t0, t1), nan=np.inf)
    return np.maximum(near.max(axis=-1), 0.0) <= np.minimum(far.min(axis=-1), 1.0)


def crossings(tris: np.ndarray, p: np.ndarray, d: np.ndarray, eps: float) -> np.ndarray:
    """Whether the segment p + t d crosses each of (T, 3, 3) triangles at t in (eps, 1):
    on the inner side of the three edge planes through p (edges closed, so two triangles
    that share an edge leave no gap) and crossing the plane there. float64."""
    tris = np.asarray(tris, dtype=np.float64)
    rel = tris - p
    sides = np.stack([np.einsum("tk,k->t", np.cross(rel[:, a], rel[:, b]), d)
                      for a, b in ((0, 1), (1, 2), (2, 0))], axis=1)
    inside = np.all(sides >= 0.0, axis=1) | np.all(sides <= 0.0, axis=1)
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    along = normal @ d
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("tk,tk->t", normal, rel[:, 0]) / along
    return inside & (along != 0.0) & (t > eps) & (t < 1.0)


def walk(tree: RayTree, p: np.ndarray, d: np.ndarray, eps: float) -> tuple[bool, int]:
    """The GPU's walk, on the host: whether a triangle blocks p + t d, t in (eps, 1), and
    how many nodes it visited (the test oracle of lib/ray_tree.glsl)."""
    p, d = np.asarray(p, dtype=np.float64), np.asarray(d, dtype=np.float64)
    node, visits = 1, 0
    while node:
        visits += 1
        inside = bool(segment_boxes(tree.lo[node].astype(np.float64), tree.hi[node].astype(np.float64), p, d))
        if inside and node < tree.leaves:
            node *= 2
            continue
        if inside:
            first = (node - tree.leaves) * LEAF
            if crossings(tree.triangles[first:first + LEAF], p, d, eps).any():
                return True, visits
        node = next_node(node)
    return False, visits
