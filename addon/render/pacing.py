"""Long GPU passes cut into slices that a signal can end between (issue 52).

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
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from ..core import interrupt

SLICE_S = 0.2  # seconds of GPU work between two looks at the interrupt
FIRST_SLICE = 16  # items of a draw's first slice when its rate is not known yet
GROWTH = 8  # the most a slice grows over the one before it


@dataclass
class Pacer:
    """Rates of the paced passes (items a second, by pass key) and the slices drawn."""

    rates: dict[str, float] = field(default_factory=dict)
    slices: int = 0  # slices drawn with a wait after them, since the pacer was made
    clock: Callable[[], float] = time.perf_counter

    def run(self, key: str, total: int, draw: Callable[[int, int], None], wait: Callable[[], None]) -> None:
        """Queue items [0, total) of draw `key` by `draw(first, count)`, in slices when a
        signal may come and the draw is long; `wait()` draws what is queued and blocks until
        the GPU is done."""
        rate = self.rates.get(key)
        if total <= 0:
            return
        if not interrupt.watching() or (rate is None and total <= FIRST_SLICE) or (
                rate is not None and total <= rate * SLICE_S):
            draw(0, total)
            return
        size = FIRST_SLICE if rate is None else max(int(rate * SLICE_S), 1)
        done = 0
        while done < total:
            count = min(size, total - done)
            start = self.clock()
            draw(done, count)
            wait()
            spent = max(self.clock() - start, 1e-4)
            self.slices += 1
            done += count
            interrupt.check()
            rate = count / spent
            self.rates[key] = rate
            size = max(1, min(int(rate * SLICE_S), count * GROWTH))

