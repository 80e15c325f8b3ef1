"""The GL calls the moderngl device makes through ctypes (render/backends/moderngl/gl_calls.py): they resolve
on EGL, a wait through them lets the GIL go, and a timer query is read as 64 bits (moderngl
reads 32 and Mesa clamps there: stages past 4,295 ms all reported about that, issue 53)."""
from __future__ import annotations

import threading
import time

import pytest

from addon.render.backends.moderngl import gl_calls as gl_calls_module
from addon.render.backends.moderngl.gl_calls import gl_calls

pytestmark = pytest.mark.gl


def test_the_calls_resolve_on_egl(gl_backend):
    assert gl_calls() is not None


def test_a_wait_lets_the_gil_go(gl_backend):
    """While the main thread waits in finish() on queued work, another Python thread runs
    (a moderngl wait would hold it off until the work is done)."""
    ticks: list[float] = []
    stop = threading.Event()

    def tick() -> None:
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    device = gl_backend.device
    with device.bound():
        texture = device.ctx.texture((4096, 4096), 4, dtype="f4")
        target = device.ctx.framebuffer([texture])
    thread = threading.Thread(target=tick)
    thread.start()
    try:
        with device.bound():
            target.use()
            for k in range(160):  # a good part of a second of fill on llvmpipe
                device.ctx.clear(k / 40, 0.0, 0.0, 1.0)
            start = time.perf_counter()
            device.finish()
            end = time.perf_counter()
    finally:
        stop.set()
        thread.join()
        with device.bound():
            target.release()
            texture.release()
    inside = [t for t in ticks if start < t < end]
    assert end - start > 0.03, end - start  # the wait was a real one
    assert len(inside) >= 5, (len(inside), end - start)  # a held GIL lets one tick in at most


def test_our_timer_measures_within_the_wall_time(gl_backend):
    """Our query around GPU work (warmed up: llvmpipe's first query of a context can read
    its whole uptime) reads a positive time no longer than the wall time around it."""
    device = gl_backend.device
    calls = gl_calls()
    with device.bound():
        ctx = device.ctx
        name = calls.new_timer()
        try:
            readings = []
            for _ in range(4):
                start = time.perf_counter_ns()
                calls.begin_timer(name)
                ctx.clear(0.3, 0.2, 0.1, 1.0)
                calls.end_timer()
                elapsed = calls.elapsed_ns(name)
                readings.append((elapsed, time.perf_counter_ns() - start))
        finally:
            calls.delete(name)
    for elapsed, wall in readings[1:]:
        assert 0 < elapsed <= wall, readings


def test_the_device_timer_keeps_all_64_bits(gl_backend, monkeypatch):
    """A stage of 2^33 ns reads as 8,590 ms (a 32-bit read would clamp it to 4,295)."""
    real = gl_calls()
    fake = gl_calls_module.GLCalls(real.finish, real.gen_queries, real.delete_queries, real.begin_query,
                                   real.end_query, lambda name, pname, out: setattr(out._obj, "value", 2 ** 33))
    monkeypatch.setattr(gl_calls_module, "_RESOLVED", fake)
    device = gl_backend.device
    device._queries.pop("probe64", None)
    timer = device.timer("probe64")
    with timer:
        pass
    assert timer.elapsed_ms == pytest.approx(2 ** 33 * 1e-6)
    device._queries.pop("probe64")
