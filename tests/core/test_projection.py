"""Paraboloid and cube-face projections (addon/core/projection.py).

Expectations are derived from the formulas in docs/design.md section 4: the paraboloid
is the stereographic projection r = tan(theta / 2) (theta = angle from the axis),
a cube face is the 90 degree perspective (x, y) = (p_x, p_y) / p_z.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from addon.core import projection as P

FAST = settings(max_examples=150, deadline=None)

unit_float = st.floats(-1.0, 1.0, allow_nan=False)
coord = st.floats(-1e3, 1e3, allow_nan=False)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between (unit or not) vectors, accurate also for tiny angles."""
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    return np.arctan2(cross, dot)


def _front_direction(x: float, y: float, z: float) -> np.ndarray:
    """A direction in the front half-space (v_z >= 0)."""
    return np.array([x, y, abs(z)])


# ---------------------------------------------------------------- known points


def test_paraboloid_axis_maps_to_centre_texel():
    """The paraboloid axis (0, 0, 1) lands on the map centre, texel (res/2, res/2)."""
    xy = P.paraboloid_project(np.array([0.0, 0.0, 1.0]))
    assert np.allclose(xy, [0.0, 0.0], atol=0.0)
    assert tuple(P.texel_index(xy, 8)) == (4, 4)


@pytest.mark.parametrize("phi_deg", [0.0, 30.0, 90.0, 135.0, 200.0, 315.0])
def test_paraboloid_horizon_maps_to_unit_circle(phi_deg):
    """A direction at 90 degrees from the axis (v_z = 0) lands on the rim |xy| = 1."""
    phi = math.radians(phi_deg)
    v = np.array([math.cos(phi), math.sin(phi), 0.0]) * 3.7
    xy = P.paraboloid_project(v)
    assert np.linalg.norm(xy) == pytest.approx(1.0, abs=1e-12)
    assert np.allclose(xy, [math.cos(phi), math.sin(phi)], atol=1e-12)


@pytest.mark.parametrize("theta_deg", [10.0, 45.0, 60.0, 89.0])
def test_paraboloid_radius_is_tan_half_angle(theta_deg):
    """r = tan(theta / 2): e.g. (1, 0, 1)/sqrt2 at 45 degrees -> x = tan(22.5 degrees)."""
    t = math.radians(theta_deg)
    xy = P.paraboloid_project(np.array([math.sin(t), 0.0, math.cos(t)]) * 2.5)
    assert xy[0] == pytest.approx(math.tan(t / 2.0), abs=1e-12)
    assert xy[1] == pytest.approx(0.0, abs=1e-12)


def test_paraboloid_45_degrees_example():
    """The brief's worked example: (1, 0, 1)/sqrt2 -> (tan 22.5 deg, 0) = (sqrt2 - 1, 0)."""
    xy = P.paraboloid_project(np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0))
    assert np.allclose(xy, [math.sqrt(2.0) - 1.0, 0.0], atol=1e-12)


def test_cube_known_points():
    """A cube face maps (1, 1, 1) to its corner (1, 1) and the axis to its centre."""
    assert np.allclose(P.cube_project(np.array([1.0, 1.0, 1.0])), [1.0, 1.0], atol=0.0)
    assert np.allclose(P.cube_project(np.array([0.0, 0.0, 5.0])), [0.0, 0.0], atol=0.0)
    assert np.allclose(P.cube_project(np.array([2.0, -3.0, 4.0])), [0.5, -0.75], atol=1e-15)


def test_project_dispatches_on_kind():
    """project/unproject pick the paraboloid or the cube formula by kind."""
    p = np.array([0.3, -0.2, 0.9])
    assert np.allclose(P.project(P.PARABOLOID, p), P.paraboloid_project(p))
    assert np.allclose(P.project(P.CUBE, p), P.cube_project(p))
    xy = np.array([0.3, -0.4])
    assert np.allclose(P.unproject(P.PARABOLOID, xy), P.paraboloid_unproject(xy))
    assert np.allclose(P.unproject(P.CUBE, xy), P.cube_unproject(xy))


@pytest.mark.parametrize(
    "xy, res, expected",
    [
        ((0.0, 0.0), 8, (4, 4)),
        ((-1.0, -1.0), 8, (0, 0)),
        ((1.0, 1.0), 8, (7, 7)),  # uv = 1 is the outer edge: clamps to the last texel
        ((5.0, -7.0), 8, (7, 0)),  # far outside: clamped, never out of range
        ((-0.76, 0.26), 8, (0, 5)),  # uv = (0.12, 0.63) -> (0.96, 5.04)
        ((1.0, 1.0), 1, (0, 0)),
    ],
)
def test_texel_index(xy, res, expected):
    """texel = floor((0.5 + 0.5 xy) * res), clamped to [0, res - 1]."""
    assert tuple(P.texel_index(np.array(xy), res)) == expected


def test_xy_to_texel_centres():
    """Texel centres sit at i + 0.5: xy of texel i's centre maps back to i + 0.5."""
    res = 16
    i = np.arange(res)
    xy = (i + 0.5) / res * 2.0 - 1.0
    assert np.allclose(P.xy_to_texel(xy, res), i + 0.5, atol=1e-12)


# ---------------------------------------------------------------- round trips


@FAST
@given(unit_float, unit_float, unit_float, st.floats(1e-3, 1e3))
def test_paraboloid_unproject_inverts_project(x, y, z, length):
    """unproject(project(v)) == v / |v| on the front hemisphere (v_z >= 0)."""
    v = _front_direction(x, y, z)
    if np.linalg.norm(v) < 1e-6:
        return
    u = v / np.linalg.norm(v)
    back = P.paraboloid_unproject(P.paraboloid_project(u * length))
    assert np.allclose(back, u, atol=1e-9)


@FAST
@given(unit_float, unit_float)
def test_paraboloid_project_inverts_unproject(x, y):
    """project(unproject(xy)) == xy inside the unit disk, and unproject gives unit v_z >= 0."""
    xy = np.array([x, y])
    if np.linalg.norm(xy) > 1.0:
        xy = xy / np.linalg.norm(xy)
    v = P.paraboloid_unproject(xy)
    assert np.linalg.norm(v) == pytest.approx(1.0, abs=1e-12)
    assert v[2] >= -1e-15
    assert np.allclose(P.paraboloid_project(v), xy, atol=1e-9)


@FAST
@given(unit_float, unit_float, st.floats(1e-3, 1.0), st.floats(1e-3, 1e3))
def test_cube_round_trips(x, y, z, length):
    """Cube: unproject(project(p)) == p/|p| for p_z > 0, project(unproject(xy)) == xy."""
    p = np.array([x, y, z])
    u = p / np.linalg.norm(p)
    assert np.allclose(P.cube_unproject(P.cube_project(u * length)), u, atol=1e-9)
    xy = np.array([x, y])
    d = P.cube_unproject(xy)
    assert np.linalg.norm(d) == pytest.approx(1.0, abs=1e-12)
    assert np.allclose(P.cube_project(d), xy, atol=1e-9)


def test_round_trip_vectorised_shapes():
    """Batched (..., 3) and (..., 2) inputs keep their leading shape."""
    rng = np.random.default_rng(1)
    v = rng.normal(size=(4, 5, 3))
    v[..., 2] = np.abs(v[..., 2])
    xy = P.paraboloid_project(v)
    assert xy.shape == (4, 5, 2)
    back = P.paraboloid_unproject(xy)
    assert back.shape == (4, 5, 3)
    assert np.allclose(back, v / np.linalg.norm(v, axis=-1, keepdims=True), atol=1e-9)


# ---------------------------------------------------------------- extremes


@FAST
@given(st.floats(0.0, 2.0 * math.pi))
def test_seam_directions_are_finite_and_on_rim(phi):
    """v_z exactly 0 (the seam) gives a finite point on the rim for both kinds' inputs."""
    v = np.array([math.cos(phi), math.sin(phi), 0.0])
    xy = P.paraboloid_project(v)
    assert np.all(np.isfinite(xy))
    assert np.linalg.norm(xy) == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.isfinite(P.cube_project(v)))  # outside the face, but never NaN


@pytest.mark.parametrize("point", [(5.0, 0.0, 0.0), (1e3, -2.0, 0.0), (3.0, 4.0, -1.0), (-7.0, 0.5, -1e-300)])
def test_cube_project_finite_on_and_behind_face_plane(point):
    """Points on (p_z = 0) or behind a cube face's plane are outside the face, but the
    result must stay finite (never inf or NaN) so a stray vertex cannot poison a map."""
    xy = P.cube_project(np.array(point))
    assert np.all(np.isfinite(xy)), xy


@pytest.mark.parametrize("length", [1e-300, 1e-200, 1e-160, 1e-100, 1e-30, 1e-6])
def test_tiny_points_project_by_direction_only(length):
    """Points of tiny length: finite, and (as documented) only the direction matters.

    The paraboloid result must equal the one for the unit direction and stay in
    the unit disk; the cube result is a ratio and must also be exact.
    """
    dirs = np.array([[1.0, 0.0, 0.0], [0.6, 0.0, 0.8], [1.0, 1.0, 1.0], [-2.0, 1.0, 3.0], [0.0, 0.0, 1.0]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    xy = P.paraboloid_project(dirs * length)
    assert np.all(np.isfinite(xy))
    assert np.all(np.linalg.norm(xy, axis=1) <= 1.0 + 1e-12)
    assert np.allclose(xy, P.paraboloid_project(dirs), atol=1e-9)
    front = dirs[dirs[:, 2] > 0]
    cube = P.cube_project(front * length)
    assert np.all(np.isfinite(cube))
    assert np.allclose(cube, P.cube_project(front), atol=1e-9)


@FAST
@given(unit_float, unit_float, st.floats(0.01, 1.0), st.floats(6.0, 30.0))
def test_huge_points_project_by_direction_only(x, y, z, exponent):
    """Points at 1e6..1e30 from the light project exactly like their unit direction."""
    v = np.array([x, y, z])
    u = v / np.linalg.norm(v)
    big = u * 10.0**exponent
    for kind in (P.PARABOLOID, P.CUBE):
        got = P.project(kind, big)
        assert np.all(np.isfinite(got))
        assert np.allclose(got, P.project(kind, u), atol=1e-9)


def test_origin_maps_to_centre_without_nan():
    """The light position itself (L = 0) maps to the centre for both kinds, no NaN."""
    for kind in (P.PARABOLOID, P.CUBE):
        xy = P.project(kind, np.zeros(3))
        assert np.all(np.isfinite(xy))
        assert np.allclose(xy, [0.0, 0.0], atol=0.0)


# ---------------------------------------------------------------- texel angle


def _measured_texel_angles(kind: int, xy: np.ndarray, res: int, h: float | None = None) -> np.ndarray:
    """Angle spanned by one texel at xy in +-x and +-y, shape (n, 4).

    With h=None the angle between unproject(xy) and unproject(xy + one texel step)
    is measured directly; with a small h it is the angle for a step h scaled up
    to one texel (the local angular size per texel at xy).
    """
    step = 2.0 / res
    move = step if h is None else h
    base = P.unproject(kind, xy)
    out = []
    for delta in ((move, 0.0), (-move, 0.0), (0.0, move), (0.0, -move)):
        out.append(_angle(base, P.unproject(kind, xy + np.array(delta))) * (step / move))
    return np.stack(out, axis=-1)


def _map_points(kind: int, n: int = 400) -> np.ndarray:
    rng = np.random.default_rng(7)
    xy = rng.uniform(-1.0, 1.0, size=(n, 2))
    if kind == P.PARABOLOID:  # the paraboloid map is the unit disk
        xy = xy[np.linalg.norm(xy, axis=1) <= 0.995]
    extra = np.array([[0.0, 0.0], [0.5, 0.0], [-0.5, 0.0], [0.0, -0.9], [0.7, 0.7], [-0.3, 0.6]])
    return np.concatenate([xy, extra])


@pytest.mark.parametrize("kind", [P.PARABOLOID, P.CUBE], ids=["paraboloid", "cube"])
@pytest.mark.parametrize("res", [64, 512])
def test_texel_angle_bounds_local_angle_per_texel_within_factor_two(kind, res):
    """texel_angle >= the local angle per texel at xy in any axis direction (a tiny
    finite difference scaled to one texel), and at most twice it."""
    xy = _map_points(kind)
    bound = P.texel_angle(kind, xy, res)
    measured = _measured_texel_angles(kind, xy, res, h=1e-7)
    worst = measured.max(axis=1)
    k = int(np.argmax(worst / bound))
    assert np.all(bound >= worst * (1.0 - 1e-6)), f"xy={xy[k]} bound={bound[k]:.9g} measured={worst[k]:.9g}"
    assert np.all(bound <= 2.0 * measured.min(axis=1))


@pytest.mark.parametrize("kind", [P.PARABOLOID, P.CUBE], ids=["paraboloid", "cube"])
@pytest.mark.parametrize("res", [64, 512])
def test_texel_angle_against_one_texel_step(kind, res):
    """Against the angle of a whole texel step (xy -> xy +- one texel in x or y):
    the bound holds up to the second-order term, i.e. within a relative 2/res
    (the density changes by at most a relative step across one texel), and is
    never more than twice the measured angle."""
    xy = _map_points(kind)
    bound = P.texel_angle(kind, xy, res)
    measured = _measured_texel_angles(kind, xy, res)
    worst = measured.max(axis=1)
    k = int(np.argmax(worst / bound))
    assert np.all(bound * (1.0 + 2.0 / res) >= worst), f"xy={xy[k]} bound={bound[k]:.9g} measured={worst[k]:.9g}"
    assert np.all(bound <= 2.0 * measured.min(axis=1))


def test_texel_angle_tracks_true_angle_closely():
    """The estimate is tight: the paraboloid is conformal, so texel_angle equals the
    local angle per texel; the cube over-estimates by at most sqrt(2)."""
    res = 1024
    for kind, low, high in ((P.PARABOLOID, 1.0 - 1e-5, 1.0 + 1e-5), (P.CUBE, 1.0 - 1e-5, math.sqrt(2.0) + 1e-5)):
        xy = _map_points(kind)
        ratio = P.texel_angle(kind, xy, res)[:, None] / _measured_texel_angles(kind, xy, res, h=1e-7)
        assert np.all(ratio >= low) and np.all(ratio <= high)


def test_paraboloid_sampling_ratio_centre_to_rim_is_two():
    """Angle per texel at the centre is twice that at the rim (4x in area, Brabec)."""
    centre = P.texel_angle(P.PARABOLOID, np.array([0.0, 0.0]), 256)
    rim = P.texel_angle(P.PARABOLOID, np.array([1.0, 0.0]), 256)
    assert centre / rim == pytest.approx(2.0, rel=1e-12)
    # The same ratio from the geometry: d(theta)/dr = 2 / (1 + r^2) at r = 0 and r = 1.
    h = 1e-6
    d_centre = _angle(P.paraboloid_unproject(np.array([0.0, 0.0])), P.paraboloid_unproject(np.array([h, 0.0])))
    d_rim = _angle(P.paraboloid_unproject(np.array([1.0 - h, 0.0])), P.paraboloid_unproject(np.array([1.0, 0.0])))
    assert d_centre / d_rim == pytest.approx(2.0, rel=1e-5)


def test_texel_angle_scales_inversely_with_resolution():
    """Doubling the resolution halves the angle per texel."""
    xy = np.array([[0.2, -0.4], [0.0, 0.0]])
    for kind in (P.PARABOLOID, P.CUBE):
        assert np.allclose(P.texel_angle(kind, xy, 256), 2.0 * P.texel_angle(kind, xy, 512), rtol=1e-12)


# ---------------------------------------------------------------- depth range


def _box_triangles(lo, hi) -> np.ndarray:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    # Any triangles whose corners cover all 8 box corners give the same bounds.
    return np.stack([c[[0, 1, 2]], c[[3, 4, 5]], c[[6, 7, 0]]])


def test_depth_range_light_inside_box():
    """Light inside the bounds: near is 0, far reaches past the farthest corner."""
    tris = _box_triangles((-1, -2, -3), (4, 5, 6))
    light = np.array([0.5, 0.5, 0.5])
    near, far = P.depth_range(tris, light)
    farthest = np.linalg.norm(np.array([4, 5, 6]) - light)
    assert near == 0.0
    assert far >= farthest
    assert far <= farthest * 1.02


@pytest.mark.parametrize(
    "light, nearest",
    [
        ((10.0, 0.0, 0.0), (4.0, 0.0, 0.0)),  # facing a box face
        ((10.0, 12.0, 0.0), (4.0, 5.0, 0.0)),  # facing an edge
        ((-5.0, -6.0, -7.0), (-1.0, -2.0, -3.0)),  # facing a corner
    ],
)
def test_depth_range_light_outside_box(light, nearest):
    """Light outside: near is the distance to the box (minus at most the 1 % margin),
    far covers the farthest corner."""
    tris = _box_triangles((-1, -2, -3), (4, 5, 6))
    light = np.array(light)
    near, far = P.depth_range(tris, light)
    dist = np.linalg.norm(np.array(nearest) - light)
    corners = np.array([[x, y, z] for x in (-1, 4) for y in (-2, 5) for z in (-3, 6)], dtype=float)
    farthest = np.linalg.norm(corners - light, axis=1).max()
    assert dist * 0.99 - 1e-12 <= near <= dist
    assert farthest <= far <= farthest * 1.02
    assert near < far


def test_depth_range_ignores_nan_and_inf_vertices():
    """Non-finite vertices do not change the range (nor make it NaN)."""
    tris = _box_triangles((0, 0, 0), (1, 1, 1))
    light = np.array([3.0, 0.5, 0.5])
    clean = P.depth_range(tris, light)
    dirty = np.concatenate([tris, [[[np.nan, 0, 0], [np.inf, 1, 1], [50.0, -np.inf, 9]]]])
    got = P.depth_range(dirty, light)
    assert np.all(np.isfinite(got))
    assert got == pytest.approx(clean, rel=0, abs=0)


@pytest.mark.parametrize("light", [(0.0, 0.0, 0.0), (1.0, 2.0, 3.0), (1e-3, 0.0, 0.0)])
def test_depth_range_point_geometry_is_non_empty(light):
    """All geometry at one point (even at the light) still gives far > near >= 0."""
    tris = np.full((2, 3, 3), 1.0)
    tris[:] = [1.0, 2.0, 3.0]
    near, far = P.depth_range(tris, np.array(light))
    assert np.isfinite(near) and np.isfinite(far)
    assert 0.0 <= near < far


def test_normalized_depth_maps_range_to_unit_interval():
    """(L - near) / (far - near): near -> 0, far -> 1, linear in between."""
    assert np.allclose(P.normalized_depth(np.array([2.0, 5.0, 3.5]), 2.0, 5.0), [0.0, 1.0, 0.5])


# Sphere unfolding (Stockli Contreras et al., eq. 1) ---------------------------------

@pytest.mark.parametrize("theta_deg", [0.0, 1e-9, 30.0, 90.0, 135.0, 179.0])
@pytest.mark.parametrize("phi_deg", [0.0, 77.0, 200.0])
def test_unfold_radius_is_angle_from_pole_over_pi(theta_deg, phi_deg):
    """Eq. 1 with y = -z: the map radius is the angle from the pole over pi, along the azimuth."""
    theta, phi = math.radians(theta_deg), math.radians(phi_deg)
    d = np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])
    xy = P.unfold_project(d * 3.7)
    assert np.linalg.norm(xy) == pytest.approx(theta / math.pi, abs=1e-12)
    if theta_deg > 1e-6:
        assert math.atan2(xy[1], xy[0]) % (2 * math.pi) == pytest.approx(phi % (2 * math.pi), abs=1e-9)
    # eq. 1 verbatim, with its y axis being our -z and its (x, z) our (x, y)
    y = -d[2]
    expected = (math.asin(y) + math.pi * 0.5) / (math.pi * math.hypot(d[0], d[1]) + 1e-300) * d[:2]
    if theta_deg > 1e-6:
        assert np.allclose(xy, expected, atol=1e-9)


def test_unfold_poles_are_finite():
    """The pole maps to the centre, the opposite pole to the rim, tiny and huge points by direction."""
    got = P.unfold_project(np.array([[0.0, 0.0, 2.0], [0.0, 0.0, -5.0], [0.0, 0.0, 0.0], [1e-300, 0.0, 1e-300],
                                     [1e300, 1e300, -1e300]]))
    assert np.all(np.isfinite(got))
    assert np.allclose(got[0], 0.0) and np.allclose(got[1], [1.0, 0.0]) and np.allclose(got[2], 0.0)
    assert np.linalg.norm(got[3]) == pytest.approx(0.25)
    assert np.all(np.isfinite(P.unfold_unproject(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, -1.0]]))))


@given(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(1e-6, 1e6))
@settings(max_examples=300, deadline=None)
def test_unfold_round_trip(x, y, z, length):
    """unproject(project(p)) is p's direction, everywhere but at the opposite pole itself."""
    p = np.array([x, y, z])
    if np.linalg.norm(p) < 1e-6 or np.hypot(x, y) < 1e-6 * np.linalg.norm(p):
        return
    p = p / np.linalg.norm(p)
    xy = P.unfold_project(p * length)
    assert np.linalg.norm(xy) <= 1.0 + 1e-12
    back = P.unfold_unproject(xy)
    # Near the opposite pole the map squeezes a whole circle of azimuths into the rim,
    # so the round trip loses precision there as 1/sin(theta).
    tol = 1e-12 / max(np.hypot(x, y) / np.linalg.norm([x, y, z]), 1e-12) + 1e-12
    assert np.allclose(back, p, atol=max(tol, 1e-11))


@pytest.mark.parametrize("res", [64, 512])
def test_unfold_texel_angle_bounds_local_angle(res):
    """pi * step bounds the angle of one texel everywhere in the disk (radially it is
    exact) and stays within 2x of it on the near hemisphere (r <= 1/2)."""
    xy = _map_points(P.PARABOLOID)
    bound = P.texel_angle(P.UNFOLD, xy, res)
    measured = _measured_texel_angles(P.UNFOLD, xy, res, h=1e-7)
    assert np.all(bound >= measured.max(axis=1) * (1.0 - 1e-6))
    near = np.linalg.norm(xy, axis=1) <= 0.5
    assert np.all(bound[near] <= 2.0 * measured[near].min(axis=1))


def test_mixed_scales_in_one_array_match_row_by_row():
    """unit_directions and paraboloid_project take a fast path when every squared length is
    safe; one tiny, huge or zero row sends the array down the scaled path, row results unchanged."""
    rng = np.random.default_rng(11)
    dirs = rng.normal(size=(40, 3))
    scales = np.ones(40)
    scales[::5] = 1e-200
    scales[1::5] = 1e200
    points = dirs * scales[:, None]
    points[7] = 0.0
    together = P.unit_directions(points)
    one_by_one = np.array([P.unit_directions(p[None])[0] for p in points])
    assert np.allclose(together, one_by_one, rtol=1e-15, atol=0.0)
    assert np.array_equal(together[7], np.zeros(3))
    assert np.allclose(np.linalg.norm(np.delete(together, 7, axis=0), axis=1), 1.0, atol=1e-15)
    xy = P.paraboloid_project(points)
    assert np.all(np.isfinite(xy))
    assert np.allclose(xy, np.array([P.paraboloid_project(p[None])[0] for p in points]), rtol=1e-12, atol=1e-12)
