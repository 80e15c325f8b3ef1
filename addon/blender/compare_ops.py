"""The comparison tool's operators.

* `omniwarp.build_preset` builds the chosen preset into a new scene.
* `omniwarp.compare` measures. Invoked from the UI it runs modally, as a background job
  (compare_background.py): a second Blender, `blender -b`, measures, and a window-manager
  timer reads its rows every `TIMER_STEP_S` seconds into the results list, so the window
  stays live through a Cycles reference or an `exact` frame of minutes; Esc or
  right-click ends the job at once and keeps the rows measured so far. Where no Blender
  binary can be started (the PyPI `bpy` module) each tick does one step in this process.
  Executed directly (`EXEC_DEFAULT`, background mode, tests) it runs every step
  synchronously.
* `omniwarp.export_results` writes the last rows as JSON or CSV.
"""
from __future__ import annotations

import logging
from pathlib import Path

import bpy

from ..core.errors import InputError, OmniWarpError
from ..core.presets import build_preset
from ..core.rows import write_rows
from . import compare_background
from .compare_job import (
    PanelJob,
    failure_text,
    rows_text,
    active_job,
    finish_job,
    is_running,
    remove_timer,
    rows_for_export,
    set_active,
    show_progress,
    start_job,
    status_line,
    step_job,
    store_row,
)
from .compare_props import TIMER_STEP_S, OMNIWARP_PG_comparison, preset_info
from .events import redraw_3d_views

log = logging.getLogger(__name__)


# ----------------------------------------------------------------------------
# operators
# ----------------------------------------------------------------------------
def _copy_settings(source: OMNIWARP_PG_comparison, target: OMNIWARP_PG_comparison) -> None:
    """Copy the comparison settings (not the results) to another scene."""
    skip = {"rna_type", "name", "results", "active_result", "status", "progress", "plot_image",
            "mismatch_preview"}
    for prop in source.bl_rna.properties:
        if prop.identifier in skip or prop.is_readonly:
            continue
        setattr(target, prop.identifier, getattr(source, prop.identifier))


class OMNIWARP_OT_build_preset(bpy.types.Operator):
    """Build the chosen preset into a new scene and switch the window to it; the current scene is
    left untouched"""

    bl_idname = "omniwarp.build_preset"
    bl_label = "Build Preset Scene"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return getattr(context.scene, "omniwarp_compare", None) is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        from ..reference.blender_scene import build_blender_scene

        old = context.scene
        settings = old.omniwarp_compare
        name = settings.preset
        if preset_info(name) is None:
            self.report({"ERROR"}, f"Unknown preset {name!r}: choose one from the list")
            return {"CANCELLED"}
        size = (int(settings.camera_size[0]), int(settings.camera_size[1]))
        try:
            scene = build_blender_scene(build_preset(name, size))
        except OmniWarpError as exc:
            self.report({"ERROR"}, f"Cannot build preset {name!r}: {exc}")
            return {"CANCELLED"}
        _copy_settings(settings, scene.omniwarp_compare)
        if context.window is not None:
            context.window.scene = scene
        self.report({"INFO"}, f"Built preset {name} into the new scene {scene.name!r}")
        return {"FINISHED"}


class OMNIWARP_OT_compare(bpy.types.Operator):
    """Measure the ticked methods at each resolution against the Cycles reference, on Blender's
    GPU backend (the same rows as `omniwarp compare`). Esc or right-click cancels and keeps the
    rows measured so far"""

    bl_idname = "omniwarp.compare"
    bl_label = "Compare"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        if getattr(context.scene, "omniwarp_compare", None) is None:
            return False
        if is_running():
            cls.poll_message_set("A comparison is running (Esc cancels it)")
            return False
        return True

    # synchronous ---------------------------------------------------------------
    def execute(self, context: bpy.types.Context) -> set[str]:
        job = start_job(context, self.report)
        if job is None:
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, job.total_steps)
        try:
            while not job.finished:
                log.info(status_line(job))
                log.info(step_job(job))
                wm.progress_update(job.steps_done)
        except Exception as exc:  # noqa: BLE001 - any failure must end the run cleanly (logged, reported)
            log.exception("OmniWarp comparison failed")
            finish_job(job, self.report, "failed", failure_text(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        finish_job(job, self.report)
        return {"FINISHED"}

    # modal ---------------------------------------------------------------------
    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if context.window is None:
            return self.execute(context)
        job = start_job(context, self.report)
        if job is None:
            return {"CANCELLED"}
        binary = compare_background.available()
        if binary is not None:
            try:
                job.child = compare_background.start(job, binary)
            except (OSError, RuntimeError) as exc:
                log.exception("cannot start the background comparison")
                finish_job(job, self.report, "failed", f"cannot start a background Blender: {exc}")
                return {"CANCELLED"}
        set_active(job)
        wm = context.window_manager
        job.timer = wm.event_timer_add(TIMER_STEP_S, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, job.total_steps)
        _set_status_text(context, status_line(job) + " | Esc: cancel")
        redraw_3d_views()
        return {"RUNNING_MODAL"}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        job = active_job()
        if job is None:  # freed by unregister
            _stop_modal(None, context)
            return {"CANCELLED"}
        if event.type in {"ESC", "RIGHTMOUSE"} and event.value == "PRESS":
            _read_child(job)  # the rows it finished until now are kept
            _stop_modal(job, context)
            finish_job(job, self.report, "cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if job.child is not None:
            return self._follow_child(context, job)
        try:
            log.info(step_job(job))
        except Exception as exc:  # noqa: BLE001 - any failure must end the run cleanly (logged, reported)
            log.exception("OmniWarp comparison failed")
            _stop_modal(job, context)
            finish_job(job, self.report, "failed", failure_text(exc))
            return {"CANCELLED"}
        context.window_manager.progress_update(job.steps_done)
        if job.finished:
            _stop_modal(job, context)
            finish_job(job, self.report)
            return {"FINISHED"}
        _set_status_text(context, status_line(job) + " | Esc: cancel")
        redraw_3d_views()
        return {"PASS_THROUGH"}

    def _follow_child(self, context: bpy.types.Context, job: PanelJob) -> set[str]:
        """One tick of a background job: show the rows it finished; end with it."""
        end = _read_child(job)
        if end is None and job.child.exited():  # its last lines may have come after the read
            end = _read_child(job) or {"event": "failed", "message": _child_ended(job.child)}
        if end is None:
            text = status_line(job) + " | Esc: cancel"
            if text != job.status_shown:  # a redraw of the status bar once a second, not every tick
                job.status_shown = text
                context.window_manager.progress_update(job.steps_done)
                _set_status_text(context, text)
            return {"PASS_THROUGH"}
        _stop_modal(job, context)
        if end["event"] == "failed":
            finish_job(job, self.report, "failed", end["message"])
            return {"CANCELLED"}
        for warning in end.get("warnings", []):
            self.report({"WARNING"}, warning)
        finish_job(job, self.report, plot_written=bool(end.get("plot")))
        return {"FINISHED"}

    def cancel(self, context: bpy.types.Context) -> None:
        """Blender ends the modal (window closed, file loaded): clean up, keep the rows."""
        job = active_job()
        if job is not None:
            _read_child(job)
        _stop_modal(job, context)
        if job is not None:
            finish_job(job, self.report, "cancelled")


def _read_child(job: PanelJob) -> dict | None:
    """Take in the background job's new events: its tasks once the reference is ready,
    each row as it is measured (into the results list). Returns its end event, if read."""
    if job.child is None:
        return None
    end = None
    events = job.child.events()
    for event in events:
        kind = event["event"]
        if kind == "reference":
            job.reference = "background"  # measured by the child: only its being ready matters here
            job.tasks = [tuple(task) for task in event["tasks"]]
            job.note = event.get("note", "")
        elif kind == "row":
            job.rows.append(event["row"])
            job.row_seconds.append(float(event["seconds"]))
            job.next_task += 1
            store_row(job, event["row"])
        elif kind in ("done", "failed"):
            end = event
    if events:  # a scene property set is an update of the scene: only when something changed
        show_progress(job)
    return end


def _child_ended(child: compare_background.ChildRun) -> str:
    """The failure message of a background Blender that ended without a result."""
    tail = child.log_tail().splitlines()
    last = tail[-1] if tail else "no output"
    return (f"the background Blender ended without a result (exit {child.proc.returncode}): {last}; "
            f"its console: {child.out_dir / compare_background.LOG_FILE}")


def _stop_modal(job: PanelJob | None, context: bpy.types.Context) -> None:
    """Timer, progress and status text off, the background Blender ended; no job is active
    any more."""
    set_active(None)
    wm = context.window_manager
    if job is not None:
        if job.child is not None:
            job.child.stop()
        remove_timer(job, wm)
    wm.progress_end()
    _set_status_text(context, None)


def _set_status_text(context: bpy.types.Context, text: str | None) -> None:
    workspace = getattr(context, "workspace", None)
    if workspace is not None:
        workspace.status_text_set(text)


class OMNIWARP_OT_export_results(bpy.types.Operator):
    """Write the last comparison's rows to the export path: .json (the full rows, as results.json of
    the command line) or .csv (one line per row, times as time_ms.* columns)"""

    bl_idname = "omniwarp.export_results"
    bl_label = "Export Results"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return getattr(context.scene, "omniwarp_compare", None) is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        settings = context.scene.omniwarp_compare
        rows = rows_for_export(context.scene)
        if not rows:
            self.report({"ERROR"}, "Nothing to export: run Compare first")
            return {"CANCELLED"}
        raw = settings.export_path.strip()
        if not raw:
            self.report({"ERROR"}, "Set an export path ending with .json or .csv")
            return {"CANCELLED"}
        if raw.startswith("//") and not bpy.data.filepath:
            self.report({"ERROR"}, f"{raw!r} is relative to the .blend file, which is not saved yet: "
                                   "save it or choose an absolute path")
            return {"CANCELLED"}
        path = Path(bpy.path.abspath(raw))
        existed = path.exists()
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_rows(rows, path)
        except InputError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        except OSError as exc:
            self.report({"ERROR"}, f"Cannot write {path}: {exc}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Wrote {rows_text(len(rows))} to {path}" + (" (replaced the old file)" if existed else ""))
        return {"FINISHED"}
