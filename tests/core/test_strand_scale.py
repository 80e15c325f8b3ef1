"""Hair radii under an object's or emitter's scale, as Cycles draws them
(readers/hair.strand_radius_scale): baked by a uniform scale, the round tube of
the same cross-section as Cycles' elliptic one under a non-uniform scale."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.blockers import PIECES_PER_SPAN, Strands
from addon.readers.hair import strand_radius_scale, uniform_scale


def _matrix(linear) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = linear
    return out


def _vertical(n: int = 5) -> tuple[np.ndarray, np.ndarray]:
    return np.c_[np.zeros(n), np.zeros(n), np.linspace(0.0, 1.0, n)], np.array([0, n])


def _rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def test_a_uniform_scale_scales_the_radius_by_itself():
    local, offsets = _vertical()
    linear = 2.5 * _rotation(1)
    assert uniform_scale(_matrix(linear))
    np.testing.assert_allclose(strand_radius_scale(_matrix(linear), local, offsets), 2.5)


@pytest.mark.parametrize(("scale", "expected"), [((3.0, 3.0, 1.0), 3.0), ((1.0, 1.0, 0.001), 1.0),
                                                 ((2.0, 0.5, 4.0), 1.0)])
def test_a_scale_across_a_strand_is_what_thickens_it(scale, expected):
    # Along object z, the tube's section is the xy circle: its image is an ellipse of
    # semi-axes sx r and sy r, whose area is that of a circle of radius sqrt(sx sy) r.
    local, offsets = _vertical()
    assert not uniform_scale(_matrix(np.diag(scale)))
    np.testing.assert_allclose(strand_radius_scale(_matrix(np.diag(scale)), local, offsets), expected, rtol=1e-9)


def _section_radius(linear: np.ndarray, tangent: np.ndarray) -> float:
    """The radius of the circle whose area is that of the world tube's cross-section, by
    brute force: the object-space unit circle about `tangent`, mapped and projected on the
    plane across the world tangent, its polygon's area."""
    t = tangent / np.linalg.norm(tangent)
    u = np.cross(t, [1.0, 0.0, 0.0] if abs(t[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(t, u)
    angles = np.linspace(0.0, 2.0 * np.pi, 4001)[:-1]
    ring = (np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * v) @ linear.T
    axis = linear @ t
    axis /= np.linalg.norm(axis)
    a = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(axis, a)
    # Project along the world axis onto its cross plane.
    x, y = ring @ a, ring @ b
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    return float(np.sqrt(area / np.pi))


@pytest.mark.parametrize("seed", range(4))
def test_the_round_tube_has_the_elliptic_tubes_cross_section(seed):
    rng = np.random.default_rng(seed)
    linear = _rotation(seed + 10) @ np.diag(rng.uniform(0.3, 3.0, 3)) @ _rotation(seed + 20)
    tangent = rng.normal(size=3)
    local = np.array([np.zeros(3), tangent, 2.0 * tangent])
    got = strand_radius_scale(_matrix(linear), local, np.array([0, 3]))
    np.testing.assert_allclose(got, _section_radius(linear, tangent), rtol=1e-4)


def test_each_curve_takes_its_own_tangents():
    # Two curves, one along z and one along x, under (1, 1, 4): along z the section is
    # the unscaled xy circle; along x it is the yz circle scaled by 4 in z.
    local = np.array([[0, 0, 0], [0, 0, 1], [0, 0, 2], [0, 0, 0], [1, 0, 0]], dtype=float)
    got = strand_radius_scale(_matrix(np.diag([1.0, 1.0, 4.0])), local, np.array([0, 3, 5]))
    np.testing.assert_allclose(got, [1.0, 1.0, 1.0, 2.0, 2.0])


def test_a_shear_is_not_uniform():
    assert not uniform_scale(_matrix(np.array([[1.0, 0.3, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])))


def test_a_tapering_strand_is_sampled_as_finely_as_its_root_needs():
    # A closed tip has radius 0: the sag's share is of the thickest radius, so the strand
    # takes the pieces its root radius asks for, not the most there are.
    points = np.array([[0.0, 0.0, 0.0], [0.002, 0.0, 0.3], [0.0, 0.002, 0.6], [0.002, 0.002, 0.9]])
    even = Strands(points, np.full(4, 0.01), np.array([0, 4]), np.array([False]), np.array([False]))
    tapering = Strands(points, np.linspace(0.01, 0.0, 4), np.array([0, 4]), np.array([False]), np.array([False]))
    assert len(tapering.pieces(None)) == len(even.pieces(None)) < 3 * PIECES_PER_SPAN
