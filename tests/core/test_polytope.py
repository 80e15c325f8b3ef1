"""The sample polytope (addon/core/polytope.py): frustum cut by the samples' box."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import plan as PL
from addon.core.polytope import box_planes, frustum_planes, polytope_of_planes, sample_polytope
from addon.core.scene import CameraSpec, look_at


def _euler_characteristic(polytope) -> int:
    """V - E + F, F counting the planes that carry a face (three or more vertices)."""
    offsets = polytope.planes[:, :3] @ polytope.vertices.T - polytope.planes[:, 3:4]
    scale = float(np.abs(polytope.vertices).max())
    faces = int(np.count_nonzero((np.abs(offsets) <= 1e-8 * scale).sum(axis=1) >= 3))
    return len(polytope.vertices) - len(polytope.edges) + faces


def test_a_box_has_its_eight_corners_and_twelve_edges():
    lo, hi = np.array([-1.0, 2.0, 0.5]), np.array([3.0, 2.5, 7.0])
    box = polytope_of_planes(box_planes(lo, hi))
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    assert len(box.vertices) == 8 and len(box.edges) == 12
    assert np.allclose(np.sort(box.vertices, axis=0), np.sort(corners, axis=0))
    # Every edge joins corners that differ in exactly one coordinate.
    a, b = box.vertices[box.edges[:, 0]], box.vertices[box.edges[:, 1]]
    assert np.all(np.count_nonzero(~np.isclose(a, b), axis=1) == 1)
    assert box.contains((lo + hi) / 2) and not box.contains(hi + [0.0, 0.1, 0.0])


def test_a_box_around_the_frustum_leaves_the_frustum():
    camera = CameraSpec(look_at((1.0, -4.0, 2.0), (0.0, 0.0, 0.5)), 50.0, (64, 48))
    corners = PL.frustum_corners(camera, 1.0, 9.0)
    planes = np.concatenate([frustum_planes(corners), box_planes(corners.min(axis=0) - 1, corners.max(axis=0) + 1)])
    polytope = polytope_of_planes(planes)
    assert len(polytope.vertices) == 8 and len(polytope.edges) == 12
    got = {tuple(np.round(v, 9)) for v in polytope.vertices}
    assert got == {tuple(np.round(c, 9)) for c in corners}


@pytest.mark.parametrize("seed", range(12))
def test_sample_polytope_holds_every_sample_and_is_a_closed_convex_solid(seed):
    rng = np.random.default_rng(seed)
    camera = CameraSpec(look_at(rng.uniform(-5, 5, 3), rng.uniform(-1, 1, 3) + [0.0, 0.0, 0.01]), 60.0, (64, 48))
    corners = PL.frustum_corners(camera, 0.5, 20.0)
    # Samples in a random slab of the frustum, so the box really cuts it.
    t = rng.uniform(0.0, 1.0, (500, 1)) * rng.uniform(0.2, 1.0)
    near, far = corners[:4], corners[4:]
    w = rng.dirichlet(np.ones(4), 500)
    samples = (w @ near) * (1 - t) + (w @ far) * t
    polytope = sample_polytope(corners, (samples.min(axis=0), samples.max(axis=0)))
    assert all(polytope.contains(p) for p in samples)
    assert all(PL.point_in_frustum(v, corners) for v in polytope.vertices)
    lo, hi = samples.min(axis=0), samples.max(axis=0)
    reach = 1e-5 * (np.abs(corners).max() + np.abs(samples).max())
    assert np.all(polytope.vertices >= lo - reach) and np.all(polytope.vertices <= hi + reach)
    assert _euler_characteristic(polytope) == 2
    # Edge points lie on the boundary: on at least two planes.
    pts = polytope.edge_points(5)
    off = np.abs(polytope.planes[:, :3] @ pts.T - polytope.planes[:, 3:4])
    assert np.all((off <= 1e-7 * np.abs(pts).max()).sum(axis=0) >= 2)


def test_disjoint_planes_give_no_polytope():
    planes = np.concatenate([box_planes(np.zeros(3), np.ones(3)), box_planes(np.full(3, 2.0), np.full(3, 3.0))])
    assert polytope_of_planes(planes) is None
    assert sample_polytope(PL.frustum_corners(CameraSpec(np.eye(4), 60.0, (8, 8)), 1.0, 2.0), None) is None


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_samples_at_one_point_give_a_tiny_polytope_that_holds_it(scale):
    """The degenerate box (every sample on one point) still makes a closed solid around it."""
    camera = CameraSpec(look_at((0.0, -6.0 * scale, 2.0 * scale), (0.0, 0.0, 0.0)), 60.0, (8, 6))
    point = np.array([0.3, 0.2, 0.0]) * scale
    corners = PL.frustum_corners(camera, 5.0 * scale, 8.0 * scale)
    polytope = sample_polytope(corners, (point, point))
    assert polytope.contains(point)
    assert len(polytope.vertices) == 8 and len(polytope.edges) == 12
    assert np.abs(polytope.vertices - point).max() < 1e-4 * scale
