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


def test_the_receivers_own_primitive_is_left_out():
    """A sample on a sphere's surface is never shadowed by that sphere, its light on
    either side (Cycles' rays skip the primitive they leave), but by another one; a sample
    on a strand (a ribbon's point, inside the tube) not by any part of that strand
    (Cycles' primitive is the whole curve), but by another strand, and a sample off it by
    the strand itself."""
    spheres = Spheres([[0.0, 0.0, 0.0], [0.0, 0.0, -3.0]], [1.0, 0.5])
    start = np.array([[0.0, 0.0, 1.0]])
    assert not spheres.crossed(start, np.array([[0.0, 0.0, 5.0]]))[0]
    assert not Spheres([[0.0, 0.0, 0.0]], [1.0]).crossed(start, np.array([[0.0, 0.0, -5.0]]))[0]
    assert spheres.crossed(start, np.array([[0.0, 0.0, -5.0]]))[0]
    # A hook: up, then back down over its start; a sample in the first span's middle.
    points = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.3, 0.0, 1.2], [0.3, 0.0, 0.5]]
    hook = Strands(points, np.full(4, 0.05), [0, 4], np.array([True]))
    on_first = np.array([[0.02, 0.0, 0.5]])
    towards_last = np.array([[5.0, 0.0, 0.6]])  # the segment passes through the last span
    assert not hook.crossed(on_first, np.array([[0.02, 0.0, -2.0]]))[0]  # its own span lies along it
    assert not hook.crossed(on_first, towards_last)[0]
    assert hook.crossed(on_first + [0.1, 0.0, 0.0], towards_last)[0]  # off the strand
    two = Strands.concatenate([hook, Strands(np.array(points[2:]) + [0.5, 0.0, 0.0], np.full(2, 0.05), [0, 2],
                                             np.array([True]))])
    beyond = np.array([[5.0, 0.0, 0.51]])  # through the hook's last span and the second strand
    assert two.crossed(on_first, beyond)[0] and not hook.crossed(on_first, beyond)[0]


def test_capsules_match_brute_force():
    rng = np.random.default_rng(7)
    a, b = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    ra, rb = rng.uniform(0.05, 0.3, 3), rng.uniform(0.05, 0.3, 3)
    starts, ends = rng.normal(size=(120, 3)) * 1.5, rng.normal(size=(120, 3)) * 1.5
    from addon.core.blockers import _crossed

    ours = _crossed(starts, ends, a, b, ra, rb, 1e-4, own=False)
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
    cut = strands.pieces(8)
    a, b = cut.a, cut.b
    assert len(a) == 3 * 8
    assert np.allclose(a[::8], points[:3]) and np.allclose(b[7::8], points[1:])
    # A strand of two points is their segment; the radius follows the same basis.
    line = Strands([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [0.1, 0.3], [0, 2])
    cut = line.pieces(4)
    a, ra = cut.a, cut.ra
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
