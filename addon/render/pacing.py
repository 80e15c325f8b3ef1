"""Long GPU passes cut into slices that a signal can end between.

A draw call returns at once; the main thread blocks later, in the first call that waits
for the GPU (a barrier, a read), for as long as everything queued takes. Python runs no
signal handler inside that call, and the watchdog thread of core/interrupt.py needs the
GIL the main thread holds, so an `exact` frame of minutes on llvmpipe (hair under a soft
sun) ignored Ctrl-C for minutes. While a command handles signals (`interrupt.watching`),
a pass whose expected time exceeds SLICE_S is drawn in slices of about SLICE_S, each
waited for, with the interrupt looked at after each.

The expected time comes from the pass's rate, items a second, measured on its earlier
slices; a pass with no rate yet starts with FIRST_SLICE items and grows by at most GROWTH
a slice. A pass expected to fit one slice is drawn whole, without a wait, so the
measured repeats of a row (after its warm-up) keep the GPU's queue as it was. Slicing a
draw keeps its primitives in order, so what it writes is the same.

The viewport spreads a long recompute over several redraws: with `stepping`
on, a draw is cut into slices of about STEP_S, each waited for (llvmpipe does a draw's
vertex work in the call itself and its fragments in its threads; the window's swap would
wait for them anyway), and the pass yields after each, so the preview's draw callback can
stop and go on at the next redraw; the redraw's `deadline` cuts a slice shorter when less
than STEP_S is left of it. While stepping a run of an object keeps its own rate, borrowed
from its object (the `fallback` key) until its first slice measures it, and draws queued
whole learn theirs from the wait they share (docs/preview.md has the figures). The passes
are generators for that (`*_steps`); `drive` runs one to its end where nothing steps.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import TypeVar

from ..core import interrupt

SLICE_S = 0.2  # seconds of GPU work between two looks at the interrupt
STEP_S = 0.015  # seconds a slice may take while stepping (the viewport)
FIRST_SLICE = 16  # items of a draw's first slice when its rate is not known yet
GROWTH = 8  # the most a slice grows over the one before it (waiting)
STEP_GROWTH = 2  # the same while stepping: an overshoot is a frozen redraw
MIN_STEP_S = 0.002  # the least a slice is sized for when a redraw's deadline is near
MAX_RATES = 4096  # rates kept (by pass, object, tile and run) before the table starts again

T = TypeVar("T")
Steps = Generator[None, None, T]  # a pass that yields between its slices and returns its value


def drive(steps: "Steps[T]") -> T:
    """Run a stepped pass to its end (nothing stepping); its value. An exception between two
    steps (a signal's, raised at any bytecode) closes it, so that its `with` blocks (a bound
    context) end now and not when the collector finds it, after the context is gone."""
    try:
        while True:
            try:
                next(steps)
            except StopIteration as done:
                return done.value
    finally:
        steps.close()


@dataclass
class Pacer:
    """Rates of the paced passes (items a second, by pass key) and the slices drawn."""

    rates: dict[str, float] = field(default_factory=dict)
    slices: int = 0  # slices drawn with a wait (or, stepping, a yield) after them
    clock: Callable[[], float] = time.perf_counter
    stepping: bool = False  # the viewport spreads this frame over redraws: yield between slices
    owed: float = 0.0  # stepping: seconds of the draws queued whole since the last yield (estimated)
    # Stepping: when the redraw going on with the frame wants it back (a `clock` time). A slice
    # is sized to end by then: the last slice of a redraw was what held it past its budget.
    deadline: float | None = None
    # Stepping: the draws queued whole since the last wait, (key, fallback, items, foretold
    # seconds), and when the first was queued: their wait measures them together.
    queued: list[tuple[str, str | None, int, float]] = field(default_factory=list)
    queued_since: float = 0.0

    def _budget(self) -> float:
        """Seconds a slice may take now: SLICE_S, or while stepping STEP_S cut to the deadline."""
        if not self.stepping:
            return SLICE_S
        if self.deadline is None:
            return STEP_S
        return min(STEP_S, max(self.deadline - self.clock(), MIN_STEP_S))

    def pause(self) -> Steps[None]:
        """Between two stages of a frame: a yield while stepping (the stage after may be long)."""
        if self.stepping:
            self.owed = 0.0
            self.queued.clear()  # what they queued is waited for in the next stage's time
            yield

    def settle(self, wait: Callable[[], None]) -> Steps[None]:
        """At the end of a stepped pass: wait for what it queued whole (measuring those draws'
        rates) and yield, so that the stage after starts on an idle GPU."""
        if self.stepping:
            if self.queued:
                wait()
                self._learn_queued()
            yield

    def run(self, key: str, total: int, draw: Callable[[int, int], None], wait: Callable[[], None]) -> None:
        """Queue items [0, total) of draw `key` by `draw(first, count)`, in slices when a
        signal may come and the draw is long; `wait()` draws what is queued and blocks until
        the GPU is done."""
        drive(self.steps(key, total, draw, wait))

    def steps(self, key: str, total: int, draw: Callable[[int, int], None], wait: Callable[[], None],
              fallback: str | None = None) -> Steps[None]:
        """`run` as a generator: while `stepping`, the pass yields after each slice of about
        STEP_S (and once the draws queued whole add up to one). A `key` with no rate yet
        takes `fallback`'s (a run of an object: the object's), and its slices set both."""
        if total <= 0:
            return
        budget = self._budget()
        rate = self.rates.get(key)
        own = rate is not None
        if rate is None and fallback is not None:
            rate = self.rates.get(fallback)
        # While stepping, a draw with only its fallback's rate is sliced: its first slice
        # measures its own (a borrowed rate misjudges it: runs differ in what they cover).
        whole = rate is not None and total <= rate * budget and (own or not self.stepping)
        if (not self.stepping and not interrupt.watching()) or (rate is None and total <= FIRST_SLICE) or whole:
            queued_at = self.clock()
            draw(0, total)
            if self.stepping and rate is not None:
                # Many short draws (an object's runs, many objects) add up: yield once they
                # would take a slice.
                if not self.queued:
                    self.queued_since = queued_at
                self.queued.append((key, fallback, total, total / rate))
                self.owed += total / rate
                if self.owed >= budget:
                    wait()
                    self._learn_queued()
                    yield
            return
        if self.stepping and self.queued:
            wait()  # the draws queued whole, measured apart from this one's first slice
            self._learn_queued()
        size = FIRST_SLICE if rate is None else max(int(rate * budget), 1)
        done = 0
        while done < total:
            count = min(size, total - done)
            start = self.clock()
            draw(done, count)
            wait()
            spent = max(self.clock() - start, 1e-4)
            self.slices += 1
            done += count
            rate = count / spent
            self._set_rate(key, fallback, rate)
            if self.stepping:
                self.owed = 0.0
                yield
                budget = self._budget()  # what is left of the redraw that goes on with it
            else:
                interrupt.check()
            size = max(1, min(int(rate * budget), count * (STEP_GROWTH if self.stepping else GROWTH)))

    def _set_rate(self, key: str, fallback: str | None, rate: float) -> None:
        if len(self.rates) >= MAX_RATES and key not in self.rates:
            self.rates.clear()  # runs come and go with the view: keep the table small
        self.rates[key] = rate
        if fallback is not None:
            self.rates[fallback] = rate

    def _learn_queued(self) -> None:
        """After the wait for the draws queued whole: each one's rate, their foretold times
        scaled to the time they took together."""
        spent = max(self.clock() - self.queued_since, 1e-4)
        foretold = sum(seconds for *_, seconds in self.queued)
        scale = spent / foretold if foretold > 0.0 else 1.0
        for key, fallback, items, seconds in self.queued:
            self._set_rate(key, fallback, items / max(seconds * scale, 1e-6))
        self.queued.clear()
        self.owed = 0.0
