"""Inside a real Blender GUI (under Xvfb, gui.sh with GUI_SCRIPT=gui_job.py and
--enable-event-simulate): the comparison panel's Compare, invoked as a user clicks it, runs as
a background job while a timer at 50 ms records the gaps between its ticks (issue 52).

  0. baselines: the window alone for 2 s, and Compare with a child that only sleeps (the
     gaps the window's own redraws and the panel's ticks make);
  1. the soft_room preset (a sized light: its reference renders 256 samples per pixel) at
     160x120 with dpsm and exact at 256, to its end: the largest tick gap during the run,
     the rows (error figures, for the caller to hold against `omniwarp compare`), the status;
  2. the same with exact at 2048 added; once the first row is in, Esc (a simulated key
     press): how long until the job has ended in the panel, how long until the child
     process is gone, the rows kept, the status, and whether its temporary folder is left;
  3. the Current scene source: room_omni built into a new scene, then Compare (dpsm and
     exact at 256): the child measures a copy of the file.

Writes `job.json` into OUT_DIR and quits; a failure writes its traceback there.
"""
from __future__ import annotations

import importlib
import json
import os
import sys
import time
import traceback
from pathlib import Path

import bpy

sys.path.insert(0, "/omniwarp")  # the repository, bound read-only in the chroot (scripts/real_blender.sh)
from tests.support.extension_worker import ADDON_MODULE as PACKAGE  # noqa: E402
OUT = Path(sys.argv[sys.argv.index("--") + 1])
TICK_S = 0.05
REPORT: dict = {"steps": []}
TICKS: list[float] = []


def _module(name: str):
    return importlib.import_module(f"{PACKAGE}.addon.{name}")


def _ticker() -> float:
    TICKS.append(time.perf_counter())
    return TICK_S


def _largest_gap(start: float, end: float) -> float:
    inside = [t for t in TICKS if start <= t <= end]
    return max((b - a for a, b in zip(inside, inside[1:])), default=float("inf"))


def _long_gaps(start: float, end: float, over: float = 0.12) -> list[list[float]]:
    """[seconds after start, gap] of every gap over `over`: where the window waited."""
    inside = [t for t in TICKS if start <= t <= end]
    return [[round(a - start, 3), round(b - a, 3)] for a, b in zip(inside, inside[1:]) if b - a > over]


def _window_context() -> dict:
    window = bpy.context.window_manager.windows[0]
    area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height)
    region = next(r for r in area.regions if r.type == "WINDOW")
    return {"window": window, "area": area, "region": region}


def _settings():
    return bpy.context.window_manager.windows[0].scene.omniwarp_compare


def _configure(resolutions: str) -> None:
    compare_props = _module("blender.compare_props")
    methods = _module("core.methods")
    settings = _settings()
    settings.source = "PRESET"
    settings.preset = "soft_room"
    settings.camera_size = (160, 120)
    settings.hard = False
    settings.frames = 1
    settings.keep_previous = False
    for method in methods.pipeline_methods():
        setattr(settings, compare_props.method_prop(method), method in ("dpsm", "exact"))
    settings.resolutions = resolutions


def _invoke() -> dict:
    with bpy.context.temp_override(**_window_context()):
        result = sorted(bpy.ops.omniwarp.compare("INVOKE_DEFAULT"))
    job = _module("blender.compare_job").active_job()
    child = job.child if job is not None else None
    return {"result": result, "child_pid": child.proc.pid if child else None,
            "temp_dir": str(child.temp_dir) if child else None}


def _running() -> bool:
    return _module("blender.compare_job").is_running()


def _rows() -> list[dict]:
    return [{"method": item.method, "resolution": item.resolution, "error_pct": item.error_pct}
            for item in _settings().results]


def _gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return True
    return state in ("Z", "X")


STATE: dict = {}


def s_idle():
    """The window alone for 2 s: the gaps its own redraws make (the baseline)."""
    if "idle" not in STATE:
        STATE["idle"] = time.perf_counter()
        return "again"
    now = time.perf_counter()
    if now - STATE["idle"] < 2.0:
        return "again"
    REPORT["idle"] = {"largest_gap_s": _largest_gap(STATE["idle"], now), "long_gaps": _long_gaps(STATE["idle"], now)}


def s_dummy():
    """Compare with a child that only sleeps: the gaps the panel's own ticks make."""
    import subprocess

    background = _module("blender.compare_background")
    if "dummy" not in STATE:
        real = background.start
        background.start = lambda job, binary: background.ChildRun(
            proc=subprocess.Popen(["sleep", "3"]), out_dir=job.out_dir)
        try:
            _configure("256")
            STATE["dummy"] = time.perf_counter()
            REPORT["dummy"] = _invoke()
        finally:
            background.start = real
        return "again"
    if _running():
        return "again"
    now = time.perf_counter()
    REPORT["dummy"].update(largest_gap_s=_largest_gap(STATE["dummy"], now),
                           long_gaps=_long_gaps(STATE["dummy"], now))


def s_full_start():
    _configure("256")
    STATE["start"] = time.perf_counter()
    REPORT["full"] = _invoke()


def s_full_wait():
    if _running():
        return "again"
    end = time.perf_counter()
    full = REPORT["full"]
    full.update(seconds=end - STATE["start"], largest_gap_s=_largest_gap(STATE["start"], end),
                long_gaps=_long_gaps(STATE["start"], end), rows=_rows(),
                status=_settings().status, plot=_settings().plot_image is not None)


def s_cancel_start():
    _configure("256,2048")
    REPORT["cancel"] = _invoke()


def s_cancel_first_row():
    if not _settings().results:
        return "again"
    STATE["esc"] = time.perf_counter()
    bpy.context.window_manager.windows[0].event_simulate(type="ESC", value="PRESS")
    bpy.context.window_manager.windows[0].event_simulate(type="ESC", value="RELEASE")


def s_cancel_ended():
    if _running():
        return "again"
    STATE["ended"] = time.perf_counter()
    REPORT["cancel"].update(ended_s=STATE["ended"] - STATE["esc"], rows=_rows(), status=_settings().status)


def s_child_gone():
    pid = REPORT["cancel"]["child_pid"]
    if not _gone(pid):
        return "again"
    REPORT["cancel"]["child_gone_s"] = time.perf_counter() - STATE["esc"]


def s_temp_removed():
    temp = REPORT["cancel"]["temp_dir"]
    if temp and os.path.exists(temp):
        return "again"
    REPORT["cancel"]["temp_left"] = bool(temp and os.path.exists(temp))


def s_current_start():
    """The current scene's source: room_omni built into a new scene (the panel's Build), then
    Compare; the child opens a copy of the file and finds the scene by its name."""
    settings = _settings()
    settings.source = "PRESET"
    settings.preset = "room_omni"
    settings.camera_size = (160, 120)
    with bpy.context.temp_override(**_window_context()):
        bpy.ops.omniwarp.build_preset()
    _configure("256")
    settings = _settings()  # the new scene's, with the settings copied
    settings.source = "CURRENT"
    REPORT["current"] = _invoke()
    REPORT["current"]["scene"] = bpy.context.window_manager.windows[0].scene.name


def s_current_wait():
    if _running():
        return "again"
    REPORT["current"].update(rows=_rows(), status=_settings().status)


STEPS = [s_idle, s_dummy, s_full_start, s_full_wait, s_cancel_start, s_cancel_first_row, s_cancel_ended, s_child_gone,
         s_temp_removed, s_current_start, s_current_wait]
_AT = {"index": 0, "since": time.perf_counter()}
STEP_LIMIT_S = 600.0


def _driver():
    try:
        if _AT["index"] >= len(STEPS):
            _finish()
            return None
        fn = STEPS[_AT["index"]]
        if fn() == "again":
            if time.perf_counter() - _AT["since"] > STEP_LIMIT_S:
                raise TimeoutError(f"step {fn.__name__} waited {STEP_LIMIT_S:.0f} s")
        else:
            REPORT["steps"].append(fn.__name__)
            _AT["index"] += 1
            _AT["since"] = time.perf_counter()
        return 0.02
    except Exception:
        REPORT["error"] = traceback.format_exc()
        _finish()
        return None


def _finish() -> None:
    import gpu

    REPORT["backend"] = gpu.platform.backend_type_get()
    REPORT["tick_s"] = TICK_S
    (OUT / "job.json").write_text(json.dumps(REPORT, indent=1), encoding="utf-8")
    bpy.ops.wm.quit_blender()


OUT.mkdir(parents=True, exist_ok=True)
bpy.app.timers.register(_ticker, first_interval=TICK_S)
bpy.app.timers.register(_driver, first_interval=1.0)
