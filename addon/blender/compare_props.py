"""The comparison tool's settings: the per-scene property groups, the method checkboxes,
the preset list and the plot and mismatch images (see compare_job.py for the run,
compare_ops.py for the operators and compare_ui.py for the panel).

* `OMNIWARP_PG_comparison` hangs on every scene as `bpy.types.Scene.omniwarp_compare`:
  the source (a preset or the current scene), the methods, resolutions and frames,
  the measured rows (`OMNIWARP_PG_result_row`), the status line and the plot.
* One BoolProperty per pipeline method of the registry ticks it.

The plot and the mismatch images need numpy only: `omniwarp compare` draws the plot with
matplotlib where it is installed, and a stock Blender (no matplotlib) with the built-in
painter, core/raster_plot.py; the images are written by core/png.py.
"""
from __future__ import annotations

import logging
import re
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

from ..core import methods as method_registry
from ..core.errors import OmniWarpError
from ..core.presets import DEFAULT_PRESET, DEFAULT_RESOLUTION, PresetInfo, available_presets

log = logging.getLogger(__name__)

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
        _PRESET_ITEMS.append((name, name, preset_summary(info), number))
    if not _PRESET_ITEMS:
        _PRESET_ITEMS.append(_NO_PRESET)


def preset_summary(info: Any) -> str:
    """A preset's line for its tooltip and the panel: what it is, then what it stresses."""
    return f"{info.description.rstrip('.')}. Stresses: {info.stresses}"


def _preset_items(_self: Any, _context: Any) -> list[tuple[str, str, str, int]]:
    """EnumProperty items callback: every preset, name and description (as the tooltip)."""
    _load_presets()
    return _PRESET_ITEMS


def clear_presets() -> None:
    """Forget the preset caches (on unregister: the next listing reads the folder again)."""
    _PRESET_ITEMS.clear()
    _PRESET_INFO.clear()


def preset_info(name: str) -> PresetInfo | None:
    """The PresetInfo of a preset shown in the enum, or None."""
    _load_presets()
    return _PRESET_INFO.get(name)


# ----------------------------------------------------------------------------
# images
# ----------------------------------------------------------------------------
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


def show_mismatch(settings: OMNIWARP_PG_comparison) -> None:
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
    show_mismatch(self)


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
    note: StringProperty(name="Note", description="What this row leaves out of the scene as Cycles renders "
                                                  "it (geometry no method draws, the method's own limits)")


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
    hard: BoolProperty(
        name="Hard Light",
        description="Give the light no size in the Cycles reference (radius 0, a sun's angle 0, a tiny area "
                    "light), as the shadow maps assume: the hard-shadow study. Off: the light as the file "
                    "has it, with its penumbrae (a sized light renders 256 samples, slower)",
        default=False,
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
