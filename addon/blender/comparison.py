"""The sidebar tab's comparison tool: every method against Cycles, inside Blender.

It measures exactly what `omniwarp compare` measures, with the same `compare.run_row`,
but on Blender's own `gpu` backend (`ShadowPipeline(BlenderGPUBackend())`): inside
Blender, Blender owns GL, so moderngl must not be used (DESIGN.md section 3). The two
backends agree on visibility, so the error figures equal the command line's; the
times differ only by timing noise.

* `OMNIWARP_PG_comparison` hangs on every scene as `bpy.types.Scene.omniwarp_compare`:
  the source (a preset or the current scene), the methods, resolutions and frames,
  the measured rows (`OMNIWARP_PG_result_row`), the status line and the plot.
* `omniwarp.build_preset` builds the chosen preset into a new scene.
* `omniwarp.compare` measures. Invoked from the UI it runs modally: a window-manager
  timer fires every `TIMER_STEP_S` seconds and each tick does ONE step (first the
  Cycles reference, then one row per tick), so the UI stays responsive between rows;
  Esc or right-click cancels and keeps the rows measured so far. Executed directly
  (`EXEC_DEFAULT`, background mode, tests) it runs every step synchronously.
* `omniwarp.export_results` writes the last rows as JSON or CSV.
* `OMNIWARP_UL_results` and `OMNIWARP_PT_compare` draw it all in the 3D viewport's
  sidebar, tab "OmniWarp".

The plot and the mismatch images need matplotlib (as `omniwarp compare` does); a
Blender without it still measures, and says that the images are missing.
"""
from __future__ import annotations

import csv
import importlib.util
import json
import logging
import re
import tempfile
import textwrap
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    IntVectorProperty,
    PointerProperty,
    StringProperty,
)

from .. import compare, report
from ..core import methods as method_registry
from ..core.errors import InputError, OmniWarpError
from ..core.presets import DEFAULT_PRESET, DEFAULT_RESOLUTION, PresetInfo, available_presets, build_preset
from .events import redraw_3d_views  # the sidebar lives in the 3D views this redraws

log = logging.getLogger(__name__)

SIDEBAR_CATEGORY = "OmniWarp"
PLOT_IMAGE_NAME = "OmniWarp error vs time"
MISMATCH_IMAGE_NAME = "OmniWarp mismatch"
TIMER_STEP_S = 0.05  # seconds between two modal ticks (each tick measures one row)
PLOT_FILE = "error_vs_time.png"
IMAGE_ICON_SCALE = 12.0  # template_icon scale of the plot and mismatch previews

Report = Callable[[set[str], str], Any]

# Newer Blenders accept "//" in a path property only with this option; 4.2 lacks it.
_BLEND_RELATIVE: set[str] = (
    {"PATH_SUPPORTS_BLEND_RELATIVE"}
    if "is_path_supports_blend_relative" in bpy.types.Property.bl_rna.properties else set()
)


# ----------------------------------------------------------------------------
# methods and presets
# ----------------------------------------------------------------------------
def method_prop(method: str) -> str:
    """The BoolProperty that ticks a method: 'cube+notw' -> 'use_cube_notw'."""
    return "use_" + re.sub(r"[^a-z0-9]+", "_", method.lower())


def _method_description(method: str) -> str:
    """The checkbox tooltip: the registry's one-line description of the method."""
    return (f"Measure {method}: {method_registry.method(method).description}. "
            "Each ticked method adds one row per resolution")


# Blender's enum callback does not keep the strings it gets alive: keep them here.
_PRESET_ITEMS: list[tuple[str, str, str, int]] = []
_PRESET_INFO: dict[str, PresetInfo] = {}
_NO_PRESET = ("NONE", "No presets", "No preset files were found in the extension's presets folder", 0)


def _load_presets() -> None:
    """Fill the preset caches once; DEFAULT_PRESET comes first (it is the default item)."""
    if _PRESET_ITEMS:
        return
    try:
        found = available_presets()
    except OmniWarpError as exc:
        log.error("cannot list the presets: %s", exc)
        found = {}
    names = sorted(found, key=lambda name: (name != DEFAULT_PRESET, name))
    _PRESET_INFO.update(found)
    for number, name in enumerate(names):
        info = found[name]
        _PRESET_ITEMS.append((name, name, f"{info.description}. Stresses: {info.stresses}", number))
    if not _PRESET_ITEMS:
        _PRESET_ITEMS.append(_NO_PRESET)


def _preset_items(_self: Any, _context: Any) -> list[tuple[str, str, str, int]]:
    """EnumProperty items callback: every preset, name and description (as the tooltip)."""
    _load_presets()
    return _PRESET_ITEMS


def preset_info(name: str) -> PresetInfo | None:
    """The PresetInfo of a preset shown in the enum, or None."""
    _load_presets()
    return _PRESET_INFO.get(name)


# ----------------------------------------------------------------------------
# module state: the running job and the full rows (for export)
# ----------------------------------------------------------------------------
# Full row dicts of the last run per scene (Scene.session_uid): what export writes.
_ROWS: dict[int, list[dict]] = {}


@dataclass
class _Job:
    """One comparison run: what to measure and what has been measured."""

    scene_name: str
    scene_uid: int  # Scene.session_uid: survives renames, never matches a scene of another file
    source: str  # 'PRESET' or 'CURRENT'
    preset: str  # the preset name, or the label of the current scene
    camera_size: tuple[int, int]
    light_name: str | None
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


_ACTIVE: _Job | None = None  # the job of the running modal operator, if any


def is_running() -> bool:
    """True while a modal comparison runs."""
    return _ACTIVE is not None


def free_state() -> None:
    """Forget the rows and the preset caches; release a running job's GPU backend."""
    global _ACTIVE
    if _ACTIVE is not None:
        log.warning("OmniWarp comparison still running while unregistering; releasing it")
        _remove_timer(_ACTIVE, bpy.context.window_manager)
        _ACTIVE.release()
        _ACTIVE = None
    _ROWS.clear()
    _PRESET_ITEMS.clear()
    _PRESET_INFO.clear()


# ----------------------------------------------------------------------------
# images
# ----------------------------------------------------------------------------
def have_matplotlib() -> bool:
    """The plot and the mismatch images are written with matplotlib."""
    return importlib.util.find_spec("matplotlib") is not None


def load_image(name: str, path: Path) -> bpy.types.Image:
    """The image datablock `name` showing the file `path` (created, or reloaded in place)."""
    image = bpy.data.images.get(name)
    if image is None:
        image = bpy.data.images.load(str(path), check_existing=False)
        image.name = name
    else:
        if image.packed_file is not None:
            image.unpack(method="REMOVE")  # the file on disk is the newer content
        image.filepath = str(path)
        image.reload()
    preview = image.preview_ensure()
    if preview is not None:
        preview.reload()
    return image


def _show_mismatch(settings: OMNIWARP_PG_comparison) -> None:
    """Load the selected row's mismatch image into the "OmniWarp mismatch" datablock."""
    index = settings.active_result
    if not 0 <= index < len(settings.results):
        return
    path = settings.results[index].mismatch_image
    if not path:
        return
    file = Path(bpy.path.abspath(path))
    if not file.is_file():
        log.info("mismatch image %s is gone (temporary files of an earlier session)", file)
        return
    settings.mismatch_preview = load_image(MISMATCH_IMAGE_NAME, file)


def _active_result_changed(self: OMNIWARP_PG_comparison, _context: bpy.types.Context) -> None:
    """Selecting a row shows its mismatch image."""
    _show_mismatch(self)


# ----------------------------------------------------------------------------
# property groups
# ----------------------------------------------------------------------------
class OMNIWARP_PG_result_row(bpy.types.PropertyGroup):
    """One measured row as the UI shows it; the full row is kept for export."""

    preset: StringProperty(name="Preset", description="The preset (or scene) this row measured")
    method: StringProperty(name="Method", description="Shadow method of this row, as the command line names it")
    resolution: IntProperty(name="Resolution", description="Side of each shadow map in texels")
    error_pct: FloatProperty(name="Error %", description="Mismatching evaluated pixels against Cycles, in percent",
                             precision=3)
    false_shadow_pct: FloatProperty(name="False shadow %", precision=3,
                                    description="Pixels Cycles lights but the method shadows, in percent")
    false_lit_pct: FloatProperty(name="False lit %", precision=3,
                                 description="Pixels Cycles shadows but the method lights, in percent")
    total_ms: FloatProperty(name="Total ms", description="Median time per frame over all stages, milliseconds",
                            precision=2)
    analysis_ms: FloatProperty(name="Analysis ms", precision=2,
                               description="Median time of the analysis (count maps and warps), milliseconds")
    maps_ms: FloatProperty(name="Maps ms", precision=2,
                           description="Median time of drawing the shadow maps, milliseconds")
    test_ms: FloatProperty(name="Test ms", precision=2,
                           description="Median time of the shadow test of every view sample, milliseconds")
    passes: IntProperty(name="Passes", description="Shadow-map passes drawn (paraboloid sides or cube faces)")
    mismatch_image: StringProperty(name="Mismatch image", subtype="FILE_PATH", options=_BLEND_RELATIVE,
                                   description="PNG of the pixels where this row disagrees with Cycles")


SOURCE_ITEMS = (
    ("PRESET", "Preset",
     "Measure a built-in preset scene. Its Cycles reference is cached, so a repeated run renders nothing", 0),
    ("CURRENT", "Current scene",
     "Measure this scene from its camera, with its one point or spot light (or the active light). "
     "Cost: two Cycles renders at the scene's resolution on every run (not cached)", 1),
)


class OMNIWARP_PG_comparison(bpy.types.PropertyGroup):
    """Settings and results of the comparison tool (`scene.omniwarp_compare`).

    One BoolProperty per pipeline method of the registry (`core/methods.py`: `use_dpsm`,
    `use_cube_notw`, ...) is added below the class, so a new method shows up here by itself.
    """

    source: EnumProperty(
        name="Source",
        description="What to measure: a preset scene or the current scene",
        items=SOURCE_ITEMS,
        default="PRESET",
    )
    preset: EnumProperty(
        name="Preset",
        description="The preset scene to measure (or to build into a new scene)",
        items=_preset_items,
        default=0,
    )
    camera_size: IntVectorProperty(
        name="Camera Size",
        description="Width and height of the preset's camera image: the Cycles reference's size and the "
                    "number of view samples. Larger costs a longer first render and a slower analysis "
                    "and shadow test",
        size=2,
        default=DEFAULT_RESOLUTION,
        min=8,
        max=8192,
        soft_max=3840,
        subtype="NONE",
    )
    resolutions: StringProperty(
        name="Resolutions",
        description="Comma-separated shadow-map resolutions in texels, e.g. 512,1024,2048. Each adds one row "
                    "per method; memory and fill time grow with the square",
        default="512,1024",
    )
    frames: IntProperty(
        name="Frames",
        description="Timed frames per row after one warm-up frame; times are their median. More frames "
                    "give steadier times and take longer",
        default=2,
        min=1,
        max=50,
    )
    cull: BoolProperty(
        name="Cull",
        description="Skip paraboloid sides and cube faces the view never touches (as the command line "
                    "does by default); off measures the unculled cost",
        default=True,
    )
    keep_previous: BoolProperty(
        name="Keep Previous",
        description="Add the new rows to the results instead of replacing them; the plot then shows "
                    "every run (e.g. several presets). No cost",
        default=False,
    )
    results: CollectionProperty(type=OMNIWARP_PG_result_row, name="Results",
                                description="The measured rows, one per method and resolution")
    active_result: IntProperty(
        name="Active Result",
        description="The selected row; its mismatch image is shown below the list",
        default=0,
        min=0,
        update=_active_result_changed,
    )
    status: StringProperty(name="Status", description="What the last or running comparison did or does")
    progress: FloatProperty(name="Progress", description="Share of the running comparison done",
                            default=0.0, min=0.0, max=1.0, subtype="FACTOR")
    plot_image: PointerProperty(type=bpy.types.Image, name="Plot",
                                description="The error-versus-time plot of the results (Pareto front per preset)")
    mismatch_preview: PointerProperty(type=bpy.types.Image, name="Mismatch",
                                      description="The selected row's mismatch image against Cycles")
    export_path: StringProperty(
        name="Export Path",
        description="File the Export button writes: .json (the full rows, as the command line's "
                    "results.json) or .csv (one line per row). // is the .blend file's folder",
        default="//omniwarp_results.json",
        subtype="FILE_PATH",
        options=_BLEND_RELATIVE,
    )

    @classmethod
    def unregister(cls) -> None:
        """Called by Blender when the class is unregistered: drop the module's state."""
        free_state()


for _method in method_registry.pipeline_methods():
    OMNIWARP_PG_comparison.__annotations__[method_prop(_method)] = BoolProperty(
        name=_method,
        description=_method_description(_method),
        default=_method in method_registry.DEFAULT_METHODS,
    )
del _method


def selected_methods(settings: OMNIWARP_PG_comparison) -> tuple[str, ...]:
    """The ticked methods, in registry order."""
    return tuple(m for m in method_registry.pipeline_methods() if getattr(settings, method_prop(m)))


# ----------------------------------------------------------------------------
# the comparison steps (shared by the modal and the synchronous paths)
# ----------------------------------------------------------------------------
def _safe_label(name: str) -> str:
    """A scene name usable in file names."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "scene"


def _scene_light(context: bpy.types.Context, scene: bpy.types.Scene) -> str | None:
    """The active object when it is a point, spot or sun light of the scene (else capture picks the only one)."""
    obj = getattr(context, "active_object", None)
    if (obj is not None and obj.type == "LIGHT" and obj.data.type in {"POINT", "SPOT", "SUN"}
            and obj.name in scene.objects):
        return obj.name
    return None


def _output_dir() -> Path:
    """A fresh folder for this run's plot and images (in Blender's session temp folder)."""
    base = Path(bpy.app.tempdir) if bpy.app.tempdir else Path(tempfile.gettempdir())
    return Path(tempfile.mkdtemp(prefix="omniwarp_compare_", dir=base))


def start_job(context: bpy.types.Context, report_fn: Report) -> _Job | None:
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
        light_name = _scene_light(context, scene)
    out_dir = _output_dir()
    images = have_matplotlib()
    if not images:
        report_fn({"WARNING"}, "matplotlib is not installed in Blender's Python: measuring without the plot "
                               "and the mismatch images")
    options = compare.CompareOptions(methods=methods, resolutions=resolutions, cull=bool(settings.cull),
                                     frames=int(settings.frames), out_dir=out_dir, write_images=images)
    keep = list(_ROWS.get(scene.session_uid, [])) if settings.keep_previous else []
    if not settings.keep_previous:
        settings.results.clear()
        settings.active_result = 0
    job = _Job(scene_name=scene.name, scene_uid=scene.session_uid, source=settings.source, preset=preset,
               camera_size=(int(settings.camera_size[0]), int(settings.camera_size[1])), light_name=light_name,
               tasks=[(m, r) for m in methods for r in resolutions], options=options, out_dir=out_dir,
               image_dir=out_dir / "images" if images else None, keep_rows=keep)
    _ROWS[scene.session_uid] = list(keep)
    settings.progress = 0.0
    settings.status = f"Starting: {_rows_text(len(job.tasks))} of {preset}"
    log.info("comparison of %s: %d rows into %s", preset, len(job.tasks), out_dir)
    return job


def _find_scene(job: _Job) -> bpy.types.Scene | None:
    """The job's scene, by session uid (a renamed scene is still found; another file's is not)."""
    for scene in bpy.data.scenes:
        if scene.session_uid == job.scene_uid:
            return scene
    return None


def _job_scene(job: _Job) -> bpy.types.Scene:
    scene = _find_scene(job)
    if scene is None:
        raise InputError(f"scene {job.scene_name!r} was removed during the comparison")
    return scene


def _load_reference(job: _Job) -> None:
    """Step 0: the Cycles reference (cached for presets) and the Blender-gpu pipeline."""
    from ..reference.cache import load_or_capture
    from ..reference.capture import capture
    from ..render.blender_backend import BlenderGPUBackend, ensure_gpu
    from ..render.pipeline import ShadowPipeline

    if job.source == "PRESET":
        reference = load_or_capture(job.preset, job.camera_size)
    else:
        reference = capture(_job_scene(job), light=job.light_name)
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


def _drop_unfit_tasks(job: _Job) -> str:
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


def step_job(job: _Job) -> str:
    """Do the next step (the reference, or one row); returns what it did."""
    scene = _job_scene(job)
    settings = scene.omniwarp_compare
    if job.reference is None:
        start = time.perf_counter()
        _load_reference(job)
        done = f"reference of {job.preset} ready in {time.perf_counter() - start:.1f} s"
        done += _drop_unfit_tasks(job)
    else:
        method, resolution = job.tasks[job.next_task]
        start = time.perf_counter()
        if job.scene is None:
            job.scene = compare.resident_scene(job.reference)
        row = compare.run_row(job.pipeline, job.reference, job.preset, method, resolution, job.options,
                              job.image_dir, job.scene)
        job.row_seconds.append(time.perf_counter() - start)
        job.rows.append(_absolute_paths(row, job.out_dir))
        _ROWS.setdefault(scene.session_uid, []).append(row)
        _store_row(settings, row)
        job.next_task += 1
        done = f"{method} @ {resolution}: {row['error_pct']:.3f} % error, {row['time_ms']['total']:.1f} ms"
    settings.progress = job.steps_done / job.total_steps
    settings.status = status_line(job)
    return done


def status_line(job: _Job) -> str:
    """'row i/N: method @ res, 12 s elapsed, ~30 s left' for the step about to run."""
    elapsed = time.perf_counter() - job.started
    if job.reference is None:
        what = f"Cycles reference of {job.preset}" if job.source == "PRESET" else "Cycles reference of the scene"
        return f"OmniWarp: {what} ({elapsed:.0f} s elapsed)"
    if job.finished:
        return f"OmniWarp: {_rows_text(len(job.tasks))} measured in {elapsed:.1f} s"
    method, resolution = job.tasks[job.next_task]
    left = job.seconds_left()
    eta = "estimating" if left is None else f"~{left:.0f} s left"
    return (f"OmniWarp: row {job.next_task + 1}/{len(job.tasks)} {method} @ {resolution} "
            f"({elapsed:.0f} s elapsed, {eta})")


def finish_job(job: _Job, report_fn: Report, outcome: str = "done", message: str = "") -> None:
    """Release the GPU, write and load the plot, set the status. `outcome`: done, cancelled, failed."""
    job.release()
    scene = _find_scene(job)
    settings = scene.omniwarp_compare if scene is not None else None
    rows = job.keep_rows + job.rows
    elapsed = time.perf_counter() - job.started
    if outcome == "done":
        text = f"{_rows_text(len(job.rows))} measured in {elapsed:.1f} s"
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


def _rows_text(count: int) -> str:
    return f"{count} row" + ("" if count == 1 else "s")


def _select_first_new_row(settings: OMNIWARP_PG_comparison, first: int) -> None:
    """Select the run's first row (its mismatch image is loaded by the update callback)."""
    if 0 <= first < len(settings.results):
        if settings.active_result == first:
            _show_mismatch(settings)
        else:
            settings.active_result = first


def _failure(exc: BaseException) -> str:
    return str(exc) if isinstance(exc, OmniWarpError) else f"{type(exc).__name__}: {exc}"


# ----------------------------------------------------------------------------
# export
# ----------------------------------------------------------------------------
def rows_for_export(scene: bpy.types.Scene) -> list[dict]:
    """The full rows of the scene's last run; rebuilt from the stored rows when this
    session has none (e.g. after reopening the .blend file)."""
    settings = scene.omniwarp_compare
    rows = _ROWS.get(scene.session_uid, [])
    if len(rows) == len(settings.results):
        return list(rows)
    return [{
        "preset": item.preset, "method": item.method, "resolution": item.resolution,
        "error_pct": item.error_pct, "false_shadow_pct": item.false_shadow_pct,
        "false_lit_pct": item.false_lit_pct,
        "time_ms": {"total": item.total_ms, "analysis": item.analysis_ms, "shadow_maps": item.maps_ms,
                    "shadow_test": item.test_ms},
        "passes": item.passes, "mismatch_image": item.mismatch_image,
    } for item in settings.results]


def flatten_row(row: dict) -> dict:
    """One CSV line: time_ms.* as their own columns, other lists and dicts as JSON text."""
    flat: dict[str, Any] = {}
    for key, value in row.items():
        if key == "time_ms":
            flat.update({f"time_ms.{k}": v for k, v in value.items()})
        elif isinstance(value, (dict, list, tuple)):
            flat[key] = json.dumps(value, sort_keys=True)
        else:
            flat[key] = value
    return flat


def write_rows(rows: list[dict], path: Path) -> None:
    """JSON (the command line's results.json format) or CSV, by the file's suffix."""
    suffix = path.suffix.lower()
    if suffix == ".json":
        path.write_text(json.dumps(rows, indent=1), encoding="utf-8")
    elif suffix == ".csv":
        flat = [flatten_row(row) for row in rows]
        columns: list[str] = []
        for line in flat:
            columns += [key for key in line if key not in columns]
        with path.open("w", newline="", encoding="utf-8") as stream:
            writer = csv.DictWriter(stream, fieldnames=columns)
            writer.writeheader()
            writer.writerows(flat)
    else:
        raise InputError(f"export file {path.name!r} must end with .json or .csv")


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
            finish_job(job, self.report, "failed", _failure(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        finish_job(job, self.report)
        return {"FINISHED"}

    # modal ---------------------------------------------------------------------
    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        global _ACTIVE
        if context.window is None:
            return self.execute(context)
        job = start_job(context, self.report)
        if job is None:
            return {"CANCELLED"}
        _ACTIVE = job
        wm = context.window_manager
        job.timer = wm.event_timer_add(TIMER_STEP_S, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, job.total_steps)
        _set_status_text(context, status_line(job) + " | Esc: cancel")
        redraw_3d_views()
        return {"RUNNING_MODAL"}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        job = _ACTIVE
        if job is None:  # freed by unregister
            _stop_modal(None, context)
            return {"CANCELLED"}
        if event.type in {"ESC", "RIGHTMOUSE"} and event.value == "PRESS":
            _stop_modal(job, context)
            finish_job(job, self.report, "cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            log.info(step_job(job))
        except Exception as exc:  # noqa: BLE001 - any failure must end the run cleanly (logged, reported)
            log.exception("OmniWarp comparison failed")
            _stop_modal(job, context)
            finish_job(job, self.report, "failed", _failure(exc))
            return {"CANCELLED"}
        context.window_manager.progress_update(job.steps_done)
        if job.finished:
            _stop_modal(job, context)
            finish_job(job, self.report)
            return {"FINISHED"}
        _set_status_text(context, status_line(job) + " | Esc: cancel")
        redraw_3d_views()
        return {"PASS_THROUGH"}

    def cancel(self, context: bpy.types.Context) -> None:
        """Blender ends the modal (window closed, file loaded): clean up, keep the rows."""
        job = _ACTIVE
        _stop_modal(job, context)
        if job is not None:
            finish_job(job, self.report, "cancelled")


def _remove_timer(job: _Job, wm: bpy.types.WindowManager | None) -> None:
    if job.timer is not None and wm is not None:
        wm.event_timer_remove(job.timer)
    job.timer = None


def _stop_modal(job: _Job | None, context: bpy.types.Context) -> None:
    """Timer, progress and status text off; no job is active any more."""
    global _ACTIVE
    _ACTIVE = None
    wm = context.window_manager
    if job is not None:
        _remove_timer(job, wm)
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
        self.report({"INFO"}, f"Wrote {_rows_text(len(rows))} to {path}" + (" (replaced the old file)" if existed else ""))
        return {"FINISHED"}


# ----------------------------------------------------------------------------
# UI
# ----------------------------------------------------------------------------
class OMNIWARP_UL_results(bpy.types.UIList):
    """One line per measured row: method, resolution, error %, total ms, passes."""

    bl_idname = "OMNIWARP_UL_results"

    def draw_item(self, context: bpy.types.Context, layout: bpy.types.UILayout, data: Any,
                  item: OMNIWARP_PG_result_row, icon: int, active_data: Any, active_propname: str,
                  index: int = 0, flt_flag: int = 0) -> None:
        if self.layout_type == "GRID":
            layout.alignment = "CENTER"
            layout.label(text=f"{item.error_pct:.2f}%")
            return
        row = layout.row(align=True)
        row.label(text=item.method)
        row.label(text=str(item.resolution))
        row.label(text=f"{item.error_pct:.3f} %")
        row.label(text=f"{item.total_ms:.1f} ms")
        row.label(text=f"{item.passes} p")


def _wrapped(layout: bpy.types.UILayout, text: str, width: int) -> None:
    """Labels of about `width` characters each (Blender's labels do not wrap)."""
    column = layout.column(align=True)
    column.scale_y = 0.8
    for line in textwrap.wrap(text, max(width, 20)):
        column.label(text=line)


def _draw_image(layout: bpy.types.UILayout, image: bpy.types.Image | None, title: str) -> None:
    if image is None:
        return
    box = layout.box()
    box.label(text=title, icon="IMAGE_DATA")
    preview = image.preview if image.preview is not None else image.preview_ensure()
    if preview is None:
        box.label(text=f"No preview of {image.name!r}")
        return
    box.template_icon(icon_value=preview.icon_id, scale=IMAGE_ICON_SCALE)


class OMNIWARP_PT_compare(bpy.types.Panel):
    """Compare the shadow methods against Cycles (3D viewport sidebar, tab OmniWarp)."""

    bl_idname = "OMNIWARP_PT_compare"
    bl_label = "Compare methods"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = SIDEBAR_CATEGORY
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return getattr(getattr(context, "scene", None), "omniwarp_compare", None) is not None

    def draw(self, context: bpy.types.Context) -> None:
        settings = context.scene.omniwarp_compare
        layout = self.layout
        region = getattr(context, "region", None)
        chars = int(getattr(region, "width", 280) / 7) - 4

        layout.prop(settings, "source", expand=True)
        if settings.source == "PRESET":
            row = layout.row(align=True)
            row.prop(settings, "preset", text="")
            row.operator(OMNIWARP_OT_build_preset.bl_idname, text="Build", icon="SCENE_DATA")
            info = preset_info(settings.preset)
            if info is not None:
                _wrapped(layout, f"{info.description}. Stresses: {info.stresses}", chars)
            layout.prop(settings, "camera_size")
        else:
            scene = context.scene
            camera = scene.camera.name if scene.camera is not None else "none (add one)"
            light = _scene_light(context, scene) or "the scene's only point/spot light"
            _wrapped(layout, f"Camera: {camera}. Light: {light}. Two Cycles renders per run.", chars)

        box = layout.box()
        box.label(text="Methods")
        grid = box.grid_flow(row_major=True, columns=2, even_columns=True, align=True)
        for method in method_registry.pipeline_methods():
            grid.prop(settings, method_prop(method))
        layout.prop(settings, "resolutions")
        row = layout.row()
        row.prop(settings, "frames")
        row.prop(settings, "cull")
        layout.prop(settings, "keep_previous")

        row = layout.row()
        row.scale_y = 1.4
        row.operator(OMNIWARP_OT_compare.bl_idname, icon="PLAY")
        if is_running():
            layout.progress(factor=settings.progress, type="BAR", text=settings.status or "Running")
            layout.label(text="Esc or right-click cancels", icon="INFO")
        elif settings.status:
            _wrapped(layout, settings.status, chars)

        layout.template_list(OMNIWARP_UL_results.bl_idname, "", settings, "results", settings, "active_result",
                             rows=4)
        if 0 <= settings.active_result < len(settings.results):
            item = settings.results[settings.active_result]
            col = layout.column(align=True)
            col.label(text=f"{item.preset} / {item.method} @ {item.resolution}")
            col.label(text=f"false shadow {item.false_shadow_pct:.3f} %, false lit {item.false_lit_pct:.3f} %")
            col.label(text=f"analysis {item.analysis_ms:.1f}, maps {item.maps_ms:.1f}, "
                           f"test {item.test_ms:.1f} ms")
        _draw_image(layout, settings.plot_image, "Error vs time")
        _draw_image(layout, settings.mismatch_preview, "Mismatch of the selected row")

        row = layout.row(align=True)
        row.prop(settings, "export_path", text="")
        row.operator(OMNIWARP_OT_export_results.bl_idname, text="Export", icon="EXPORT")


CLASSES: tuple[type, ...] = (
    OMNIWARP_PG_result_row,
    OMNIWARP_PG_comparison,
    OMNIWARP_OT_build_preset,
    OMNIWARP_OT_compare,
    OMNIWARP_OT_export_results,
    OMNIWARP_UL_results,
    OMNIWARP_PT_compare,
)
