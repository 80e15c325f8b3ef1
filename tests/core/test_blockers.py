"""Spheres and strands as Cycles intersects them (core/blockers.py): the numpy oracle of
the point-cloud and hair blockers, against brute force and closed forms."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.blockers import Spheres, Strands, catmull_rom_basis


def _brute(starts, ends, a, b, ra, rb, eps, n=1001):
    """Dense sampling of both segments: the smallest gap less the radius there."""
    s = np.linspace(eps, 1.0, n)[:, None]
    u = np.linspace(0.0, 1.0, 301)[:, None]
    out = []
    for p, q in zip(starts, ends):
        seg = p + s * (q - p)
        hit = False
        for k in range(len(a)):
            axis = a[k] + u * (b[k] - a[k])
            radius = ra[k] + u[:, 0] * (rb[k] - ra[k])
            gap = np.linalg.norm(seg[:, None, :] - axis[None], axis=2) - radius[None]
            hit |= bool(gap.min() <= 0.0)
        out.append(hit)
    return np.array(out)


def test_a_sphere_blocks_the_segments_that_pass_within_its_radius():
    spheres = Spheres([[0.0, 0.0, 1.0]], [0.25])
    ends = np.array([[x, 0.0, 2.0] for x in (0.0, 0.2, 0.3, 0.49, 0.51, 1.0)])
    starts = np.array([[x, 0.0, 0.0] for x in (0.0, 0.2, 0.3, 0.49, 0.51, 1.0)])
    # The segment x = const passes the centre at distance x; a tilted one: its closest point.
    assert spheres.crossed(starts, ends).tolist() == [True, True, False, False, False, False]
    tilted = spheres.crossed(np.array([[0.49, 0.0, 0.0]]), np.array([[-0.49, 0.0, 2.0]]))
    assert tilted.tolist() == [True]


def test_the_receivers_own_sphere_is_left_out_near_the_start():
    """A sample on the sphere's surface, its light straight away from the sphere: not
    shadowed; behind it (the light on the far side): shadowed."""
    spheres = Spheres([[0.0, 0.0, 0.0]], [1.0])
    start = np.array([[0.0, 0.0, 1.0]])
    assert not spheres.crossed(start, np.array([[0.0, 0.0, 5.0]]))[0]
    assert spheres.crossed(start, np.array([[0.0, 0.0, -5.0]]))[0]


def test_capsules_match_brute_force():
    rng = np.random.default_rng(7)
    a, b = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    ra, rb = rng.uniform(0.05, 0.3, 3), rng.uniform(0.05, 0.3, 3)
    starts, ends = rng.normal(size=(120, 3)) * 1.5, rng.normal(size=(120, 3)) * 1.5
    from addon.core.blockers import _crossed

    ours = _crossed(starts, ends, a, b, ra, rb, 1e-4)
    theirs = _brute(starts, ends, a, b, ra, rb, 1e-4)
    # Dense sampling can only miss a grazing hit, never invent one.
    assert not np.any(theirs & ~ours)
    assert np.count_nonzero(ours != theirs) <= 1, np.count_nonzero(ours != theirs)
    assert 10 < np.count_nonzero(ours) < 110


def test_catmull_rom_passes_through_its_control_points_with_repeated_ends():
    weights = catmull_rom_basis(np.array([0.0, 1.0]))
    assert np.allclose(weights, [[0, 1, 0, 0], [0, 0, 1, 0]])
    assert np.allclose(catmull_rom_basis(np.linspace(0, 1, 9)).sum(axis=1), 1.0)
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 1.0, 0.0], [3.0, 1.0, 0.0]])
    strands = Strands(points, np.full(4, 0.1), [0, 4])
    a, b, ra, rb = strands.capsules(8)
    assert len(a) == 3 * 8
    assert np.allclose(a[::8], points[:3]) and np.allclose(b[7::8], points[1:])
    # A strand of two points is their segment; the radius follows the same basis.
    line = Strands([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [0.1, 0.3], [0, 2])
    a, b, ra, rb = line.capsules(4)
    weights = catmull_rom_basis(np.linspace(0.0, 1.0, 5))[:-1]
    assert np.allclose(a[:, :2], 0.0) and np.allclose(ra, weights @ np.array([0.1, 0.1, 0.3, 0.3]))
    crossing = line.crossed(np.array([[-1.0, 0.0, 0.9], [-1.0, 0.22, 0.1]]), np.array([[1.0, 0.0, 0.9],
                                                                                      [1.0, 0.22, 0.1]]))
    assert crossing.tolist() == [True, False]


def test_strands_concatenate_and_refuse_bad_offsets():
    one = Strands(np.zeros((3, 3)), np.ones(3), [0, 3])
    two = Strands(np.ones((4, 3)), np.ones(4), [0, 2, 4])
    both = Strands.concatenate([one, Strands.empty(), two])
    assert both.offsets.tolist() == [0, 3, 5, 7] and len(both) == 3
    with pytest.raises(ValueError):
        Strands(np.zeros((3, 3)), np.ones(3), [0, 2])
    with pytest.raises(ValueError):
        Spheres(np.zeros((2, 3)), np.ones(3))
