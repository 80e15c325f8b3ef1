"""Long draws in slices a signal can end between (render/pacing.py, issue 52): the slices
cover every item once and in order, grow by at most GROWTH, are drawn whole where no
signal is watched or the draw fits one slice; a sliced frame writes the very bits of an
unsliced one; a signal that comes during a slice ends the draw after that slice."""
from __future__ import annotations

import contextlib
import os
import signal

import numpy as np
import pytest

from addon.core import interrupt
from addon.core.errors import Interrupted
from addon.render import pacing
from addon.render.frame import ShadowSettings, settings_for
from addon.render.pacing import Pacer
from addon.render.pipeline import ShadowPipeline
from tests.gl.test_soft_filter import _scene
from tests.support.oracle import view_samples


class _Clock:
    """A clock that moves `per_item` seconds a drawn item."""

    def __init__(self, per_item: float) -> None:
        self.now = 0.0
        self.per_item = per_item

    def __call__(self) -> float:
        return self.now


def _recorder(clock: _Clock | None = None):
    """A draw that records each (first, count) it is given and moves `clock` by its items."""
    drawn: list[tuple[int, int]] = []

    def draw(first: int, count: int) -> None:
        drawn.append((first, count))
        if clock is not None:
            clock.now += count * clock.per_item

    return drawn, draw


def _run(pacer: Pacer, total: int, clock: _Clock | None = None, key: str = "exact") -> list[tuple[int, int]]:
    drawn, draw = _recorder(clock)
    pacer.run(key, total, draw, lambda: None)
    return drawn


def test_whole_when_no_signal_is_watched():
    assert _run(Pacer(), 10 ** 6) == [(0, 10 ** 6)]


def test_slices_cover_the_pass_in_order_and_take_about_the_slice():
    clock = _Clock(per_item=1e-5)  # 100k items a second: 20k a 0.2 s slice
    pacer = Pacer(clock=clock)
    with interrupt.handling():
        drawn = _run(pacer, 200_000, clock)
    starts = [first for first, _ in drawn]
    assert starts == sorted(starts) and starts[0] == 0
    assert all(a + n == b for (a, n), (b, _) in zip(drawn, drawn[1:]))
    assert sum(n for _, n in drawn) == 200_000
    assert drawn[0][1] == pacing.FIRST_SLICE
    assert all(n <= GROWTH_LIMIT * m for (_, m), (_, n) in zip(drawn, drawn[1:-1]))
    assert max(n for _, n in drawn) * clock.per_item <= pacing.SLICE_S * 1.001
    assert pacer.slices == len(drawn)
    # The rate is known now: a pass that fits one slice is drawn whole, without a wait.
    with interrupt.handling():
        assert _run(pacer, 15_000, clock) == [(0, 15_000)]
        first = _run(pacer, 40_000, clock)[0]  # a longer one starts at the slice
        assert first[0] == 0 and abs(first[1] - 20_000) <= 1


GROWTH_LIMIT = pacing.GROWTH


def test_a_signal_during_a_slice_ends_the_pass_after_it():
    drawn: list[tuple[int, int]] = []

    def draw(first: int, count: int) -> None:
        drawn.append((first, count))
        if len(drawn) == 2:
            os.kill(os.getpid(), signal.SIGINT)

    with interrupt.handling():
        with pytest.raises(Interrupted):
            Pacer().run("exact", 10 ** 6, draw, lambda: None)
    assert len(drawn) == 2
    assert sum(n for _, n in drawn) < 10 ** 6


def _frames(backend, method_settings):
    """Visibility and exact work of each frame, drawn whole and then in slices of 2 items."""
    scene = _scene("area")
    samples, _, _ = view_samples(scene)
    out = []
    for sliced in (False, True):
        backend.pacer = Pacer()
        first, grow = pacing.FIRST_SLICE, pacing.SLICE_S
        try:
            if sliced:  # 2 items a slice (the rate gives none more): every draw cut in many
                pacing.FIRST_SLICE, pacing.SLICE_S = 2, 1e-9
            # Whole: no signal watched (as in Blender's UI); sliced: as in a command.
            with interrupt.handling() if sliced else contextlib.nullcontext():
                frames = []
                for settings in method_settings:
                    result = ShadowPipeline(backend).render(scene.light, scene.world_triangles(), samples, settings)
                    frames.append((result.visibility.tobytes(), result.exact_work))
        finally:
            pacing.FIRST_SLICE, pacing.SLICE_S = first, grow
        out.append((frames, backend.pacer.slices))
    return out


@pytest.mark.gl
def test_a_sliced_frame_writes_the_same_bits(gl_backend):
    """The exact pass of a sized light (its lists, its walks, its counters) and a map pass,
    whole and cut into slices of 2 triangles: the same visibility, the same work."""
    chosen = [ShadowSettings("dpsm", 256, warp="notw", exact=True, exact_samples=16, exact_segments=False),
              settings_for("dpsm+notw", 256)]
    (whole, whole_slices), (sliced, sliced_slices) = _frames(gl_backend, chosen)
    assert whole_slices == 0
    assert sliced_slices > 4
    for (bits_a, work_a), (bits_b, work_b) in zip(whole, sliced):
        assert bits_a == bits_b
        assert work_a == work_b
    assert np.frombuffer(whole[0][0], np.float32).min() < 0.5  # the frame has shadows to keep


def test_stepping_yields_between_slices_and_after_short_draws_that_add_up():
    """The viewport's mode: no signal watched, yet a long draw is cut (into STEP_S slices)
    with a yield after each; short draws drawn whole yield once their estimated time adds
    up to a slice; `pause` yields only while stepping; `drive` runs a stepped pass whole."""
    from addon.render.pacing import drive

    clock = _Clock(per_item=1e-5)
    pacer = Pacer(clock=clock, stepping=True)
    drawn, draw = _recorder(clock)
    steps = pacer.steps("step:maps:a", 100_000, draw, lambda: None)
    yields = sum(1 for _ in steps)
    assert yields == len(drawn) > 5 and sum(n for _, n in drawn) == 100_000
    assert max(n for _, n in drawn[1:]) <= 2 * max(n for _, n in drawn[:-1])  # STEP_GROWTH
    assert max(n for _, n in drawn) * clock.per_item <= pacing.STEP_S * 1.001
    # The rate is known: draws of a tenth of a slice each go whole, one yield every ten or so.
    small = int(pacing.STEP_S / clock.per_item / 10)
    yields = sum(sum(1 for _ in pacer.steps("step:maps:a", small, draw, lambda: None)) for _ in range(30))
    assert 2 <= yields <= 4, yields
    assert list(pacer.pause()) == [None]
    pacer.stepping = False
    assert list(pacer.pause()) == []
    assert drive(iter_value(7)) == 7


def iter_value(value: int):
    yield None
    yield None
    return value


def test_a_stepped_slice_ends_by_the_redraws_deadline():
    """A redraw going on with a spread frame gives it a deadline: each slice is sized to end
    by it (the last slice of a redraw held it past its budget before), never below
    MIN_STEP_S of work; without a deadline slices take STEP_S."""
    clock = _Clock(per_item=1e-5)  # 100k items a second: STEP_S is 2,000 items
    pacer = Pacer(clock=clock, stepping=True)
    drawn, draw = _recorder(clock)
    steps = pacer.steps("step:maps:a", 100_000, draw, lambda: None)
    for _ in range(8):  # the rate learnt, slices of STEP_S
        next(steps)
    assert drawn[-1][1] * clock.per_item == pytest.approx(pacing.STEP_S, rel=0.01)
    pacer.deadline = clock.now + 0.005  # 5 ms left of this redraw
    next(steps)
    assert drawn[-1][1] * clock.per_item == pytest.approx(0.005, rel=0.01)
    next(steps)  # the deadline passed: the least slice
    assert drawn[-1][1] * clock.per_item == pytest.approx(pacing.MIN_STEP_S, rel=0.01)
    pacer.deadline = None
    for _ in range(5):  # growth is capped (STEP_GROWTH) after a small slice, then STEP_S again
        next(steps)
    sizes = [n for _, n in drawn[-6:]]
    assert all(b <= pacing.STEP_GROWTH * a for a, b in zip(sizes, sizes[1:])), sizes
    assert drawn[-1][1] * clock.per_item == pytest.approx(pacing.STEP_S, rel=0.01)


def test_a_run_borrows_its_objects_rate_until_its_first_slice_measures_its_own():
    """Stepping, a run (key) with no rate of its own takes its object's (fallback) to size
    its first slice, and is sliced even where that rate says it would fit one: its own rate,
    measured on that slice, then sizes it and its object's next runs."""
    clock = _Clock(per_item=1e-5)  # this run: 100k items a second
    pacer = Pacer(clock=clock, stepping=True, rates={"step:maps:obj": 1e6})  # its object's: 1M/s
    drawn, draw = _recorder(clock)
    total = int(1e6 * pacing.STEP_S * 0.8)  # "fits" a slice on the borrowed rate
    steps = pacer.steps("step:maps:obj:0:500", total, draw, lambda: None, fallback="step:maps:obj")
    next(steps)
    # Sliced on the borrowed rate (what it foretells for STEP_S), not drawn whole.
    assert drawn == [(0, total)]
    assert pacer.rates["step:maps:obj:0:500"] == pytest.approx(1e5) == pacer.rates["step:maps:obj"]
    # The next run of the object is sized by the rate just measured.
    drawn, draw = _recorder(clock)
    steps = pacer.steps("step:maps:obj:0:900", 100_000, draw, lambda: None, fallback="step:maps:obj")
    next(steps)
    assert drawn[0][1] * clock.per_item == pytest.approx(pacing.STEP_S, rel=0.01)
    list(steps)
    assert sum(n for _, n in drawn) == 100_000
    assert max(n for _, n in drawn[1:]) * clock.per_item <= pacing.STEP_S * 1.001
    # Not stepping, the borrowed rate decides as before: no signal watched, drawn whole.
    idle = Pacer(clock=clock, rates={"step:maps:obj": 1e6})
    drawn, draw = _recorder(clock)
    list(idle.steps("step:maps:obj:0:900", 10_000, draw, lambda: None, fallback="step:maps:obj"))
    assert drawn == [(0, 10_000)]


def test_draws_queued_whole_learn_their_rates_from_the_wait_they_share():
    """Short draws drawn whole on known rates (each foretold at a tenth of a slice) that took
    three times as long together: the wait after them scales each one's rate by a third;
    `settle` waits for what is queued and yields while stepping, and does nothing otherwise."""
    clock = _Clock(per_item=3e-5)  # they are three times dearer than their rates say
    keys = [f"step:maps:obj:0:{i}" for i in range(12)]
    pacer = Pacer(clock=clock, stepping=True, rates={key: 1e5 for key in keys})
    small = int(pacing.STEP_S * 1e5 / 10)
    waits = []
    for key in keys[:5]:
        drawn, draw = _recorder(clock)
        list(pacer.steps(key, small, draw, lambda: waits.append(clock.now)))
    assert waits == []  # five tenths of a slice foretold: no wait yet
    assert all(pacer.rates[key] == 1e5 for key in keys[:5])
    assert list(pacer.settle(lambda: waits.append(clock.now))) == [None] and len(waits) == 1
    assert all(pacer.rates[key] == pytest.approx(1e5 / 3, rel=1e-6) for key in keys[:5])
    assert pacer.queued == [] and pacer.owed == 0.0
    pacer.stepping = False
    assert list(pacer.settle(lambda: waits.append(clock.now))) == [] and len(waits) == 1


def test_a_stepped_ray_table_is_the_table_of_one_draw(gl_backend, monkeypatch):
    """The ray table built in bands of rows (stepping, each band a slice of its own) holds
    the very bits of the one draw that builds it otherwise."""
    from addon.render.backend import ShadowBackend
    from addon.render.passes import footprints

    calls = []

    def recording(backend, tile, uniforms):
        calls.append((tile, dict(uniforms)))
        return footprints.build_ray_table_steps(backend, tile, uniforms)

    monkeypatch.setattr(ShadowBackend, "build_ray_table_steps", recording)
    scene = _scene("sphere")
    samples, _, _ = view_samples(scene)
    ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples, settings_for("dpsm+notw", 256))
    assert calls, "a warped frame builds its ray table"
    tile, uniforms = calls[0]
    rows = gl_backend.atlas.layout.resolution

    def table() -> np.ndarray:
        return gl_backend.device.read(gl_backend.textures["ow_ray_table"], "RG32F").copy()

    with gl_backend.device.bound():
        pacing.drive(footprints.build_ray_table_steps(gl_backend, tile, uniforms))
        once = table()
        gl_backend.device.clear(gl_backend.ray_target, (0.0, 0.0, 0.0, 0.0))
        gl_backend.pacer.stepping = True
        try:
            yields = sum(1 for _ in footprints.build_ray_table_steps(gl_backend, tile, uniforms))
        finally:
            gl_backend.pacer.stepping = False
        banded = table()
    assert yields >= rows // footprints.RAY_BAND  # a band a slice at least
    x, y, width, height = gl_backend.atlas.layout.span_viewport(tile, 1)
    once, banded = once[y:y + height, x:x + width], banded[y:y + height, x:x + width]
    assert np.array_equal(once.view(np.uint32), banded.view(np.uint32))
    assert np.isfinite(once).all() and np.ptp(once) > 0.0  # a table with something in it
