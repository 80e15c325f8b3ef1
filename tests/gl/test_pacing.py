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
    chosen = [ShadowSettings("dpsm", 256, warp="notw", exact=True, exact_samples=16),
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
