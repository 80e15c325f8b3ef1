"""Frame planning and layer culling (addon/core/plan.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from addon.core import frames as F
from addon.core import plan as PL
from addon.core import samples as SS
from addon.core.polytope import sample_polytope
from addon.core.scene import CameraSpec, LightSpec, look_at, translation

FAST = settings(max_examples=80, deadline=None)


def _half_extents(camera: CameraSpec) -> tuple[float, float]:
    width, height = camera.resolution
    half = math.tan(math.radians(camera.fov_deg) / 2.0)
    return (half, half * height / width) if width >= height else (half * width / height, half)


def _frustum_points(camera: CameraSpec, ndc: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """World points at image coordinates ndc (n, 2) in [-1, 1] and view depth (n,)."""
    hx, hy = _half_extents(camera)
    local = np.stack([ndc[:, 0] * hx * depth, ndc[:, 1] * hy * depth, -depth], axis=1)
    m = camera.matrix_world
    return local @ m[:3, :3].T + m[:3, 3]


def _random_frustum_samples(camera: CameraSpec, rng, n: int, d0: float, d1: float) -> np.ndarray:
    ndc = rng.uniform(-1.0, 1.0, size=(n, 2))
    ndc[:4] = [[-1, -1], [1, -1], [1, 1], [-1, 1]]  # the image corners too
    depth = rng.uniform(d0, d1, size=n)
    return _frustum_points(camera, ndc, depth)


def _ground_samples(camera: CameraSpec, half_size: float, nx: int = 48, ny: int = 36):
    """Camera rays hitting the square z = 0, |x|, |y| <= half_size (a ground quad)."""
    gx, gy = np.meshgrid(np.linspace(-1, 1, nx), np.linspace(-1, 1, ny))
    hx, hy = _half_extents(camera)
    d = np.stack([gx * hx, gy * hy, -np.ones_like(gx)], -1).reshape(-1, 3) @ camera.matrix_world[:3, :3].T
    o = camera.matrix_world[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o[2] / d[:, 2]
    hit = np.isfinite(t) & (t > 0)
    pos = o + d * np.where(hit, t, 0.0)[:, None]
    hit &= (np.abs(pos[:, 0]) <= half_size) & (np.abs(pos[:, 1]) <= half_size)
    return pos, hit


def _slots_needed(light: LightSpec, par: str, points: np.ndarray) -> set[int]:
    """Slots that the light-local directions of emitted points fall in (exact oracle)."""
    offs = points - light.position
    offs = offs[F.in_emission(light, offs) & (np.linalg.norm(offs, axis=1) > 0)]
    local = offs @ light.rotation  # world -> light local
    return {int(s) for s in np.unique(F.pick_slot(par, local))}


def _light_with_axis(position, axis, emission="omni") -> LightSpec:
    """A light at `position` whose axis (local -Z) points along `axis`."""
    position = np.asarray(position, dtype=float)
    return LightSpec(emission, look_at(position, position + np.asarray(axis, dtype=float)))


# ---------------------------------------------------------------- frustum corners


@pytest.mark.parametrize("resolution", [(64, 48), (48, 64), (32, 32)])
def test_frustum_corners_project_to_image_corners(resolution):
    """Corners at clip_start/clip_end project onto NDC (+-1, +-1, -1/+1) with projection()."""
    cam = CameraSpec(look_at((1.0, -4.0, 2.0), (0.3, 0.5, 0.2)), 57.0, resolution, 0.1, 40.0)
    corners = PL.frustum_corners(cam, cam.clip_start, cam.clip_end)
    homo = np.concatenate([corners, np.ones((8, 1))], axis=1)
    clip = homo @ (cam.projection() @ np.linalg.inv(cam.matrix_world)).T
    assert np.all(clip[:, 3] > 0)
    ndc = clip[:, :3] / clip[:, 3:]
    xy = [[-1, -1], [1, -1], [1, 1], [-1, 1]] * 2
    assert np.allclose(ndc[:, :2], xy, atol=1e-9)
    assert np.allclose(ndc[:4, 2], -1.0, atol=1e-9)
    assert np.allclose(ndc[4:, 2], 1.0, atol=1e-9)


def test_frustum_corners_at_given_depths():
    """Corner view depths equal the requested near and far depths."""
    cam = CameraSpec(look_at((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)), 90.0, (20, 10))
    corners = PL.frustum_corners(cam, 2.0, 7.0)
    forward = -cam.matrix_world[:3, 2]
    assert np.allclose(corners[:4] @ forward, 2.0) and np.allclose(corners[4:] @ forward, 7.0)
    # fov 90 spans the width: half-width = depth, half-height = depth / 2.
    assert np.allclose(np.abs(corners[:4, 0]), 2.0) and np.allclose(np.abs(corners[:4, 2]), 1.0)


def test_truncated_frustum_contains_all_hit_samples():
    """The truncated frustum spans the sample depths (with margin) and ignores misses and NaN."""
    cam = CameraSpec(look_at((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)), 60.0, (40, 30))
    rng = np.random.default_rng(4)
    pts = _random_frustum_samples(cam, rng, 200, 3.0, 9.0)
    hit = np.ones(len(pts), dtype=bool)
    pts[0] = [0.0, 1000.0, 0.0]
    hit[0] = False  # a miss far away must not stretch the frustum
    pts[1] = [np.nan, 5.0, 0.0]  # a NaN sample flagged as hit is ignored
    corners = PL.truncated_frustum(cam, SS.measure(cam, None, pts, hit))
    depth = corners @ np.array([0.0, 1.0, 0.0])
    sample_depth = pts[2:, 1]
    assert depth[:4].max() <= sample_depth.min() and depth[4:].min() >= sample_depth.max()
    assert depth[4:].max() < 9.0 * 1.1
    assert PL.truncated_frustum(cam, SS.measure(cam, None, pts, np.zeros(len(pts), dtype=bool))) is None


# ---------------------------------------------------------------- scenarios


def test_light_behind_camera_culls_face_behind_light():
    """Camera at y=2 looking along +Y, omni light at the origin behind it: the -Y face
    looks away from everything the camera sees and is culled; in fact every sample
    lies in the +Y face (|x|, |z| <= y), so only +Y is drawn."""
    cam = CameraSpec(look_at((0.0, 2.0, 0.0), (0.0, 10.0, 0.0)), 60.0, (64, 48))
    light = LightSpec("omni", np.eye(4))
    pts = _random_frustum_samples(cam, np.random.default_rng(0), 500, 1.0, 20.0)
    hit = np.ones(len(pts), dtype=bool)
    plan = PL.plan_frame(light, "cube", cam, SS.measure(cam, light, pts, hit), far=30.0)
    assert 3 not in plan.drawn_slots and "-Y" in plan.culled_names
    assert plan.drawn_slots == [2]
    assert len(plan.all_layers) == 6


def test_light_behind_camera_draws_one_paraboloid_side():
    """Same view, light axis pointing away from the view (-Y): the whole view lies in
    the back side (slot 1), so the axis side is culled."""
    cam = CameraSpec(look_at((0.0, 2.0, 0.0), (0.0, 10.0, 0.0)), 60.0, (64, 48))
    light = _light_with_axis((0.0, 0.0, 0.0), (0.0, -1.0, 0.0))
    pts = _random_frustum_samples(cam, np.random.default_rng(1), 500, 1.0, 20.0)
    plan = PL.plan_frame(light, "dpsm", cam, SS.measure(cam, light, pts, np.ones(len(pts), dtype=bool)), far=30.0)
    assert plan.drawn_slots == [1]


def test_courtyard_like_setup_needs_few_layers():
    """Omni light high above and behind a camera looking down onto a ground square:
    at most 3 cube faces (never +Z, everything is below the light) and one
    paraboloid side (the one looking down)."""
    light = LightSpec("omni", translation((13.0, -11.0, 20.0)))
    cam = CameraSpec(look_at((7.5, -7.5, 3.2), (-2.0, 2.0, 0.0)), 62.0, (64, 48))
    pts, hit = _ground_samples(cam, 15.0)
    assert hit.sum() > 100
    corners = PL.truncated_frustum(cam, SS.measure(cam, None, pts, hit))
    assert np.all(corners[:, 2] < light.position[2])  # precondition: the view is below the light

    cube = PL.plan_frame(light, "cube", cam, SS.measure(cam, light, pts, hit), far=60.0)
    assert len(cube.drawn) <= 3
    assert 4 not in cube.drawn_slots
    assert _slots_needed(light, "cube", pts[hit]) <= set(cube.drawn_slots)

    dpsm = PL.plan_frame(light, "dpsm", cam, SS.measure(cam, light, pts, hit), far=60.0)
    assert dpsm.drawn_slots == [0]  # slot 0 looks along local -Z = down
    assert dpsm.culled_names == [F.PARABOLOID_SIDE_NAMES[1]]


@pytest.mark.parametrize("par, count", [("dpsm", 2), ("cube", 6)])
def test_light_inside_view_gets_all_layers(par, count):
    """A light inside the truncated view frustum needs every layer."""
    cam = CameraSpec(look_at((0.0, 0.0, 1.0), (0.0, 10.0, 1.0)), 70.0, (64, 48))
    light = LightSpec("omni", translation((0.2, 6.0, 0.9)))
    pts = _random_frustum_samples(cam, np.random.default_rng(2), 400, 0.5, 15.0)
    plan = PL.plan_frame(light, par, cam, SS.measure(cam, light, pts, np.ones(len(pts), dtype=bool)), far=30.0)
    assert len(plan.drawn) == count and plan.culled_names == []


@pytest.mark.parametrize("cull", [True, False])
def test_hemi_light_never_gets_back_side(cull):
    """A hemi light has no back paraboloid side and no +Z cube face, culled or not,
    even when the view surrounds the light."""
    cam = CameraSpec(look_at((0.0, 0.0, 1.0), (0.0, 10.0, 1.0)), 70.0, (64, 48))
    light = _light_with_axis((0.0, 6.0, 1.0), (0.3, 0.2, -1.0), emission="hemi")
    pts = _random_frustum_samples(cam, np.random.default_rng(3), 400, 0.5, 15.0)
    hit = np.ones(len(pts), dtype=bool)
    dpsm = PL.plan_frame(light, "dpsm", cam, SS.measure(cam, light, pts, hit), far=30.0, cull=cull)
    cube = PL.plan_frame(light, "cube", cam, SS.measure(cam, light, pts, hit), far=30.0, cull=cull)
    assert dpsm.drawn_slots == [0]
    assert sorted(cube.drawn_slots) == [0, 1, 2, 3, 5]


@pytest.mark.parametrize("par", ["dpsm", "cube"])
def test_empty_view(par):
    """No sample hits: cull=True draws nothing (no frustum), cull=False draws everything."""
    cam = CameraSpec(look_at((0.0, 0.0, 1.0), (0.0, 10.0, 1.0)), 70.0, (8, 6))
    light = LightSpec("omni", translation((0.0, 3.0, 1.0)))
    pts = np.zeros((48, 3))
    hit = np.zeros(48, dtype=bool)
    culled = PL.plan_frame(light, par, cam, SS.measure(cam, light, pts, hit), far=10.0, cull=True)
    assert culled.drawn == [] and culled.frustum_corners is None
    assert len(culled.culled_names) == F.slot_count(par)
    full = PL.plan_frame(light, par, cam, SS.measure(cam, light, pts, hit), far=10.0, cull=False)
    assert full.drawn_slots == list(range(F.slot_count(par)))
    assert full.culled_names == []


# ---------------------------------------------------------------- conservativeness


def _random_camera(rng) -> CameraSpec:
    eye = rng.uniform(-10, 10, size=3)
    target = eye + rng.normal(size=3)
    res = [(64, 48), (48, 64), (40, 40)][rng.integers(3)]
    return CameraSpec(look_at(eye, target), float(rng.uniform(15.0, 120.0)), res, 0.05, 200.0)


def _random_light(rng, camera: CameraSpec) -> LightSpec:
    m = np.eye(4)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    m[:3, :3] = q
    choice = rng.integers(3)
    if choice == 0:  # somewhere in front of the camera (often inside the view)
        m[:3, 3] = _frustum_points(camera, rng.uniform(-1.2, 1.2, size=(1, 2)), rng.uniform(0.5, 12.0, size=1))[0]
    elif choice == 1:  # just behind or beside the camera
        m[:3, 3] = camera.matrix_world[:3, 3] + rng.normal(scale=2.0, size=3)
    else:
        m[:3, 3] = rng.uniform(-20, 20, size=3)
    return LightSpec(["omni", "hemi"][rng.integers(2)], m)


@FAST
@given(st.integers(0, 2**32 - 1))
def test_culling_is_conservative(seed):
    """Random cameras, lights and samples in the view: every layer that some sample's
    direction falls in (pick_slot) is drawn, for both parameterizations. The same
    holds for points on the edges of the plan's truncated frustum, which contains
    every occluder of a visible receiver."""
    rng = np.random.default_rng(seed)
    cam = _random_camera(rng)
    light = _random_light(rng, cam)
    d0 = float(rng.uniform(0.1, 5.0))
    d1 = d0 + float(rng.uniform(0.01, 30.0))
    pts = _random_frustum_samples(cam, rng, 300, d0, d1)
    hit = rng.random(len(pts)) < 0.9
    hit[:4] = True
    for par in ("dpsm", "cube"):
        plan = PL.plan_frame(light, par, cam, SS.measure(cam, light, pts, hit), far=float(rng.uniform(1.0, 100.0)))
        drawn = set(plan.drawn_slots)
        assert _slots_needed(light, par, pts[hit]) <= drawn
        c = plan.frustum_corners
        edges = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]
        t = np.linspace(0.0, 1.0, 41)[:, None]
        hull = np.concatenate([c[i] + t * (c[j] - c[i]) for i, j in edges])
        assert _slots_needed(light, par, hull) <= drawn
        assert {layer.slot for layer in plan.all_layers} >= drawn


def test_layer_meets_frustum_exact_touching_cases():
    """Cube face pyramid vs a box-like frustum: clearly inside, clearly outside, and a
    hull that crosses the pyramid only between its corners (no corner inside)."""
    light = LightSpec("omni", np.eye(4))
    face_px = F.light_layers(light, "cube")[0]  # looks along +X
    cam = CameraSpec(look_at((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)), 10.0, (10, 10))
    inside = PL.frustum_corners(cam, 2.0, 3.0)
    assert PL.layer_meets_frustum(face_px, np.zeros(3), inside, far=10.0)
    behind = inside - np.array([10.0, 0.0, 0.0])  # all at x < 0
    assert not PL.layer_meets_frustum(face_px, np.zeros(3), behind, far=10.0)
    # A thin slab crossing the +X pyramid at x = 5 whose corners all lie outside it
    # (|y| = 20 > x): only an exact intersection test draws this face.
    slab = np.array([[5.0, -20.0, -0.1], [5.0, 20.0, -0.1], [5.0, 20.0, 0.1], [5.0, -20.0, 0.1],
                     [5.2, -20.0, -0.1], [5.2, 20.0, -0.1], [5.2, 20.0, 0.1], [5.2, -20.0, 0.1]])
    assert PL.layer_meets_frustum(face_px, np.zeros(3), slab, far=10.0)
    # The same slab moved to negative x misses the +X face entirely.
    assert not PL.layer_meets_frustum(face_px, np.zeros(3), slab - [10.0, 0.0, 0.0], far=10.0)


def test_layer_meets_frustum_is_exact_beside_a_face():
    """A small box just outside the +X pyramid's side (|y| > x everywhere) is culled:
    the pyramid's side plane separates them, although the box is in front (x > 0)."""
    light = LightSpec("omni", np.eye(4))
    face_px = F.light_layers(light, "cube")[0]
    lo, hi = np.array([4.9, 5.2, -0.1]), np.array([5.1, 5.4, 0.1])
    box = np.array([[lo[0], lo[1], lo[2]], [lo[0], hi[1], lo[2]], [lo[0], hi[1], hi[2]], [lo[0], lo[1], hi[2]],
                    [hi[0], lo[1], lo[2]], [hi[0], hi[1], lo[2]], [hi[0], hi[1], hi[2]], [hi[0], lo[1], hi[2]]])
    assert not PL.layer_meets_frustum(face_px, np.zeros(3), box, far=10.0)
    assert PL.layer_meets_frustum(face_px, np.zeros(3), box - [0.0, 0.5, 0.0], far=10.0)  # now |y| < x


@pytest.mark.parametrize("offset, meets", [(0.05, False), (-0.05, True)])
def test_layer_meets_frustum_is_exact_near_a_pyramid_edge(offset, meets):
    """A thin rod skew to the +Z pyramid's edge x = y = z, just outside it: only the
    cross product of the two edge directions separates them (no face normal of
    either solid does), so an exact test culls it; moved inward it meets."""
    light = LightSpec("omni", np.eye(4))
    face_pz = F.light_layers(light, "cube")[4]  # local frame == light frame
    u = np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0)  # the pyramid edge
    w = np.array([1.0, 1.0, -2.0]) / np.sqrt(6.0)  # outward from that edge
    d = np.cross(u, w)  # rod direction, perpendicular to both
    a, b = (u + w) / np.sqrt(2.0), (u - w) / np.sqrt(2.0)  # rod cross-section turned 45 degrees
    centre = 5.0 * np.sqrt(3.0) * u + offset * w
    half_len, h = 3.0, 0.005
    quad = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    near = [centre - half_len * d + h * (sa * a + sb * b) for sa, sb in quad]
    far = [centre + half_len * d + h * (sa * a + sb * b) for sa, sb in quad]
    rod = np.array(near + far)
    local = face_pz.to_local(rod)
    inside = lambda p: np.all(np.abs(p[:, :2]) <= p[:, 2:3], axis=1)  # noqa: E731
    samples = rod[:4][:, None] + np.linspace(0, 1, 101)[None, :, None] * (rod[4:] - rod[:4])[:, None]
    assert inside(face_pz.to_local(samples.reshape(-1, 3))).any() == meets  # ground truth
    assert local[:, 2].min() > 0
    assert PL.layer_meets_frustum(face_pz, np.zeros(3), rod, far=20.0) == meets


def test_courtyard_preset_needs_one_side_and_three_faces():
    """The shipped courtyard (light high behind the camera, outside the view), with
    view samples ray-cast by the numpy oracle: one paraboloid side and at most 3
    cube faces, and every face a sample falls in is among them."""
    from addon.core.presets import build_preset
    from addon.core.projection import depth_range
    from tests.support.oracle import camera_rays, ray_hits  # imported here: it pulls in addon.render

    scene = build_preset("courtyard", (80, 60))
    origins, dirs = camera_rays(scene.camera)
    tris = scene.world_triangles()
    t, _ = ray_hits(origins, dirs, tris)
    hit = np.isfinite(t)
    pos = origins + dirs * np.where(hit, t, 0.0)[:, None]
    _, far = depth_range(tris, scene.light.position)
    dpsm = PL.plan_frame(scene.light, "dpsm", scene.camera, SS.measure(scene.camera, scene.light, pos, hit), far)
    cube = PL.plan_frame(scene.light, "cube", scene.camera, SS.measure(scene.camera, scene.light, pos, hit), far)
    assert dpsm.drawn_slots == [0]
    assert len(cube.drawn) <= 3 and 4 not in cube.drawn_slots
    assert _slots_needed(scene.light, "cube", pos[hit]) <= set(cube.drawn_slots)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from(["dpsm", "cube"]))
def test_layer_scissor_holds_every_sample(seed, par):
    """Map-space culling is conservative: every sample, moved by up to a texel (the normal
    offset), projects inside its layer's scissor box, which comes from the sample
    polytope; a light inside the polytope gets no box."""
    from addon.core import projection

    rng = np.random.default_rng(seed)
    camera = CameraSpec(look_at(rng.uniform(-5, 5, 3), rng.uniform(-1, 1, 3) + [0.0, 0.0, 0.01]), 60.0, (64, 48))
    samples = _random_frustum_samples(camera, rng, 400, 0.5, 20.0)
    corners = PL.frustum_corners(camera, 0.5, 20.0)
    polytope = sample_polytope(corners, (samples.min(axis=0), samples.max(axis=0)))
    light = LightSpec("omni", translation(rng.uniform(-30, 30, 3)))
    res = 256
    for layer in F.light_layers(light, par):
        box = PL.layer_scissor(layer, light.position, polytope, res)
        if polytope.contains(light.position):
            assert box is None
        if box is None:
            continue
        local = layer.to_local(samples - light.position)
        mine = F.pick_slot(par, (samples - light.position) @ light.rotation) == layer.slot
        if not np.any(mine):
            continue
        texel = (projection.project(layer.kind, local[mine]) * 0.5 + 0.5) * res
        # A texel of slack inside the box, except where the box meets the map's border.
        lo = np.array([box[0] + 1 if box[0] > 0 else 0, box[1] + 1 if box[1] > 0 else 0])
        hi = np.array([box[2] - 1 if box[2] < res else res, box[3] - 1 if box[3] < res else res])
        assert np.all(texel >= lo) and np.all(texel <= hi), (box, texel.min(axis=0), texel.max(axis=0))


@pytest.mark.parametrize("parameterization", ["dpsm", "unfold", "cube"])
@pytest.mark.parametrize("emission", ["omni", "hemi"])
def test_occupied_slots_match_pick_slot(parameterization, emission):
    """The fast paraboloid path and the general one both agree with pick_slot per sample."""
    from addon.core.frames import pick_slot
    from addon.core.scene import LightSpec

    rng = np.random.default_rng(4)
    angles = rng.uniform(-np.pi, np.pi, 3)
    c, s = np.cos(angles), np.sin(angles)
    rot = (np.array([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]])
           @ np.array([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]])
           @ np.array([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]]))
    matrix = np.eye(4)
    matrix[:3, :3] = rot
    matrix[:3, 3] = [1.0, -2.0, 0.5]
    light = LightSpec(emission, matrix)
    for count in (1, 7, 500):
        pts = light.position + rng.normal(size=(count, 3)) * rng.uniform(0.1, 10.0)
        local = (pts - light.position) @ light.rotation
        if emission == "hemi":
            local = local[local[:, 2] < 0.0]
        expected = set(int(v) for v in np.unique(pick_slot(parameterization, local)))
        assert SS.measure(None, light, pts, np.ones(len(pts), dtype=bool)).occupied(parameterization) == expected


# ---------------------------------------------------------------- sample window


def _pixel_ground_samples(camera: CameraSpec, half_size: float) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) hits of pixel-centre rays (row 0 at the top) on a ground square, and the mask."""
    from tests.support.oracle import camera_rays

    width, height = camera.resolution
    origins, dirs = camera_rays(camera)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -origins[:, 2] / dirs[:, 2]
    hit = np.isfinite(t) & (t > 0)
    pos = origins + dirs * np.where(hit, t, 0.0)[:, None]
    hit &= (np.abs(pos[:, 0]) <= half_size) & (np.abs(pos[:, 1]) <= half_size)
    return pos.reshape(height, width, 3), hit.reshape(height, width)


def _window(camera: CameraSpec, hit: np.ndarray) -> tuple[float, float, float, float]:
    """The sample window of a hit mask (positions do not matter to it)."""
    return SS.measure(camera, None, np.zeros(np.shape(hit) + (3,)), hit).window


def _ndc(camera: CameraSpec, points: np.ndarray) -> np.ndarray:
    m = camera.matrix_world
    local = (points - m[:3, 3]) @ m[:3, :3]
    hx, hy = _half_extents(camera)
    return np.stack([local[:, 0] / -local[:, 2] / hx, local[:, 1] / -local[:, 2] / hy], axis=1)


@pytest.mark.parametrize("target", [(0.0, 30.0, 0.0), (-12.0, 30.0, -1.0), (14.0, 6.0, -4.0)])
def test_sample_window_drops_sky_rows_and_keeps_every_sample(target):
    """A camera looking over a ground square sees sky above the horizon (and beside the
    square): the window leaves those pixels out but holds every sample's image point."""
    cam = CameraSpec(look_at((0.0, -6.0, 2.0), target), 70.0, (64, 48))
    pos, hit = _pixel_ground_samples(cam, 8.0)
    assert 0 < hit.sum() < hit.size
    x0, x1, y0, y1 = _window(cam, hit)
    assert (x1 - x0) * (y1 - y0) < 4.0  # narrower than the whole frame
    ndc = _ndc(cam, pos[hit])
    assert np.all((ndc[:, 0] >= x0) & (ndc[:, 0] <= x1) & (ndc[:, 1] >= y0) & (ndc[:, 1] <= y1))
    # Within one pixel and a half of the outermost samples (the window grows one pixel).
    width, height = cam.resolution
    assert x0 >= ndc[:, 0].min() - 3.0 / width and x1 <= ndc[:, 0].max() + 3.0 / width
    assert y0 >= ndc[:, 1].min() - 3.0 / height and y1 <= ndc[:, 1].max() + 3.0 / height
    # The truncated frustum through the window holds every sample.
    corners = PL.truncated_frustum(cam, SS.measure(cam, None, pos, hit))
    assert all(PL.point_in_frustum(p, corners) for p in pos[hit][::7])


def test_sample_window_falls_back_to_the_whole_frame():
    cam = CameraSpec(look_at((0.0, -6.0, 2.0), (0.0, 30.0, 0.0)), 70.0, (64, 48))
    _, hit = _pixel_ground_samples(cam, 8.0)
    assert _window(cam, hit.ravel()) == SS.FULL_WINDOW  # not an image mask
    assert _window(cam, hit.T) == SS.FULL_WINDOW  # the wrong way round
    assert _window(cam, np.zeros_like(hit)) == SS.FULL_WINDOW
    assert _window(cam, np.ones_like(hit)) == SS.FULL_WINDOW
