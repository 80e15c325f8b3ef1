"""A frame's stage clock (render/stage_clock.py): wall time per stage, GPU time from the
device's timer queries, and no GPU time where a query's time cannot be true."""
from __future__ import annotations

import time

import pytest

from addon.compare import _median_gpu_times
from addon.render.stage_clock import StageClock


class _Timer:
    def __init__(self, ms: float) -> None:
        self.elapsed_ms = ms

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        pass


class _Device:
    """Hands out timers whose times are given in order."""

    def __init__(self, times: list[float]) -> None:
        self.times = list(times)

    def timer(self, key: str = "frame"):
        return _Timer(self.times.pop(0))


def _frame(times: list[float]) -> dict | None:
    clock = StageClock(_Device(times), None)
    with clock.part("stats", "analysis"):
        pass
    with clock.part("plan", "prepare", gpu=False):
        pass
    with clock.part("maps", "shadow_maps"):
        time.sleep(0.02)
    return clock.gpu_reader()()


def test_gpu_times_are_summed_per_stage():
    gpu = _frame([1.0, 2.5])
    assert gpu == pytest.approx({"analysis": 1.0, "shadow_maps": 2.5, "shadow_test": 0.0, "total": 3.5})


@pytest.mark.parametrize("bad", [4294.967296, -1.0])
def test_a_time_longer_than_the_frame_or_negative_gives_none(bad):
    # llvmpipe gave 2^32 ns for the first queries of a new context; the frame took ~20 ms.
    assert _frame([bad, 2.0]) is None


def test_a_rows_gpu_time_is_the_median_of_its_timed_frames():
    frames = [None, {"analysis": 1.0, "total": 1.0}, {"analysis": 3.0, "total": 3.0}, {"analysis": 2.0, "total": 2.0}]
    assert _median_gpu_times(frames) == {"analysis": 2.0, "total": 2.0}
    assert _median_gpu_times([None, None]) is None
