"""A steady frame's traffic between host and GPU (issue 41), counted at moderngl's API
(tests/support/traffic.py): the frame does not wait for its result, and the methods whose
plan the GPU reduces to a few numbers wait once, for those numbers."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.presets import build_preset
from addon.render.pipeline import ShadowPipeline, ShadowSettings, ViewSamples, settings_for
from addon.render.frame import Measure
from scripts.frame_traffic import steady_traffic
from tests.support.oracle import view_samples
from tests.support.traffic import Traffic

pytestmark = pytest.mark.gl

# Issue 41's bounds for a steady frame.
MAX_WAITS = 1
MAX_READ_BYTES = 4096
MAX_UPLOAD_BYTES = 64 * 1024


def _assert_bounds(traffic: Traffic) -> None:
    """Issue 41's bounds on one steady frame's traffic."""
    assert traffic.finishes == 0, traffic.calls
    assert traffic.waits <= MAX_WAITS, traffic.calls
    assert traffic.read_bytes <= MAX_READ_BYTES, traffic.calls
    assert traffic.upload_bytes <= MAX_UPLOAD_BYTES, traffic.calls


@pytest.fixture(scope="module")
def case():
    scene = build_preset("room_omni", (64, 48))
    samples, _, _ = view_samples(scene)
    arrays = [np.array(a) for a in (samples.positions, samples.normals, samples.hit)]
    for array in arrays:
        array.flags.writeable = False  # read-only: they stay on the GPU (frame.resident_samples_key)
    return scene, ViewSamples(*arrays, samples.camera)


@pytest.mark.parametrize("method", ["dpsm", "cube", "exact"])
def test_a_steady_frame_waits_once_and_uploads_nothing(gl_backend, case, method):
    scene, samples = case
    pipeline = ShadowPipeline(gl_backend)
    triangles = scene.world_triangles()
    triangles.flags.writeable = False  # the same read-only array: resident across frames
    settings = settings_for(method, 256, scene.light.emission)
    try:
        traffic = steady_traffic(pipeline, scene.light, triangles, samples, settings)
    finally:
        pipeline.release()
    _assert_bounds(traffic)


def test_the_result_is_read_when_first_asked_for_and_equals_a_synced_frame(gl_backend, case):
    """The frame's visibility stays on the GPU until read; reading it then gives what a
    measuring frame (a wait after each stage) gives, and a second frame's start reads an
    earlier result still unread."""
    scene, samples = case
    pipeline = ShadowPipeline(gl_backend)
    triangles = scene.world_triangles()
    settings = ShadowSettings("dpsm", 256, warp="notw")
    try:
        synced = pipeline.render(scene.light, triangles, samples, settings, measure=Measure(sync_stages=True)).visibility
        first = pipeline.render(scene.light, triangles, samples, settings)
        assert first.pending
        traffic = Traffic()
        with traffic.counting():
            visibility = first.visibility
        assert not first.pending and traffic.reads >= 1
        assert np.array_equal(visibility, synced)
        unread = pipeline.render(scene.light, triangles, samples, settings)
        pipeline.render(scene.light, triangles, samples, ShadowSettings("cube", 256))
        assert not unread.pending  # read before the cube frame overwrote its target
        assert np.array_equal(unread.visibility, synced)
    finally:
        pipeline.release()


def test_gpu_stage_times_come_with_the_result_and_survive_release(case):
    """moderngl times each GPU stage with a timer query; a result left unread when its
    backend is released was read first, so it still holds its visibility and times. (A new
    context's first frame may have none: llvmpipe's first queries read 2^32 - 1 ns, which
    stage_clock refuses.)"""
    from addon.render.backends.moderngl.backend import ModernGLBackend

    scene, samples = case
    with ModernGLBackend() as backend:
        pipeline = ShadowPipeline(backend)
        settings = ShadowSettings("dpsm", 256, warp="notw")
        _ = pipeline.render(scene.light, scene.world_triangles(), samples, settings).visibility
        result = pipeline.render(scene.light, scene.world_triangles(), samples, settings)
        assert result.pending
    assert not result.pending
    gpu = result.gpu_ms
    assert set(gpu) == {"analysis", "shadow_maps", "shadow_test", "total"}
    assert all(np.isfinite(v) and v >= 0.0 for v in gpu.values())
    assert gpu["total"] == pytest.approx(gpu["analysis"] + gpu["shadow_maps"] + gpu["shadow_test"])
    assert result.visibility.shape == samples.hit.shape


@pytest.mark.parametrize("method", ["dpsm+notw", "exact"])
def test_the_visibility_drawn_into_a_texture_is_the_frames_and_nothing_is_read(gl_backend, case, method):
    """visibility_into draws the latest frame's visibility and flags (the exact pass's marks
    applied) into a texture a compositor samples; after `discard` nothing of the frame is
    read back, and its visibility is refused with a clear error."""
    from addon.core.errors import BackendError

    scene, samples = case
    pipeline = ShadowPipeline(gl_backend)
    device = gl_backend.device
    settings = settings_for(method, 256, scene.light.emission)
    triangles = scene.world_triangles()
    triangles.flags.writeable = False  # resident, as the viewport's are
    height, width = samples.hit.shape
    texture = device.texture((width, height), "RG32F")
    target = device.target((texture,))
    try:
        expected = pipeline.render(scene.light, triangles, samples, settings)
        expected_vis, expected_flags = expected.visibility, expected.flags
        result = pipeline.render(scene.light, triangles, samples, settings)
        with pytest.raises(BackendError):
            pipeline.visibility_into(expected, target)  # not the latest frame
        traffic = Traffic()
        with traffic.counting():
            pipeline.visibility_into(result, target)
            result.discard()
            gl_backend.settle()  # what the next frame does first: nothing left to read
        # At most the one texel that stands in for the marks, made once; exact reads its
        # pass's counters (whether its lists need later rounds) before the marks are drawn.
        assert traffic.reads == (1 if method == "exact" else 0), traffic.calls
        assert traffic.read_bytes <= MAX_READ_BYTES and traffic.upload_bytes <= 4, traffic.calls
        drawn = device.read(texture, "RG32F")[::-1]
        assert np.array_equal(drawn[..., 0], expected_vis)
        assert np.array_equal(drawn[..., 1].astype(np.int8), expected_flags)
        with pytest.raises(BackendError, match="discarded"):
            _ = result.visibility
    finally:
        device.free(target, texture)
        pipeline.release()


def _media_scene(scene):
    """The room with a fog box (a homogeneous medium) round its middle and a density grid
    (8 voxels a side) by the light: both resident (issue 43)."""
    from addon.core.alpha import Surface
    from addon.core.media import GridMedium, Medium
    from addon.core.scene import SceneBuilder
    from addon.render.resident import ResidentScene

    triangles = scene.world_triangles()
    lo, hi = triangles.reshape(-1, 3).min(axis=0), triangles.reshape(-1, 3).max(axis=0)
    box = SceneBuilder("fog", (8, 8))
    box.box("fog", tuple(0.5 * (lo + hi)), tuple(0.4 * (hi - lo)))
    box.point_light(tuple(hi + 1.0))
    box.camera(tuple(hi + 2.0), tuple(lo), fov_deg=60.0)
    fog = box.finish().world_triangles()
    resident = ResidentScene()
    resident.set_geometry("room", triangles)
    resident.set_geometry("fog", fog, surface=Surface.opaque(len(fog)).with_media(
        np.zeros(len(fog), np.int32), (Medium("fog", 0.8),)))
    to_world = np.diag([*(0.05 * (hi - lo)), 1.0])
    to_world[:3, 3] = np.asarray(scene.light.position) - 0.2 * (hi - lo)
    resident.set_grid("cloud", GridMedium("cloud", 1.5, np.ones((8, 8, 8), np.float32), np.linalg.inv(to_world)))
    return resident


@pytest.mark.parametrize("method", ["dpsm+notw", "cube", "exact"])
def test_a_steady_frame_with_media_keeps_the_bounds(gl_backend, case, method):
    """A medium and a grid add resident words and a texture, not traffic: the steady frame
    keeps issue 41's bounds, and the media do darken it (issue 43)."""
    scene, samples = case
    pipeline = ShadowPipeline(gl_backend)
    settings = settings_for(method, 256, scene.light.emission)
    resident = _media_scene(scene)
    try:
        traffic = steady_traffic(pipeline, scene.light, resident, samples, settings)
        with_media = pipeline.render(scene.light, resident, samples, settings).visibility
        clear = pipeline.render(scene.light, scene.world_triangles(), samples, settings).visibility
    finally:
        pipeline.release()
    _assert_bounds(traffic)
    hit = samples.hit
    assert float(with_media[hit].mean()) < float(clear[hit].mean()) - 0.01
