"""One comparison run of the sidebar tool, step by step: it measures exactly what
`omniwarp compare` measures, with the same `compare.run_row`, but on Blender's own `gpu`
backend (`ShadowPipeline(BlenderGPUBackend())`): inside Blender, Blender owns GL, so
moderngl must not be used (docs/design.md section 3). The two backends agree on visibility,
so the error figures equal the command line's; the times differ only by timing noise.

The first step renders (or loads) the Cycles reference, each later step one row. The
modal operator (compare_ops.py) runs one step per timer tick; the synchronous one runs
them all. The full rows of the last run per scene are kept for export.
"""
from __future__ import annotations

import logging
import os
import re
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import bpy

from .. import compare, report
from . import compare_background
from ..core import methods as method_registry
from ..core.errors import InputError, OmniWarpError
from ..core.rows import Row, make_row
from .compare_props import (
    PLOT_FILE,
    PLOT_IMAGE_NAME,
    OMNIWARP_PG_comparison,
    Report,
    show_mismatch,
    clear_presets,
    load_image,
    preset_info,
    selected_methods,
)
from .properties import SUPPORTED_LIGHT_TYPES
from .events import redraw_3d_views  # the sidebar lives in the 3D views this redraws

log = logging.getLogger(__name__)

# ----------------------------------------------------------------------------
# module state: the running job and the full rows (for export)
# ----------------------------------------------------------------------------
# Full row dicts of the last run per scene (Scene.session_uid): what export writes.
_ROWS: dict[int, list[dict]] = {}


@dataclass
class PanelJob:
    """One comparison run: what to measure and what has been measured."""

    scene_name: str
    scene_uid: int  # Scene.session_uid: survives renames, never matches a scene of another file
    source: str  # 'PRESET' or 'CURRENT'
    preset: str  # the preset name, or the label of the current scene
    camera_size: tuple[int, int]
    light_name: str | None
    hard: bool  # the reference's light without its size (capture.capture)
    tasks: list[tuple[str, int]]  # (method, resolution) per row, in order
    options: compare.CompareOptions
    out_dir: Path
    image_dir: Path | None
    keep_rows: list[dict] = field(default_factory=list)  # rows of earlier runs kept in the plot
    rows: list[dict] = field(default_factory=list)
    reference: Any = None  # ReferenceData once loaded
    scene: Any = None  # its compare.resident_scene, kept on the GPU for every row
    pipeline: Any = None  # ShadowPipeline once the reference is loaded
    next_task: int = 0
    started: float = field(default_factory=time.perf_counter)
    row_seconds: list[float] = field(default_factory=list)
    timer: Any = None  # the window-manager timer of the modal run
    note: str = ""  # what the reference step said (methods skipped for the light)
    child: Any = None  # the background run measuring for it (compare_background.ChildRun), if any
    status_shown: str = ""  # the status bar's text as last set

    @property
    def total_steps(self) -> int:
        """The reference, then one step per row."""
        return len(self.tasks) + 1

    @property
    def steps_done(self) -> int:
        return (self.reference is not None) + self.next_task

    @property
    def finished(self) -> bool:
        return self.reference is not None and self.next_task >= len(self.tasks)

    def seconds_left(self) -> float | None:
        """Estimated seconds to the end, from the mean time of the rows so far."""
        if not self.row_seconds:
            return None
        return sum(self.row_seconds) / len(self.row_seconds) * (len(self.tasks) - self.next_task)

    def release(self) -> None:
        """Free the GPU backend (and with it every GPU object the rows made)."""
        if self.pipeline is not None:
            self.pipeline.backend.release()
            self.pipeline = None


_ACTIVE: PanelJob | None = None  # the job of the running modal operator, if any


def is_running() -> bool:
    """True while a modal comparison runs."""
    return _ACTIVE is not None


def active_job() -> PanelJob | None:
    """The job of the running modal comparison, if any."""
    return _ACTIVE


def set_active(job: PanelJob | None) -> None:
    """Make `job` the running modal comparison (None: none runs)."""
    global _ACTIVE
    _ACTIVE = job


def free_state() -> None:
    """Forget the rows and the preset caches; release a running job's GPU backend."""
    global _ACTIVE
    if _ACTIVE is not None:
        log.warning("OmniWarp comparison still running while unregistering; releasing it")
        remove_timer(_ACTIVE, bpy.context.window_manager)
        if _ACTIVE.child is not None:
            _ACTIVE.child.kill_now()
        _ACTIVE.release()
        _ACTIVE = None
    compare_background.free_children()
    _ROWS.clear()
    clear_presets()


def remove_timer(job: PanelJob, wm: bpy.types.WindowManager | None) -> None:
    """Stop the modal run's window-manager timer."""
    if job.timer is not None and wm is not None:
        wm.event_timer_remove(job.timer)
    job.timer = None


# ----------------------------------------------------------------------------
# the comparison steps (shared by the modal and the synchronous paths)
# ----------------------------------------------------------------------------
def _safe_label(name: str) -> str:
    """A scene name usable in file names."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "scene"


def scene_light(context: bpy.types.Context, scene: bpy.types.Scene) -> str | None:
    """The active object when it is a light OmniWarp shadows (else capture picks the only one)."""
    obj = getattr(context, "active_object", None)
    if (obj is not None and obj.type == "LIGHT" and obj.data.type in SUPPORTED_LIGHT_TYPES
            and obj.name in scene.objects):
        return obj.name
    return None


def _output_dir() -> Path:
    """A fresh folder for this run's plot and images (in Blender's session temp folder)."""
    base = Path(bpy.app.tempdir) if bpy.app.tempdir else Path(tempfile.gettempdir())
    return Path(tempfile.mkdtemp(prefix="omniwarp_compare_", dir=base))


def start_job(context: bpy.types.Context, report_fn: Report) -> PanelJob | None:
    """Validate the settings and set up a job; None (after an error report) if they are bad.

    Nothing is changed before the input is valid; then the results are cleared unless
    `keep_previous` is on.
    """
    scene = context.scene
    settings = scene.omniwarp_compare
    methods = selected_methods(settings)
    if not methods:
        report_fn({"ERROR"}, "No method ticked: tick at least one of "
                  + ", ".join(method_registry.pipeline_methods()))
        return None
    try:
        resolutions = compare.parse_resolutions(settings.resolutions)
    except InputError as exc:
        report_fn({"ERROR"}, f"Resolutions {settings.resolutions!r}: {exc}")
        return None
    light_name = None
    if settings.source == "PRESET":
        preset = settings.preset
        if preset_info(preset) is None:
            report_fn({"ERROR"}, f"Unknown preset {preset!r}: choose one from the list")
            return None
    else:
        if scene.camera is None or scene.camera.type != "CAMERA":
            report_fn({"ERROR"}, f"Scene {scene.name!r} has no active camera: the Cycles reference needs one")
            return None
        preset = _safe_label(scene.name)
        light_name = scene_light(context, scene)
    out_dir = _output_dir()
    # The plot and the images need numpy only (core/png.py, core/raster_plot.py where
    # matplotlib is missing, as in a stock Blender), so every run writes them.
    options = compare.CompareOptions(methods=methods, resolutions=resolutions, cull=bool(settings.cull),
                                     frames=int(settings.frames), out_dir=out_dir, write_images=True)
    keep = list(_ROWS.get(scene.session_uid, [])) if settings.keep_previous else []
    if not settings.keep_previous:
        settings.results.clear()
        settings.active_result = 0
    job = PanelJob(scene_name=scene.name, scene_uid=scene.session_uid, source=settings.source, preset=preset,
               camera_size=(int(settings.camera_size[0]), int(settings.camera_size[1])), light_name=light_name,
               hard=bool(settings.hard),
               tasks=[(m, r) for m in methods for r in resolutions], options=options, out_dir=out_dir,
               image_dir=out_dir / "images", keep_rows=keep)
    _ROWS[scene.session_uid] = list(keep)
    settings.progress = 0.0
    settings.status = f"Starting: {rows_text(len(job.tasks))} of {preset}"
    log.info("comparison of %s: %d rows into %s", preset, len(job.tasks), out_dir)
    return job


def _find_scene(job: PanelJob) -> bpy.types.Scene | None:
    """The job's scene, by session uid (a renamed scene is still found; another file's is not)."""
    for scene in bpy.data.scenes:
        if scene.session_uid == job.scene_uid:
            return scene
    return None


def _job_scene(job: PanelJob) -> bpy.types.Scene:
    scene = _find_scene(job)
    if scene is None:
        raise InputError(f"scene {job.scene_name!r} was removed during the comparison")
    return scene


def reference_cache_dir() -> Path | None:
    """Where the panel caches preset references. Installed as an extension, Blender's user
    folder for it (`extension_path_user`): the extension's own folder is replaced by every
    update and may be read-only. None otherwise, or where $OMNIWARP_CACHE names one: the
    command line's choice (reference/cache.py)."""
    from ..reference.cache import CACHE_ENV

    package = __package__.split(".addon.", 1)[0]
    if os.environ.get(CACHE_ENV) or not package.startswith("bl_ext."):
        return None
    return Path(bpy.utils.extension_path_user(package, path="reference", create=True))


def _load_reference(job: PanelJob) -> None:
    """Step 0: the Cycles reference (cached for presets) and the Blender-gpu pipeline."""
    from ..reference.cache import load_or_capture
    from ..reference.capture import capture
    from ..render.backends.blender.backend import BlenderGPUBackend
    from ..render.backends.blender.gpu_objects import ensure_gpu
    from ..render.pipeline import ShadowPipeline

    if job.source == "PRESET":
        reference = load_or_capture(job.preset, job.camera_size, hard=job.hard, cache_dir=reference_cache_dir())
    else:
        reference = capture(_job_scene(job), light=job.light_name, hard=job.hard)
    compare.light_from_reference(reference)  # an unsupported light fails here, before any GPU work
    ensure_gpu()
    job.pipeline = ShadowPipeline(BlenderGPUBackend())
    job.reference = reference


def _absolute_paths(row: dict, out_dir: Path) -> dict:
    """run_row's image paths are relative to the output folder; make them absolute."""
    if "mismatch_image" in row:
        row["mismatch_image"] = str(out_dir / row["mismatch_image"])
    if "map_images" in row:
        row["map_images"] = [str(out_dir / name) for name in row["map_images"]]
    return row


def _store_row(settings: OMNIWARP_PG_comparison, row: dict) -> None:
    item = settings.results.add()
    item.name = f"{row['method']} @ {row['resolution']}"
    item.preset = row["preset"]
    item.method = row["method"] + ("" if row.get("cull", True) else " (no cull)")
    item.resolution = int(row["resolution"])
    item.error_pct = row["error_pct"]
    item.false_shadow_pct = row["false_shadow_pct"]
    item.false_lit_pct = row["false_lit_pct"]
    times = row["time_ms"]
    item.total_ms = times["total"]
    item.analysis_ms = times["analysis"]
    item.maps_ms = times["shadow_maps"]
    item.test_ms = times["shadow_test"]
    item.passes = int(row["passes"])
    item.mismatch_image = row.get("mismatch_image", "")
    item.note = row.get("note") or ""


def _drop_unfit_tasks(job: PanelJob) -> str:
    """Drop the ticked methods the reference's light does not take (as `compare` skips
    them); an InputError when none is left. Returns a note for the step's message."""
    emission = job.reference.emission
    unfit = sorted({method for method, _ in job.tasks if not method_registry.fits(method, emission)})
    if not unfit:
        return ""
    job.tasks = [(method, res) for method, res in job.tasks if method_registry.fits(method, emission)]
    if not job.tasks:
        raise InputError(f"none of the ticked methods fits the {emission} light of {job.preset}: "
                         f"{method_registry.fits_text(emission)}")
    return f"; skipped {', '.join(unfit)}: they do not fit a {emission} light"


def measure_step(job: PanelJob) -> dict | None:
    """Do the next step, touching no Blender property: the reference (None), or one row
    (returned, its image paths absolute). What the background job's child runs
    (compare_child.py), and `step_job` in Blender's own process."""
    if job.reference is None:
        _load_reference(job)
        job.note = _drop_unfit_tasks(job)
        return None
    method, resolution = job.tasks[job.next_task]
    start = time.perf_counter()
    if job.scene is None:
        job.scene = compare.resident_scene(job.reference)
    row = compare.run_row(job.pipeline, job.reference, job.preset, method, resolution, job.options,
                          job.image_dir, job.scene)
    job.row_seconds.append(time.perf_counter() - start)
    job.rows.append(_absolute_paths(row, job.out_dir))
    job.next_task += 1
    return row


def step_text(job: PanelJob, row: dict | None, seconds: float) -> str:
    """What a step did, for the log."""
    if row is None:
        return f"reference of {job.preset} ready in {seconds:.1f} s{job.note}"
    return f"{row['method']} @ {row['resolution']}: {row['error_pct']:.3f} % error, {row['time_ms']['total']:.1f} ms"


def store_row(job: PanelJob, row: dict) -> None:
    """Show a measured row in the job's scene (the results list) and keep it for export."""
    scene = _find_scene(job)
    _ROWS.setdefault(job.scene_uid, []).append(row)
    if scene is not None:
        _store_row(scene.omniwarp_compare, row)


def show_progress(job: PanelJob) -> None:
    """The job's progress and status line in its scene's settings (the panel draws them)."""
    scene = _find_scene(job)
    if scene is not None:
        scene.omniwarp_compare.progress = job.steps_done / job.total_steps
        scene.omniwarp_compare.status = status_line(job)


def step_job(job: PanelJob) -> str:
    """Do the next step (the reference, or one row) in this process; returns what it did."""
    _job_scene(job)  # removed during the run: stop here, with its name
    start = time.perf_counter()
    row = measure_step(job)
    if row is not None:
        store_row(job, row)
    show_progress(job)
    return step_text(job, row, time.perf_counter() - start)


def status_line(job: PanelJob) -> str:
    """'row i/N: method @ res, 12 s elapsed, ~30 s left' for the step about to run."""
    elapsed = time.perf_counter() - job.started
    if job.reference is None:
        what = f"Cycles reference of {job.preset}" if job.source == "PRESET" else "Cycles reference of the scene"
        return f"OmniWarp: {what} ({elapsed:.0f} s elapsed)"
    if job.finished:
        return f"OmniWarp: {rows_text(len(job.tasks))} measured in {elapsed:.1f} s"
    method, resolution = job.tasks[job.next_task]
    left = job.seconds_left()
    eta = "estimating" if left is None else f"~{left:.0f} s left"
    return (f"OmniWarp: row {job.next_task + 1}/{len(job.tasks)} {method} @ {resolution} "
            f"({elapsed:.0f} s elapsed, {eta})")


def finish_job(job: PanelJob, report_fn: Report, outcome: str = "done", message: str = "",
               plot_written: bool = False) -> None:
    """Release the GPU, write (unless `plot_written`: the background run wrote it) and load
    the plot, set the status. `outcome`: done, cancelled, failed."""
    job.release()
    scene = _find_scene(job)
    settings = scene.omniwarp_compare if scene is not None else None
    rows = job.keep_rows + job.rows
    elapsed = time.perf_counter() - job.started
    if outcome == "done":
        text = f"{rows_text(len(job.rows))} measured in {elapsed:.1f} s"
    elif outcome == "cancelled":
        text = f"Cancelled after {len(job.rows)} of {len(job.tasks)} rows (kept)"
    else:
        text = f"Failed after {len(job.rows)} of {len(job.tasks)} rows: {message}"
    if job.rows:
        try:
            compare.check_rows(job.rows)
        except ValueError as exc:
            report_fn({"WARNING"}, f"{exc} (shown as measured)")
    if rows and settings is not None and job.image_dir is not None:
        path = job.out_dir / PLOT_FILE
        try:
            if not plot_written:
                report.write_plot(rows, path)
            settings.plot_image = load_image(PLOT_IMAGE_NAME, path)
        except (OSError, ValueError, RuntimeError) as exc:
            log.exception("writing or loading the plot %s failed", path)
            report_fn({"WARNING"}, f"No plot: {exc}")
    if job.rows and settings is not None:
        _select_first_new_row(settings, len(settings.results) - len(job.rows))
    if settings is not None:
        settings.status = text
        if outcome == "done":
            settings.progress = 1.0
    log.info("comparison %s: %s", outcome, text)
    if outcome == "failed":
        report_fn({"ERROR"}, f"OmniWarp comparison failed: {message}")
    elif outcome == "cancelled":
        report_fn({"WARNING"}, f"OmniWarp comparison: {text}")
    else:
        report_fn({"INFO"}, f"OmniWarp comparison: {text}")
    redraw_3d_views()


def rows_text(count: int) -> str:
    return f"{count} row" + ("" if count == 1 else "s")


def _select_first_new_row(settings: OMNIWARP_PG_comparison, first: int) -> None:
    """Select the run's first row (its mismatch image is loaded by the update callback)."""
    if 0 <= first < len(settings.results):
        if settings.active_result == first:
            show_mismatch(settings)
        else:
            settings.active_result = first


def failure_text(exc: BaseException) -> str:
    return str(exc) if isinstance(exc, OmniWarpError) else f"{type(exc).__name__}: {exc}"


def rows_for_export(scene: bpy.types.Scene) -> list[Row]:
    """The full rows of the scene's last run; rebuilt from the stored rows when this
    session has none (e.g. after reopening the .blend file): the columns the panel keeps."""
    settings = scene.omniwarp_compare
    rows = _ROWS.get(scene.session_uid, [])
    if len(rows) == len(settings.results):
        return list(rows)
    return [stored_row(item) for item in settings.results]


def stored_row(item: Any) -> Row:
    """A row from the panel's stored copy (`OMNIWARP_PG_result_row`): what was not stored
    in the .blend (light, renderer, frames, camera size, evaluated pixels) is absent."""
    figure = SimpleNamespace(error_pct=item.error_pct, false_shadow_pct=item.false_shadow_pct,
                             false_lit_pct=item.false_lit_pct, evaluated_pixels=None)
    return make_row(item.preset, item.method, None, figure,
                    {"total": item.total_ms, "analysis": item.analysis_ms, "shadow_maps": item.maps_ms,
                     "shadow_test": item.test_ms}, None, None, None, None,
                    resolution=item.resolution, passes=item.passes, mismatch_image=item.mismatch_image or None,
                    note=item.note or None)
