"""The background job's child (compare_background.py): inside `blender -b`, measure the job
of `job.json` step by step and append each event to `events.jsonl` as it happens.

    blender -b [copy.blend] --python-expr "...compare_child.main(SPEC)" -- SPEC

It runs compare_job.measure_step, so its rows are the panel's in-process rows and the
command line's. It ends with its parent (PR_SET_PDEATHSIG on Linux, and a check that the
parent is still the one that started it); the parent lowers its priority as it starts it.
"""
from __future__ import annotations

import json
import logging
import os
import signal
import sys
import time
from pathlib import Path

import bpy

from .. import compare, report
from . import registration
from .compare_background import EVENTS_FILE
from .compare_job import PanelJob, failure_text, measure_step
from .compare_props import PLOT_FILE

log = logging.getLogger(__name__)

def job_from_spec(spec: dict) -> PanelJob:
    """The child's job, from `job_spec`'s dictionary."""
    out_dir = Path(spec["out_dir"])
    options = compare.CompareOptions(methods=tuple(spec["methods"]), resolutions=tuple(spec["resolutions"]),
                                     cull=spec["cull"], frames=spec["frames"], out_dir=out_dir, write_images=True)
    scene_uid = 0
    for scene in bpy.data.scenes:  # the copy's scene of that name (a preset needs none)
        if scene.name == spec["scene_name"]:
            scene_uid = scene.session_uid
    return PanelJob(scene_name=spec["scene_name"], scene_uid=scene_uid, source=spec["source"], preset=spec["preset"],
                camera_size=tuple(spec["camera_size"]), light_name=spec["light_name"], hard=spec["hard"],
                tasks=[tuple(task) for task in spec["tasks"]], options=options, out_dir=out_dir,
                image_dir=out_dir / "images", keep_rows=spec["keep_rows"])


def _die_with_parent(parent_pid: int) -> None:
    """End when the Blender that started this one ends (quit, crash, killed)."""
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError) as exc:
            log.warning("cannot tie this job to its parent: %s", exc)
    if os.getppid() != parent_pid:  # the parent ended before the tie was made
        os._exit(1)


def _register() -> None:
    """The extension's classes, where this Blender's preferences have not enabled it."""
    if not hasattr(bpy.types.Scene, "omniwarp_compare"):
        registration.register()


class _Events:
    """events.jsonl, one whole line a write."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def write(self, event: str, **fields) -> None:
        line = json.dumps({"event": event, **fields}) + "\n"
        with self.path.open("a", encoding="utf-8") as stream:
            stream.write(line)


def run(spec: dict) -> None:
    """Measure the job of `spec` (compare_background.job_spec), writing its events."""
    out_dir = Path(spec["out_dir"])
    events = _Events(out_dir / EVENTS_FILE)
    try:
        _register()
        job = job_from_spec(spec)
        measure_step(job)  # the reference
        events.write("reference", tasks=[list(task) for task in job.tasks], note=job.note)
        while not job.finished:
            start = time.perf_counter()
            row = measure_step(job)
            events.write("row", row=row, seconds=time.perf_counter() - start)
        warnings = []
        try:
            compare.check_rows(job.rows)
        except ValueError as exc:
            warnings.append(f"{exc} (shown as measured)")
        plot = False
        try:
            plot = bool(report.write_plot(job.keep_rows + job.rows, out_dir / PLOT_FILE))
        except (OSError, ValueError, RuntimeError) as exc:
            warnings.append(f"No plot: {exc}")
        events.write("done", plot=plot, warnings=warnings)
    except Exception as exc:  # noqa: BLE001 - any failure is reported to the panel, then logged
        log.exception("background comparison failed")
        events.write("failed", message=failure_text(exc))
    finally:
        if "job" in locals():
            job.release()


def main(spec_path: str) -> None:
    """The child's entry (compare_background.start)."""
    spec = json.loads(Path(spec_path).read_text())
    _die_with_parent(int(spec["parent_pid"]))
    run(spec)  # at the parent's NICENESS (compare_background.start)
