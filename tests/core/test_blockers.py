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
    on a strand not by any part of that strand (Cycles' primitive is the whole curve),
    but by another strand, and a sample off it by the strand itself."""
    spheres = Spheres([[0.0, 0.0, 0.0], [0.0, 0.0, -3.0]], [1.0, 0.5])
    start, up = np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]])
    assert not spheres.crossed(start, np.array([[0.0, 0.0, 5.0]]), normals=up)[0]
    assert not Spheres([[0.0, 0.0, 0.0]], [1.0]).crossed(start, np.array([[0.0, 0.0, -5.0]]), normals=up)[0]
    assert spheres.crossed(start, np.array([[0.0, 0.0, -5.0]]), normals=up)[0]
    # Without normals no start lies on a sphere: its own blocks the far side.
    assert Spheres([[0.0, 0.0, 0.0]], [1.0]).crossed(start, np.array([[0.0, 0.0, -5.0]]))[0]
    # A hook: up, then back down over its start; a sample on the first span's side.
    points = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.3, 0.0, 1.2], [0.3, 0.0, 0.5]]
    hook = Strands(points, np.full(4, 0.05), [0, 4], np.array([True]))
    on_first, out = np.array([[0.05, 0.0, 0.5]]), np.array([[1.0, 0.0, 0.0]])
    towards_last = np.array([[5.0, 0.0, 0.6]])  # the segment passes through the last span
    assert not hook.crossed(on_first, np.array([[0.05, 0.0, -2.0]]), normals=out)[0]  # along its own span
    assert not hook.crossed(on_first, towards_last, normals=out)[0]
    assert hook.crossed(on_first + [0.1, 0.0, 0.0], towards_last, normals=out)[0]  # off the strand
    two = Strands.concatenate([hook, Strands(np.array(points[2:]) + [0.5, 0.0, 0.0], np.full(2, 0.05), [0, 2],
                                             np.array([True]))])
    beyond = np.array([[5.0, 0.0, 0.51]])  # through the hook's last span and the second strand
    assert two.crossed(on_first, beyond, normals=out)[0] and not hook.crossed(on_first, beyond, normals=out)[0]


def test_a_sample_inside_another_strand_is_shadowed_by_it():
    """Two round strands that overlap: a sample on the first one's surface lies inside the
    second, whose tube Cycles' ray leaves on its way to the light; so the second shadows
    it, and the first does not. Told apart by the sample's normal: on the second strand's
    surface with its normal facing out, the sample would lie on it instead."""
    first = Strands([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [0.1, 0.1], [0, 2], np.array([True]))
    second = Strands([[0.05, 0.0, 0.0], [0.05, 0.0, 1.0]], [0.1, 0.1], [0, 2], np.array([True]))
    both = Strands.concatenate([first, second])
    sample, normal = np.array([[0.1, 0.0, 0.5]]), np.array([[1.0, 0.0, 0.0]])  # on the first, inside the second
    light = np.array([[0.1, 0.0, 0.5]]) + [-5.0, 0.0, 0.0]  # through both axes
    assert both.crossed(sample, light, normals=normal)[0]
    assert not first.crossed(sample, light, normals=normal)[0]
    assert second.crossed(sample, light, normals=normal)[0]
    # On the second's surface (0.05 + 0.1 from its axis, facing out) neither shadows it
    # towards +x: it lies on the second, and the first lies behind it.
    outer = np.array([[0.15, 0.0, 0.5]])
    assert not both.crossed(outer, outer + [5.0, 0.0, 0.0], normals=normal)[0]


def test_a_ribbon_faces_the_ray():
    """A ribbon (Strands.flat) is met where the ray passes its axis, more than twice its
    radius from the start: a segment starting in its tube past the axis does not meet it,
    one before the axis does; a sample in the
    ribbon's plane facing the camera (its true normal) lies on it, one across the plane
    (on a round tube's surface) does not."""
    flat = Strands([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [0.1, 0.1], [0, 2], np.array([False]), np.array([True]))
    round_ = Strands(flat.points, flat.radii, flat.offsets, flat.linear)
    sample, light = np.array([[0.05, 0.0, 0.5]]), np.array([[5.0, 0.0, 0.5]])  # inside, past the axis
    camera = np.array([[0.0, 1.0, 0.0]])  # the camera ray's: the ribbon's plane y = 0
    assert not flat.crossed(sample + [0.0, 0.05, 0.0], light)[0]  # past the axis: no hit
    assert flat.crossed(sample - [0.5, 0.0, 0.0], light)[0]  # before it: a hit
    assert not flat.crossed(sample - [0.2, 0.0, 0.0], light)[0]  # nearer than twice its radius: ignored
    assert round_.crossed(sample + [0.0, 0.05, 0.0], light)[0]  # a round tube's far side
    in_plane = np.array([[0.05, 0.0, 0.5], [0.05, 0.05, 0.5]])  # in the plane y = 0, its normal +y; off it
    on = flat.pieces(4).on_curve(in_plane, np.repeat(camera, 2, axis=0), np.array([1, 1]))
    assert on.tolist() == [True, False]
    assert flat.pieces(4).flat.all() and not round_.pieces(4).flat.any()


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


def test_a_curve_is_open_at_its_ends():
    """Cycles ends a Catmull-Rom curve's tube in the plane across its axis, with no half
    sphere: a segment that passes the end point within the radius but beyond that plane
    misses it, one through the side near the end meets it. A sample beyond the end, within
    the radius of the end point, does not lie on the curve. A point's sphere is closed,
    and so is a poly curve's end (Cycles 5.x draws it as round linear segments, ribbons
    or not)."""
    strand = Strands([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [0.1, 0.1], [0, 2])
    assert np.allclose(strand.pieces(1).end_planes()[0], [[0, 0, 1, 0], [0, 0, -1, 1]])
    assert not Spheres([[0.0, 0.0, 0.0]], [0.1]).pieces().end_planes().any()
    beyond = strand.crossed(np.array([[-1.0, 0.0, -0.05]]), np.array([[1.0, 0.0, -0.05]]))
    side = strand.crossed(np.array([[-1.0, 0.0, 0.05]]), np.array([[1.0, 0.0, 0.05]]))
    assert beyond.tolist() == [False] and side.tolist() == [True]
    ball = Spheres([[0.0, 0.0, 0.0]], [0.1]).crossed(np.array([[-1.0, 0.0, -0.05]]), np.array([[1.0, 0.0, -0.05]]))
    assert ball.tolist() == [True]
    poly = Strands(strand.points, strand.radii, strand.offsets, np.array([True]), np.array([True]))
    assert not poly.pieces(1).flat.any() and not poly.pieces(1).end_planes().any()
    assert poly.crossed(np.array([[-1.0, 0.0, -0.05]]), np.array([[1.0, 0.0, -0.05]])).tolist() == [True]
    pieces = strand.pieces(1)
    on = pieces.on_curve(np.array([[0.1, 0.0, 0.5], [0.1, 0.0, -0.01]]), np.array([[1.0, 0.0, 0.0]] * 2),
                         np.array([0, 0]))
    assert on.tolist() == [True, False]
