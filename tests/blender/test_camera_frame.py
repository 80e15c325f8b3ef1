"""Cameras as the file has them: numpy windows against Blender's own camera, and Cycles.

Blender is the oracle here: `Camera.view_frame(scene=...)` gives the image corners in
camera space, `Object.calc_matrix_camera` the projection matrix, and a Cycles capture
gives per-pixel positions, which must project back (through the reference's
CameraSpec) onto their own pixel centres. Captures are 2 renders of a tiny scene each.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from mathutils import Matrix  # noqa: E402

from addon.core.camera import CameraSpec, blender_camera_window  # noqa: E402
from addon.core.scene import SceneBuilder, look_at  # noqa: E402
from addon.reference import capture as CAP  # noqa: E402
from addon.reference.blender_scene import build_blender_scene, remove_blender_scene  # noqa: E402
from tests.support.checks import expect  # noqa: E402
from tests.support.cli_run import run_python  # noqa: E402
from tests.support.oracle import ray_hits  # noqa: E402

pytestmark = pytest.mark.blender

WORKER = Path(__file__).resolve().parents[1] / "support" / "camera_gbuffer_worker.py"

# name -> camera data and render settings (resolution before the percentage).
CASES = {
    "centred": dict(),
    "shifted": dict(shift=(0.3, -0.2)),
    "vertical_portrait_aspect_half": dict(fit="VERTICAL", res=(96, 128), pct=50, aspect=(2.0, 1.0),
                                          sensor=(30.0, 20.0), lens=40.0, shift=(0.1, 0.05)),
    "horizontal_portrait": dict(fit="HORIZONTAL", res=(48, 64), shift=(0.0, 0.25)),
    "auto_portrait_tall_pixels": dict(res=(64, 48), aspect=(1.0, 3.0)),
    "ortho_shifted": dict(type="ORTHO", scale=7.0, shift=(0.2, 0.1)),
    "ortho_vertical_portrait": dict(type="ORTHO", fit="VERTICAL", res=(40, 80), aspect=(1.0, 3.0), scale=5.0),
}


def _set_camera(scene, type="PERSP", fit="AUTO", res=(64, 48), pct=100, aspect=(1.0, 1.0), sensor=(36.0, 24.0),
                lens=35.0, scale=6.0, shift=(0.0, 0.0), look=None) -> tuple[int, int]:
    """Set the scene camera (and, with `look` = (eye, target), where it is) and the render
    size; returns the rendered pixel size."""
    if look is not None:
        scene.camera.matrix_world = Matrix(look_at(*look).tolist())
    cam = scene.camera.data
    cam.type, cam.sensor_fit = type, fit
    cam.sensor_width, cam.sensor_height = sensor
    cam.lens, cam.ortho_scale = lens, scale
    cam.shift_x, cam.shift_y = shift
    r = scene.render
    r.resolution_x, r.resolution_y = res
    r.resolution_percentage = pct
    r.pixel_aspect_x, r.pixel_aspect_y = aspect
    return res[0] * pct // 100, res[1] * pct // 100


def _floor_box(size=(64, 48)):
    b = SceneBuilder("camframe", size)
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    b.box("box", (0.0, 0.0, 1.0), (1.0, 1.0, 1.0))
    b.box("pillar", (1.8, 1.2, 0.75), (0.4, 0.4, 1.5))
    b.point_light((0.5, 0.3, 4.0))
    b.camera((0.0, -7.0, 5.0), (0.0, 0.0, 0.3), fov_deg=60.0, clip_start=0.1, clip_end=60.0)
    return b.finish()


@pytest.fixture()
def scene():
    built = build_blender_scene(_floor_box())
    yield built
    remove_blender_scene(built)


def _spec_of(scene, width: int, height: int) -> CameraSpec:
    """The CameraSpec the capture stores for this camera (capture's own camera code)."""
    cam = scene.camera.data
    window = CAP._camera_window(cam, scene.render, width, height)
    matrix = np.array(scene.camera.matrix_world, dtype=np.float64)
    if window is None:
        return CameraSpec(matrix, CAP._camera_fov_deg(cam, width, height), (width, height), cam.clip_start,
                          cam.clip_end)
    return CameraSpec.from_window(matrix, window, (width, height), cam.clip_start, cam.clip_end,
                                  ortho=cam.type == "ORTHO")


def _blender_extents(scene) -> tuple[float, float, float, float]:
    """(left, right, bottom, top) from view_frame: tangents (perspective) or scene units."""
    frame = np.array([tuple(v) for v in scene.camera.data.view_frame(scene=scene)])
    xy = frame[:, :2] if scene.camera.data.type == "ORTHO" else frame[:, :2] / -frame[:, 2:]
    return xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()


@pytest.mark.parametrize("case", list(CASES))
def test_window_and_projection_match_blender(scene, case):
    width, height = _set_camera(scene, **CASES[case])
    spec = _spec_of(scene, width, height)
    assert (spec.window is None) == (case == "centred")
    np.testing.assert_allclose(spec.frame_extents(), _blender_extents(scene), rtol=1e-5, atol=1e-6)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    r = scene.render
    blender = np.array(scene.camera.calc_matrix_camera(depsgraph, x=width, y=height, scale_x=r.pixel_aspect_x,
                                                       scale_y=r.pixel_aspect_y))
    ours = spec.projection()
    np.testing.assert_allclose(ours, blender, rtol=1e-5, atol=1e-5 * np.abs(blender).max())


def test_windowed_spec_builds_the_same_blender_camera():
    """build_blender_scene turns a windowed CameraSpec (shift, ortho) into the Blender camera
    whose frame is that window."""
    for kwargs in (dict(shift=(0.25, -0.1)), dict(ortho_scale=6.0, shift=(0.0, 0.2))):
        b = SceneBuilder("camspec", (48, 64))
        b.plane("floor", (0.0, 0.0, 0.0), 4.0, 4.0)
        b.point_light((0.0, 0.0, 3.0))
        b.camera((0.0, -5.0, 2.0), (0.0, 0.0, 0.0), fov_deg=50.0, **kwargs)
        spec = b.finish()
        built = build_blender_scene(spec)
        try:
            np.testing.assert_allclose(_blender_extents(built), spec.camera.window, rtol=1e-5, atol=1e-6)
            assert _spec_of(built, 48, 64).window == pytest.approx(spec.camera.window, rel=1e-5, abs=1e-6)
        finally:
            remove_blender_scene(built)


def test_panoramic_camera_is_refused(scene):
    scene.camera.data.type = "PANO"
    with pytest.raises(CAP.ReferenceCaptureError, match="perspective or orthographic"):
        CAP.capture(scene)


# ------------------------------------------------------------------ Cycles end to end
E2E = {
    "shifted": dict(shift=(0.3, -0.15)),
    "vertical_portrait_aspect_half": dict(fit="VERTICAL", res=(96, 128), pct=50, aspect=(2.0, 1.0), lens=28.0),
    # Close by and looking past the box and the pillar: their -x faces are seen although
    # the camera's location is on their far side, so an eye-point normal rule flips them
    # (measured: 1.1 % of the hit pixels), where Cycles' ray-direction rule does not.
    "ortho": dict(type="ORTHO", scale=9.0, shift=(0.1, 0.05), look=((2.5, -2.5, 2.5), (3.5, 1.0, 0.0))),
}


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    """The three Cycles references, saved (for the G-buffer worker) and loaded back."""
    folder = tmp_path_factory.mktemp("camera_refs")
    out = {}
    for name, settings in E2E.items():
        built = build_blender_scene(_floor_box())
        try:
            size = _set_camera(built, **settings)
            ref = CAP.capture(built)
        finally:
            remove_blender_scene(built)
        assert ref.resolution == size and ref.hit.any() and not ref.hit.all()
        out[name] = (ref, ref.save(folder / f"{name}.npz"))
    return out


@pytest.mark.parametrize("name", list(E2E))
def test_cycles_positions_project_to_their_pixel_centres(captures, name):
    ref, path = captures[name]
    camera = type(ref).load(path).camera()  # through the saved file, as compare reads it
    assert camera.window is not None and camera.ortho == (name == "ortho")
    rows, cols = np.nonzero(ref.hit)
    pixel = camera.pixel_of(ref.position[ref.hit].astype(np.float64))
    err = np.abs(pixel - np.stack([cols + 0.5, rows + 0.5], axis=-1))
    assert err.max() < 0.05, (name, err.max())
    # The numpy rays through the pixel centres hit what Cycles hit (only edge-grazing pixels differ).
    origins, dirs = camera.pixel_rays()
    t, _ = ray_hits(origins.reshape(-1, 3), dirs.reshape(-1, 3), ref.triangles.astype(np.float64))
    assert np.count_nonzero(np.isfinite(t).reshape(ref.hit.shape) != ref.hit) <= 2


def test_preview_gbuffer_matches_cycles_pixels(captures, tmp_path):
    """The headless preview's G-buffer (camera.projection() @ view, normals towards
    camera.eye_homogeneous()) sees what Cycles saw, for each windowed camera; and the
    viewport's compute path on those matrices gets a camera (culling runs) whose culled
    cube faces change no shadow."""
    out = tmp_path / "gbuffer.json"
    proc = run_python(WORKER, out, *(p for _, p in captures.values()), timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(out.read_text())
    for name in E2E:
        r = report[name]
        assert r["hit_agreement"] > 0.99 and r["both"] > 500, (name, r)
        assert r["position_p99"] < 0.05, (name, r)
        assert r["normal_agreement"] > 0.995, (name, r)
        expect(r, "viewport_frustum", "viewport_same_shadows", camera=name)
        assert r["viewport_faces_unculled"] == 6 and r["viewport_faces_drawn"] <= 6, (name, r)
    assert report["shifted"]["viewport_faces_drawn"] < 6  # the shifted view's culling leaves a face out


def test_blender_window_helper_is_what_capture_uses(scene):
    """capture._camera_window is blender_camera_window on the camera's own fields."""
    width, height = _set_camera(scene, **CASES["vertical_portrait_aspect_half"])
    cam = scene.camera.data
    expected = blender_camera_window((width, height), lens=cam.lens, sensor_fit="VERTICAL",
                                     sensor_width=cam.sensor_width, sensor_height=cam.sensor_height,
                                     shift=(cam.shift_x, cam.shift_y), pixel_aspect=(2.0, 1.0))
    assert CAP._camera_window(cam, scene.render, width, height) == pytest.approx(expected)
