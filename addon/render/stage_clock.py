"""A frame's stage times: wall clock on the host and, where the device has them, GPU timer
queries (docs/design.md section 3).

A frame is a sequence of parts, each counted in one of the report's stages. A part that
submits GPU work runs inside its own timer query; a measuring frame (`sync`) also waits
for the GPU at the end of each such part, so that its wall time holds its GPU work. A
real-time frame does not wait: its wall times are the host's, and the GPU's own time
comes from the queries, read after the frame.
"""
from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable, Iterator

from .device import Device, GPUTimer

log = logging.getLogger(__name__)

# The report's stages, in the order of a frame.
STAGES = ("prepare", "analysis", "shadow_maps", "shadow_test")


class StageClock:
    """Collects one frame's wall ms per stage and its GPU timers."""

    def __init__(self, device: Device, sync: Callable[[], None] | None) -> None:
        self.device = device
        self.sync = sync  # waits for the GPU after each GPU part; None: never wait
        self.wall: dict[str, float] = {stage: 0.0 for stage in STAGES}
        self._timers: list[tuple[str, GPUTimer]] = []
        self._start = time.perf_counter()

    @contextlib.contextmanager
    def part(self, name: str, stage: str, gpu: bool = True) -> Iterator[None]:
        """Time the calls inside as part `name` of `stage`; `gpu`: they submit GPU work."""
        start = time.perf_counter()
        timer = self.device.timer(name) if gpu else None
        with contextlib.ExitStack() as stack:
            if timer is not None:
                stack.enter_context(timer)
                self._timers.append((stage, timer))
            yield
        if gpu and self.sync is not None:
            self.sync()
        self.wall[stage] += (time.perf_counter() - start) * 1e3

    def add(self, stage: str, ms: float) -> None:
        """Host time spent before the clock started, counted in `stage`."""
        self.wall[stage] += ms

    def wall_ms(self, before_ms: float = 0.0) -> dict[str, float]:
        """Wall ms per stage and `total` (since the clock started, plus `before_ms`)."""
        return {**self.wall, "total": (time.perf_counter() - self._start) * 1e3 + before_ms}

    def gpu_reader(self) -> Callable[[], dict[str, float] | None]:
        """Reads the GPU ms per stage and their `total` (waits for the GPU); None without
        queries, or when a query's time cannot be true: longer than the wall time from the
        frame's start to the read, within which all of its work began and ended (llvmpipe
        gave 2^32 ns for the first queries of a new context)."""
        timers = list(self._timers)
        start = self._start

        def read() -> dict[str, float] | None:
            if not timers:
                return None
            out = {stage: 0.0 for stage in STAGES[1:]}
            elapsed = [(stage, timer.elapsed_ms) for stage, timer in timers]
            bound = (time.perf_counter() - start) * 1e3
            if any(not 0.0 <= ms <= bound for _, ms in elapsed):
                log.debug("a GPU timer query gave a time outside the frame: %s", elapsed)
                return None
            for stage, ms in elapsed:
                out[stage] += ms
            out["total"] = sum(out.values())
            return out

        return read
