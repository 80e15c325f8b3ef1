"""Cameras as Blender has them (addon/core/camera.py), numpy only.

Oracles: the formulas CameraSpec had before windows existed (copied here, so the
centred form is checked bit for bit), Blender's view-plane rule written out by hand
for a few cameras, OpenGL's glFrustum / glOrtho conventions, and convex-hull
containment of sampled points. tests/blender/test_camera_frame.py checks the same
windows against Blender's own `view_frame` and `calc_matrix_camera`, and Cycles.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core import perspective as PS
from addon.core import plan as PL
from addon.core import samples as SS
from addon.core.camera import (
    CameraSpec,
    blender_camera_settings,
    blender_camera_window,
    camera_from_matrices,
    window_fov_deg,
)
from addon.core.errors import InputError
from addon.core.scene import LightSpec, SceneBuilder, look_at, translation
from addon.reference.data import ReferenceData

EYE, TARGET = (1.0, -4.0, 2.0), (0.3, 0.5, 0.2)


def _old_frustum_corners(camera: CameraSpec, near_depth: float, far_depth: float, window=PL.FULL_WINDOW):
    """plan.frustum_corners as it was before windows (the centred form)."""
    width, height = camera.resolution
    half = math.tan(math.radians(camera.fov_deg) / 2.0)
    if width >= height:
        hx, hy = half, half * height / width
    else:
        hx, hy = half * width / height, half
    x0, x1, y0, y1 = window
    corners = []
    for depth in (near_depth, far_depth):
        for sx, sy in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):
            corners.append([sx * hx * depth, sy * hy * depth, -depth])
    local = np.asarray(corners, dtype=np.float64)
    m = np.asarray(camera.matrix_world, dtype=np.float64)
    return local @ m[:3, :3].T + m[:3, 3]


def _old_projection(camera: CameraSpec) -> np.ndarray:
    width, height = camera.resolution
    half = math.tan(math.radians(camera.fov_deg) / 2.0)
    if width >= height:
        sx, sy = 1.0 / half, (width / height) / half
    else:
        sx, sy = (height / width) / half, 1.0 / half
    n, f = camera.clip_start, camera.clip_end
    return np.array([[sx, 0, 0, 0], [0, sy, 0, 0], [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)], [0, 0, -1, 0]],
                    dtype=np.float64)


def _old_pixel_dirs(camera: CameraSpec) -> np.ndarray:
    """tests/support/oracle.camera_rays as it was: directions through pixel centres."""
    width, height = camera.resolution
    half = math.tan(math.radians(camera.fov_deg) / 2)
    hx, hy = (half, half * height / width) if width >= height else (half * width / height, half)
    xs = ((np.arange(width) + 0.5) / width * 2 - 1) * hx
    ys = (1 - (np.arange(height) + 0.5) / height * 2) * hy
    gx, gy = np.meshgrid(xs, ys)
    local = np.stack([gx, gy, -np.ones_like(gx)], axis=-1).reshape(-1, 3)
    dirs = local @ np.asarray(camera.matrix_world)[:3, :3].T
    return dirs / np.linalg.norm(dirs, axis=1, keepdims=True)


# Windowed cameras: shifted landscape, VERTICAL-fit portrait with 2:1 pixels, orthographic.
def _shifted() -> CameraSpec:
    window = blender_camera_window((64, 48), lens=35.0, shift=(0.35, -0.2))
    return CameraSpec.from_window(look_at(EYE, TARGET), window, (64, 48), 0.1, 40.0)


def _portrait() -> CameraSpec:
    window = blender_camera_window((24, 48), lens=30.0, sensor_fit="VERTICAL", pixel_aspect=(2.0, 1.0),
                                   shift=(-0.1, 0.15))
    return CameraSpec.from_window(look_at(EYE, TARGET), window, (24, 48), 0.1, 40.0)


def _ortho() -> CameraSpec:
    window = blender_camera_window((64, 48), ortho=True, ortho_scale=5.0, shift=(0.2, 0.1))
    return CameraSpec.from_window(look_at(EYE, TARGET), window, (64, 48), 0.1, 40.0, ortho=True)


WINDOWED = {"shifted": _shifted, "portrait": _portrait, "ortho": _ortho}


# ---------------------------------------------------------------- the centred form
@pytest.mark.parametrize("resolution", [(64, 48), (48, 64), (50, 50), (640, 480)])
@pytest.mark.parametrize("window", [PL.FULL_WINDOW, (-0.25, 0.8, -1.0, 0.125), (0.0, 0.5, -0.5, 0.0)])
def test_fov_form_is_bit_identical_to_before(resolution, window):
    camera = CameraSpec(look_at(EYE, TARGET), 57.0, resolution, 0.1, 40.0)
    assert camera.window is None and not camera.ortho and camera.is_centred
    assert np.array_equal(PL.frustum_corners(camera, 0.3, 12.5, window),
                          _old_frustum_corners(camera, 0.3, 12.5, window))
    assert np.array_equal(camera.projection(), _old_projection(camera))
    assert np.array_equal(camera.pixel_rays()[1].reshape(-1, 3), _old_pixel_dirs(camera))


def _built_camera(**kwargs) -> CameraSpec:
    b = SceneBuilder("t", (64, 48))
    b.point_light((0.0, 0.0, 3.0))
    b.camera((0.0, -5.0, 2.0), (0.0, 0.0, 0.0), **kwargs)
    return b.finish().camera


def test_builder_default_camera_is_the_fov_form():
    camera = _built_camera(fov_deg=62.0)
    assert camera.window is None and camera.fov_deg == 62.0


def test_fov_form_window_matches_blender_auto_fit():
    """The centred form is Blender's AUTO fit: the larger side spans fov_deg."""
    for resolution in ((64, 48), (48, 64)):
        camera = CameraSpec(np.eye(4), 60.0, resolution)
        lens = 18.0 / math.tan(math.radians(30.0))  # a 36 mm sensor spanning 60 degrees
        np.testing.assert_allclose(camera.frame_extents(), blender_camera_window(resolution, lens=lens), rtol=1e-12)


# ---------------------------------------------------------------- Blender's rule by hand
def test_blender_window_cases():
    # HORIZONTAL fit on a portrait image: the width spans the sensor, the height follows.
    l, r, b, t = blender_camera_window((48, 64), lens=50.0, sensor_fit="HORIZONTAL", sensor_width=36.0)
    assert (r - l) == pytest.approx(36.0 / 50.0) and (t - b) == pytest.approx(36.0 / 50.0 * 64 / 48)
    # VERTICAL fit uses the sensor height, whatever the image shape.
    l, r, b, t = blender_camera_window((64, 48), lens=50.0, sensor_fit="VERTICAL", sensor_height=24.0)
    assert (t - b) == pytest.approx(24.0 / 50.0) and (r - l) == pytest.approx(24.0 / 50.0 * 64 / 48)
    # AUTO on a portrait image fits the height, with the sensor WIDTH (Blender's rule).
    l, r, b, t = blender_camera_window((48, 64), lens=50.0, sensor_width=36.0, sensor_height=24.0)
    assert (t - b) == pytest.approx(36.0 / 50.0) and (r - l) == pytest.approx(36.0 / 50.0 * 48 / 64)
    # Pixel aspect 2:1 on 32x64 pixels is a square image: AUTO fits the width (>=).
    l, r, b, t = blender_camera_window((32, 64), lens=50.0, pixel_aspect=(2.0, 1.0))
    assert (r - l) == pytest.approx(0.72) and (t - b) == pytest.approx(0.72)
    # Shift moves the window by shift times the fitted side, on both axes.
    l, r, b, t = blender_camera_window((48, 64), lens=50.0, shift=(0.5, -0.25))
    assert (l + r) / 2 == pytest.approx(0.5 * 0.72) and (b + t) / 2 == pytest.approx(-0.25 * 0.72)
    # Orthographic: scene units, the fitted side spans ortho_scale.
    l, r, b, t = blender_camera_window((64, 48), ortho=True, ortho_scale=8.0, shift=(0.25, 0.0))
    assert (l, r) == pytest.approx((-2.0, 6.0)) and (b, t) == pytest.approx((-3.0, 3.0))


def test_bad_camera_values_are_input_errors():
    with pytest.raises(InputError, match="sensor fit"):
        blender_camera_window((64, 48), sensor_fit="DIAGONAL")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="orthographic scale"):
        blender_camera_window((64, 48), ortho=True, ortho_scale=0.0)
    with pytest.raises(InputError, match="window"):
        CameraSpec(np.eye(4), 0.0, (8, 8), window=(1.0, -1.0, -1.0, 1.0))
    with pytest.raises(InputError, match="orthographic"):
        CameraSpec(np.eye(4), 60.0, (8, 8), ortho=True)


@pytest.mark.parametrize("name", list(WINDOWED))
def test_blender_settings_invert_the_window(name):
    camera = WINDOWED[name]()
    s = blender_camera_settings(camera)
    back = blender_camera_window(camera.resolution, ortho=s["type"] == "ORTHO", lens=s.get("lens", 50.0),
                                 ortho_scale=s.get("ortho_scale", 6.0), sensor_fit=s["sensor_fit"],
                                 sensor_width=s["sensor_width"], shift=(s["shift_x"], s["shift_y"]),
                                 pixel_aspect=(s["pixel_aspect_x"], s["pixel_aspect_y"]))
    np.testing.assert_allclose(back, camera.window, rtol=1e-12, atol=1e-14)
    assert min(s["pixel_aspect_x"], s["pixel_aspect_y"]) == 1.0  # Blender's range starts at 1


# ---------------------------------------------------------------- projection and rays
@pytest.mark.parametrize("name", list(WINDOWED))
def test_projection_maps_the_frame_onto_ndc(name):
    """Frame points at the clip depths land on their NDC with z = -1 / +1 (OpenGL)."""
    camera = WINDOWED[name]()
    rng = np.random.default_rng(1)
    ndc = rng.uniform(-1.0, 1.0, (50, 2))
    for depth, z in ((camera.clip_start, -1.0), (camera.clip_end, 1.0), (3.0, None)):
        world = camera.world_points(ndc, depth)
        clip = np.c_[world, np.ones(len(world))] @ (camera.projection() @ np.linalg.inv(camera.matrix_world)).T
        np.testing.assert_allclose(clip[:, :2] / clip[:, 3:], ndc, atol=1e-9)
        if z is not None:
            np.testing.assert_allclose(clip[:, 2] / clip[:, 3], z, atol=1e-9)
        np.testing.assert_allclose(camera.ndc_of(world), ndc, atol=1e-9)
        np.testing.assert_allclose(camera.view_depths(world), depth, rtol=1e-12)


@pytest.mark.parametrize("name", list(WINDOWED))
def test_pixel_rays_pass_through_their_pixel_centres(name):
    camera = WINDOWED[name]()
    origins, dirs = camera.pixel_rays()
    width, height = camera.resolution
    assert origins.shape == dirs.shape == (height, width, 3)
    points = origins + 2.5 * dirs
    cols, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    np.testing.assert_allclose(camera.pixel_of(points), np.stack([cols, rows], axis=-1), atol=1e-9)
    if camera.ortho:  # parallel rays along the view axis, starting on the camera plane
        np.testing.assert_allclose(dirs, np.broadcast_to(-camera.matrix_world[:3, 2], dirs.shape), atol=1e-12)
        np.testing.assert_allclose(camera.view_depths(origins), 0.0, atol=1e-12)
    else:
        np.testing.assert_allclose(origins, np.broadcast_to(camera.matrix_world[:3, 3], origins.shape))


def test_ortho_frustum_is_a_box():
    camera = _ortho()
    corners = PL.frustum_corners(camera, 1.0, 9.0)
    local = (corners - camera.matrix_world[:3, 3]) @ camera.matrix_world[:3, :3]
    np.testing.assert_allclose(local[:4, :2], local[4:, :2], atol=1e-12)  # no growth with depth
    l, r, b, t = camera.window
    np.testing.assert_allclose(local[:4, :2], [[l, b], [r, b], [r, t], [l, t]], atol=1e-12)
    assert camera.fov_deg == 0.0 and window_fov_deg(camera.window, camera.resolution, ortho=True) == 0.0


# ---------------------------------------------------------------- camera_from_matrices
@pytest.mark.parametrize("name", ["centred", *WINDOWED])
def test_camera_from_matrices_round_trips(name):
    camera = CameraSpec(look_at(EYE, TARGET), 57.0, (64, 48), 0.1, 40.0) if name == "centred" else WINDOWED[name]()
    back = camera_from_matrices(np.linalg.inv(camera.matrix_world), camera.projection(), camera.resolution)
    assert back is not None and back.ortho == camera.ortho and back.resolution == camera.resolution
    np.testing.assert_allclose(back.frame_extents(), camera.frame_extents(), rtol=1e-9, atol=1e-12)
    assert (back.clip_start, back.clip_end) == pytest.approx((camera.clip_start, camera.clip_end), rel=1e-9)
    np.testing.assert_allclose(back.matrix_world, camera.matrix_world, atol=1e-12)
    np.testing.assert_allclose(PL.frustum_corners(back, 0.5, 7.0), PL.frustum_corners(camera, 0.5, 7.0), atol=1e-9)


def test_camera_from_matrices_viewport_ortho_with_negative_near():
    """Blender's orthographic viewport puts its near plane behind the view point."""
    camera = CameraSpec.from_window(look_at(EYE, TARGET), (-3.0, 3.0, -2.0, 2.0), (60, 40), -50.0, 50.0, ortho=True)
    back = camera_from_matrices(np.linalg.inv(camera.matrix_world), camera.projection(), (60, 40))
    assert back is not None and back.ortho
    assert (back.clip_start, back.clip_end) == pytest.approx((-50.0, 50.0))


def test_camera_from_matrices_refuses_a_skewed_projection():
    p = _shifted().projection()
    p[0, 1] = 0.3
    assert camera_from_matrices(np.eye(4), p, (64, 48)) is None


# ---------------------------------------------------------------- culling stays safe
def _samples(camera: CameraSpec, seed: int, depth_range=(0.5, 9.0), jitter: float = 0.49):
    """Positions (H, W, 3) on rays within `jitter` px of each pixel centre, and a hit mask
    that leaves sky around the edges (so sample_window narrows the frame)."""
    rng = np.random.default_rng(seed)
    width, height = camera.resolution
    ndc = camera.pixel_ndc() + rng.uniform(-jitter, jitter, (height, width, 2)) * [2.0 / width, 2.0 / height]
    origins, dirs = camera.rays_through_ndc(ndc)
    depth = rng.uniform(*depth_range, (height, width))
    along = depth / np.maximum(camera.view_depths(origins + dirs) - camera.view_depths(origins), 1e-12)
    positions = origins + dirs * along[..., None]
    hit = rng.random((height, width)) < 0.7
    hit[: height // 5] = False
    hit[:, -width // 6:] = False
    return positions, hit


@pytest.mark.parametrize("name", list(WINDOWED))
def test_truncated_frustum_holds_every_sample(name):
    camera = WINDOWED[name]()
    positions, hit = _samples(camera, seed=len(name))
    corners = PL.truncated_frustum(camera, SS.measure(camera, None, positions, hit))
    planes = PS.hull_planes(corners)
    points = positions[hit]
    slack = 1e-9 * (1.0 + float(np.abs(points).max()))
    assert np.all(points @ planes[:, :3].T - planes[:, 3] <= slack)
    # The window cut really narrows the frame (sky rows and columns are left out).
    window = SS.measure(camera, None, positions, hit).window
    assert window[1] < 1.0 and window[3] < 1.0


def test_ortho_samples_at_negative_depth_are_held():
    """An orthographic viewport sees samples behind its view point (near < 0)."""
    camera = CameraSpec.from_window(look_at(EYE, TARGET), (-3.0, 3.0, -2.0, 2.0), (48, 32), -50.0, 50.0, ortho=True)
    positions, hit = _samples(camera, seed=5, depth_range=(-6.0, 4.0))
    planes = PS.hull_planes(PL.truncated_frustum(camera, SS.measure(camera, None, positions, hit)))
    assert np.all(positions[hit] @ planes[:, :3].T - planes[:, 3] <= 1e-8)


def test_ortho_camera_culls_cube_faces_and_keeps_occupied_ones():
    camera = _ortho()
    positions, hit = _samples(camera, seed=3, depth_range=(4.0, 6.0))
    far_light = LightSpec("omni", translation(camera.matrix_world[:3, 3] + [30.0, 0.0, 0.0]))
    plan = PL.plan_frame(far_light, "cube", camera, SS.measure(camera, far_light, positions, hit), far=100.0)
    assert 0 < len(plan.drawn) < 6
    occupied = SS.measure(camera, far_light, positions, hit).occupied("cube")
    assert occupied <= set(plan.drawn_slots)


def test_skewed_axis_weighs_ortho_corners_alike():
    camera = _ortho()
    corners = PL.frustum_corners(camera, 1.0, 9.0)
    light = np.array([10.0, 10.0, 10.0])
    d = corners - light
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    expected = d.sum(axis=0) / np.linalg.norm(d.sum(axis=0))
    np.testing.assert_allclose(PL.skewed_axis(light, corners, camera), expected, atol=1e-12)


# ---------------------------------------------------------------- PSM
BOX_LO, BOX_HI = np.array([-6.0, -6.0, -1.0]), np.array([6.0, 6.0, 4.0])
SPOT = LightSpec("spot", look_at((0.0, 2.0, 9.0), (0.0, 0.0, 0.0)), spot_size=math.radians(90.0))


def test_psm_uses_the_cameras_real_projection():
    """PPS is the shifted camera's own NDC: the frustum's corners map to (+-1, +-1, +-1)."""
    camera = _shifted()
    near, far = 0.5, 9.0
    clip = PS.camera_clip(camera, near, far, SPOT.position)
    corners = PL.frustum_corners(camera, near, far) - SPOT.position
    hom = np.c_[corners, np.ones(8)] @ clip.T
    expected = [[-1, -1], [1, -1], [1, 1], [-1, 1]] * 2
    np.testing.assert_allclose(hom[:, :2] / hom[:, 3:], expected, atol=1e-9)
    np.testing.assert_allclose(hom[:, 2] / hom[:, 3], [-1.0] * 4 + [1.0] * 4, atol=1e-9)
    psm = PS.psm_map(SPOT, camera, near, far, PL.frustum_corners(camera, near, far), BOX_LO, BOX_HI, 512)
    uv, z, w = PS.project(psm, psm.region)
    assert np.all(w > 0) and np.all((uv > -1e-9) & (uv < 1 + 1e-9))


def test_psm_refuses_an_ortho_camera():
    camera = _ortho()
    with pytest.raises(InputError, match="perspective camera"):
        PS.psm_map(SPOT, camera, 1.0, 9.0, PL.frustum_corners(camera, 1.0, 9.0), BOX_LO, BOX_HI, 512)


def test_psm_plan_falls_back_to_sm_with_an_ortho_camera():
    camera = _ortho()
    positions, hit = _samples(camera, seed=4, depth_range=(3.0, 6.0))
    plan = PL.plan_projective(SPOT, "psm", camera, SS.measure(camera, SPOT, positions, hit), BOX_LO, BOX_HI, 512)
    assert plan.parameterization == "sm" and plan.requested == "psm"
    assert plan.projective is not None and plan.projective.pps_light == "world"
    shifted = PL.plan_projective(SPOT, "psm", _shifted(), SS.measure(_shifted(), SPOT, *_samples(_shifted(), seed=4, depth_range=(3.0, 6.0))), BOX_LO, BOX_HI, 512)
    assert shifted.parameterization == "psm"


# ---------------------------------------------------------------- builder and reference data
def test_builder_shift_and_ortho():
    cam = _built_camera(fov_deg=60.0, shift=(0.25, 0.0))
    l, r, b, t = cam.window
    half = math.tan(math.radians(30.0))
    assert (r - l) / 2 == pytest.approx(half) and (l + r) / 2 == pytest.approx(0.25 * 2 * half)
    assert (b, t) == pytest.approx((-half * 0.75, half * 0.75)) and cam.fov_deg == pytest.approx(60.0)
    ortho = _built_camera(ortho_scale=4.0)
    assert ortho.ortho and ortho.window == pytest.approx((-2.0, 2.0, -1.5, 1.5))


def _reference(**camera_fields) -> ReferenceData:
    w, h = 8, 6
    return ReferenceData(position=np.zeros((h, w, 3)), normal=np.zeros((h, w, 3)), hit=np.zeros((h, w), bool),
                         shadowed=np.zeros((h, w)), unshadowed=np.zeros((h, w)), triangles=np.zeros((0, 3, 3)),
                         light_matrix=np.eye(4), emission="omni", camera_matrix=look_at(EYE, TARGET),
                         camera_fov_deg=57.0, resolution=(w, h), **camera_fields)


def test_reference_camera_old_file_is_the_centred_camera(tmp_path):
    """A file without the camera fields (written before them) gives the camera it gave before."""
    path = _reference().save(tmp_path / "old.npz")
    with np.load(path, allow_pickle=False) as npz:
        assert not {"camera_window", "camera_ortho", "camera_clip"} & set(npz.files)
    camera = ReferenceData.load(path).camera()
    before = CameraSpec(look_at(EYE, TARGET), 57.0, (8, 6))
    assert camera.window is None and (camera.clip_start, camera.clip_end) == (before.clip_start, before.clip_end)
    assert np.array_equal(PL.frustum_corners(camera, 1.0, 5.0), PL.frustum_corners(before, 1.0, 5.0))
    assert np.array_equal(camera.projection(), before.projection())


def test_reference_camera_fields_round_trip(tmp_path):
    window = (-1.5, 2.5, -1.0, 2.0)
    ref = _reference(camera_window=window, camera_ortho=True, camera_clip=(0.2, 80.0))
    back = ReferenceData.load(ref.save(tmp_path / "new.npz"))
    camera = back.camera()
    assert camera.ortho and camera.window == window and (camera.clip_start, camera.clip_end) == (0.2, 80.0)
    assert camera.resolution == (8, 6)
