"""The render layer keeps one home per idea (issue 40): each pass is written once over the
device interface, the backends are thin adapters, and no module outgrows a sitting."""
from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np
import pytest

from addon.render import backend as backend_module
from addon.render.backends.blender.backend import BlenderDevice, BlenderGPUBackend
from addon.render.device import Device
from addon.render.backends.moderngl.backend import ModernGLBackend, ModernGLDevice

RENDER = Path(backend_module.__file__).resolve().parent
BACKEND_MODULES = ("backends/moderngl/backend.py", "backends/blender/backend.py")
MAX_BACKEND_LINES = 400
MAX_RENDER_LINES = 500


def _pass_methods() -> set[str]:
    """The public entry points ShadowBackend gives the pipeline (its passes and resources)."""
    return {name for name, value in vars(backend_module.ShadowBackend).items()
            if not name.startswith("_") and callable(value)}


def test_no_pass_is_written_in_a_backend_class():
    passes = _pass_methods()
    assert {"begin_atlas", "draw_layer", "draw_footprints", "link_samples", "advance_lists", "edge_distance",
            "scatter_counts", "reduce_samples", "run_shadow_test", "sync_scene"} <= passes
    for cls in (ModernGLBackend, BlenderGPUBackend):
        # samples_from_gbuffer is the one pass only Blender's GL can run (its G-buffer).
        own = (set(vars(cls)) & passes) - {"samples_from_gbuffer", "release"}
        assert not own, f"{cls.__name__} defines passes of its own: {sorted(own)}"
    both = {name for name in set(vars(ModernGLBackend)) & set(vars(BlenderGPUBackend))
            if not name.startswith("__")} - {"name", "release"}
    assert not both, f"defined in both backend classes: {sorted(both)}"


def test_the_devices_implement_every_primitive():
    for device in (ModernGLDevice, BlenderDevice):
        assert not inspect.isabstract(device), (device.__name__, sorted(device.__abstractmethods__))
        assert issubclass(device, Device)


def test_modules_stay_small_enough_to_read():
    for name in BACKEND_MODULES:
        lines = len((RENDER / name).read_text().splitlines())
        assert lines <= MAX_BACKEND_LINES, f"render/{name} has {lines} lines (at most {MAX_BACKEND_LINES})"
    long = {str(path.relative_to(RENDER)): n for path in RENDER.rglob("*.py")
            if (n := len(path.read_text().splitlines())) > MAX_RENDER_LINES}
    assert not long, f"render modules over {MAX_RENDER_LINES} lines: {long}"


@pytest.mark.gl
def test_moderngl_timer_query_times_gpu_work(gl_backend):
    """The device's timer query (where the API has one) reads a finite, non-negative time."""
    device = gl_backend.device
    texture = device.texture((64, 64), "R32UI")
    try:
        timer = device.timer()
        with timer:
            for _ in range(4):
                device.clear_image(texture)
        assert np.isfinite(timer.elapsed_ms) and timer.elapsed_ms >= 0.0
    finally:
        device.free(texture)


@pytest.mark.gl
def test_a_uint_image_round_trips_through_the_device(gl_backend):
    """clear_image zeroes an R32UI image on the GPU; read gives it back as uint32 rows."""
    device = gl_backend.device
    data = np.arange(12, dtype=np.uint32).reshape(3, 4)
    image = device.texture((4, 3), "R32UI", data)
    try:
        assert np.array_equal(device.read(image, "R32UI"), data)
        device.clear_image(image)
        assert not device.read(image, "R32UI").any()
    finally:
        device.free(image)
