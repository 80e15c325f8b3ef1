"""The panel's comparison as a background job: a second Blender, `blender -b`,
measures while the window stays live.

A Cycles reference of a sized light and an `exact` frame each hold a thread for seconds to
minutes, and Blender's UI runs on one: run in Blender's own process, they froze the window
and Esc was not read until they returned. So the modal operator (compare_ops.py) starts
`bpy.app.binary_path -b [copy.blend] --python-expr ...` on the same GPU backend; the child
(compare_child.py) runs the very steps of compare_job.measure_step and appends one JSON
line per event to `events.jsonl` in the run's folder; the operator's timer reads the new
lines (a few hundred bytes a row) and fills the results list as rows arrive. Esc kills
the child at once (its rows are already read; a timer reaps it and removes its temporary
folder), and the child dies with this Blender (PR_SET_PDEATHSIG).

Events, one object a line: {"event": "reference", "tasks": [[method, res], ...], "note"};
{"event": "row", "row": {...}, "seconds"}; {"event": "done", "plot": bool, "warnings"};
{"event": "failed", "message"}.
"""
from __future__ import annotations

import json
import logging
import os
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import bpy


log = logging.getLogger(__name__)

EVENTS_FILE = "events.jsonl"
SPEC_FILE = "job.json"
LOG_FILE = "child.log"
KILL_AFTER_S = 1.0  # a cancelled child that has not ended on SIGTERM by then is killed
# The child's nice value: below the window it serves, from its first moment (Blender's own
# start-up, about 1.5 s of both cores, made the window's redraws wait up to 0.29 s).
NICENESS = 10
REAP_STEP_S = 0.1


def available() -> str | None:
    """The Blender binary a background job runs, or None: the PyPI `bpy` module has none,
    and a background Blender measures in its own process anyway."""
    binary = getattr(bpy.app, "binary_path", "")
    if bpy.app.background or not binary or not Path(binary).is_file():
        return None
    return binary


def _gpu_backend() -> str | None:
    """This Blender's GPU backend, for the child's --gpu-backend ('opengl', 'vulkan')."""
    try:
        import gpu

        return gpu.platform.backend_type_get().lower()
    except (ImportError, AttributeError, RuntimeError):
        return None


def job_spec(job: Any) -> dict:
    """What the child needs to rebuild the job (compare_job.PanelJob; compare_child.job_from_spec)."""
    options = job.options
    return {"parent_pid": os.getpid(), "source": job.source, "preset": job.preset,
            "scene_name": job.scene_name, "camera_size": list(job.camera_size), "light_name": job.light_name,
            "hard": job.hard, "tasks": [list(task) for task in job.tasks], "methods": list(options.methods),
            "resolutions": list(options.resolutions), "cull": options.cull, "frames": options.frames,
            "out_dir": str(job.out_dir), "keep_rows": job.keep_rows}


@dataclass(eq=False)  # kept in a set by identity
class ChildRun:
    """One background Blender measuring a job, and what has been read of its events."""

    proc: subprocess.Popen
    out_dir: Path
    offset: int = 0
    partial: bytes = b""
    stopped_at: float | None = None  # when stop() asked it to end
    reaper: Any = None  # the timer that reaps it once stopped

    @property
    def temp_dir(self) -> Path:
        return self.out_dir / "tmp"

    def events(self) -> list[dict]:
        """The events written since the last call (whole lines only)."""
        path = self.out_dir / EVENTS_FILE
        try:
            with path.open("rb") as stream:
                stream.seek(self.offset)
                data = stream.read()
        except FileNotFoundError:
            return []  # not written yet
        except OSError as exc:
            log.warning("background comparison: cannot read %s: %s", path, exc)
            return []
        self.offset += len(data)
        lines = (self.partial + data).split(b"\n")
        self.partial = lines.pop()
        out = []
        for line in lines:
            if not line.strip():
                continue
            try:
                event = json.loads(line)
            except ValueError:  # the child writes whole lines: a torn one is a bug, not a reason to stop
                log.warning("background comparison: unreadable event line %r", line[:200])
                continue
            out.append(event)
        return out

    def exited(self) -> bool:
        return self.proc.poll() is not None

    def log_tail(self, limit: int = 1500) -> str:
        """The end of the child's console, for a failure's message."""
        try:
            text = (self.out_dir / LOG_FILE).read_text(errors="replace")
        except OSError:
            return ""
        lines = [line for line in text.splitlines() if line.strip() and "EGL_BAD" not in line]
        return "\n".join(lines)[-limit:]

    def stop(self) -> None:
        """End the child now, without waiting: SIGTERM, then SIGKILL after KILL_AFTER_S,
        reaped by a timer that then removes its temporary folder."""
        self.stopped_at = time.monotonic()
        if not self.exited():
            self.proc.terminate()
        _LIVE.add(self)
        self.reaper = self._reap  # the one bound method, to unregister it by
        bpy.app.timers.register(self.reaper, first_interval=REAP_STEP_S)

    def _reap(self) -> float | None:
        if self in _LIVE and not self.exited():
            if time.monotonic() - (self.stopped_at or 0.0) > KILL_AFTER_S:
                self.proc.kill()
            return REAP_STEP_S
        self.cleanup()
        return None

    def cleanup(self) -> None:
        """The child has ended: remove its temporary folder (Blender's session folder of it)."""
        shutil.rmtree(self.temp_dir, ignore_errors=True)
        _LIVE.discard(self)

    def kill_now(self) -> None:
        """End the child and wait for it (unregistering: no timer may outlive the extension)."""
        if not self.exited():
            self.proc.kill()
        self.proc.wait()
        if self.reaper is not None and bpy.app.timers.is_registered(self.reaper):
            bpy.app.timers.unregister(self.reaper)
        self.cleanup()


_LIVE: set[ChildRun] = set()  # children stopped but not reaped yet


def start(job: Any, binary: str) -> ChildRun:
    """Start the background Blender for `job`: a copy of the current file when the job
    measures the current scene, the preset's name otherwise."""
    out_dir = Path(job.out_dir)
    temp_dir = out_dir / "tmp"
    temp_dir.mkdir(parents=True, exist_ok=True)
    spec = job_spec(job)
    (out_dir / SPEC_FILE).write_text(json.dumps(spec))
    args = [binary, "-b"]
    if job.source == "CURRENT":
        copy = out_dir / "scene.blend"
        # A copy: the artist's file keeps its name and its unsaved state; relative paths are
        # remapped to the copy's folder.
        bpy.ops.wm.save_as_mainfile(filepath=str(copy), copy=True, check_existing=False)
        args.append(str(copy))
    backend = _gpu_backend()
    if backend:
        args += ["--gpu-backend", backend]
    # The child imports compare_child by this extension's full name; an edge between two
    # processes, not an import of this one (compare_child imports this module).
    module = __name__.rsplit(".", 1)[0] + ".compare_child"
    code = f"import sys; import {module} as child; child.main(sys.argv[sys.argv.index('--') + 1])"
    args += ["--python-expr", code, "--", str(out_dir / SPEC_FILE)]
    env = dict(os.environ, TMPDIR=str(temp_dir), TEMP=str(temp_dir), TMP=str(temp_dir))
    with (out_dir / LOG_FILE).open("wb") as console:
        proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=console, stderr=subprocess.STDOUT, env=env)
    if hasattr(os, "setpriority"):  # at once, before Blender starts its threads (they inherit it)
        try:
            os.setpriority(os.PRIO_PROCESS, proc.pid, NICENESS)
        except OSError as exc:
            log.debug("the background comparison keeps its priority: %s", exc)
    log.info("background comparison: pid %d, %s", proc.pid, " ".join(args[:3]))
    return ChildRun(proc=proc, out_dir=out_dir)


def free_children() -> None:
    """Kill every child still running (the extension is unregistered)."""
    for run in list(_LIVE):
        run.kill_now()
