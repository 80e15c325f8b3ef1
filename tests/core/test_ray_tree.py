"""core/ray_tree.py: the implicit tree holds every triangle once, its boxes hold what lies
under them, and its stackless walk finds a blocker exactly when one of all the triangles
blocks the segment."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import ray_tree

EPS = 1e-4


def _scene(count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-2.0, 2.0, (count, 1, 3))
    return centres + rng.normal(scale=0.3, size=(count, 3, 3))


@pytest.mark.parametrize("count", [0, 1, 5, 4, 333])
def test_every_triangle_has_one_slot_and_every_box_holds_its_subtree(count):
    tris = _scene(count, count)
    tree = ray_tree.build(tris)
    assert tree.leaves & (tree.leaves - 1) == 0 and tree.leaves * ray_tree.LEAF >= count
    held = np.sort(tree.order[tree.order >= 0])
    assert np.array_equal(held, np.arange(count))
    filled = tree.order >= 0
    assert np.array_equal(tree.triangles[filled], tris[tree.order[filled]].astype(np.float32))
    assert not tree.triangles[~filled].any()
    for leaf in range(tree.leaves):
        corners = tree.triangles[leaf * ray_tree.LEAF:(leaf + 1) * ray_tree.LEAF][filled[
            leaf * ray_tree.LEAF:(leaf + 1) * ray_tree.LEAF]].reshape(-1, 3)
        node = tree.leaves + leaf
        if len(corners) == 0:
            assert np.all(tree.lo[node] >= ray_tree.FAR)
            continue
        assert np.all(tree.lo[node] < corners) and np.all(tree.hi[node] > corners)
    for node in range(1, tree.leaves):
        for child in (2 * node, 2 * node + 1):
            if tree.lo[child, 0] < ray_tree.FAR:
                assert np.all(tree.lo[node] <= tree.lo[child]) and np.all(tree.hi[node] >= tree.hi[child])


def test_next_node_goes_through_the_heap_in_preorder():
    leaves = 8
    order, node = [], 1
    while node:  # every box hit: the walk descends to each leaf in turn
        order.append(node)
        node = 2 * node if node < leaves else ray_tree.next_node(node)
    expected: list[int] = []

    def visit(n: int) -> None:
        expected.append(n)
        if n < leaves:
            visit(2 * n)
            visit(2 * n + 1)

    visit(1)
    assert order == expected


def test_the_walk_blocks_exactly_where_some_triangle_does():
    tris = _scene(400, 3)
    tree = ray_tree.build(tris)
    rng = np.random.default_rng(4)
    blocked_any = 0
    visits = []
    for _ in range(300):
        p = rng.uniform(-3.0, 3.0, 3)
        d = rng.uniform(-3.0, 3.0, 3) - p
        expected = bool(ray_tree.crossings(tris, p, d, EPS).any())
        got, count = ray_tree.walk(tree, p, d, EPS)
        assert got == expected
        blocked_any += expected
        visits.append(count)
    assert 30 < blocked_any < 270  # both verdicts well represented
    assert np.median(visits) < tree.nodes / 4  # the walk does prune


def test_crossings_leave_no_gap_between_neighbours():
    """Segments through the shared edge of two triangles, and through their shared corner,
    are blocked; a segment ending short of the plane, or starting within eps of it, is not."""
    square = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]], dtype=np.float64)
    for point in ([0.5, 0.5, 0.0], [0.0, 0.0, 0.0], [0.3, 0.3, 0.0]):
        p = np.array([0.2, 0.4, 1.0])
        d = 2.0 * (np.array(point) - p)
        assert ray_tree.crossings(square, p, d, EPS).any()
    p = np.array([0.5, 0.4, 1.0])
    assert not ray_tree.crossings(square, p, np.array([0.0, 0.0, -0.9]), EPS).any()  # short
    p = np.array([0.5, 0.4, 1e-6])
    assert not ray_tree.crossings(square, p, np.array([0.0, 0.0, -1.0]), EPS).any()  # its own surface
