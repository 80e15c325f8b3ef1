"""The comparison tool's sidebar panel (tab "OmniWarp") and its results list."""
from __future__ import annotations

import textwrap
from typing import Any

import bpy

from ..core import methods as method_registry
from .compare_job import scene_light, is_running
from .compare_ops import OMNIWARP_OT_build_preset, OMNIWARP_OT_compare, OMNIWARP_OT_export_results
from .compare_props import (
    IMAGE_ICON_SCALE,
    OMNIWARP_PG_comparison,
    OMNIWARP_PG_result_row,
    method_prop,
    preset_info,
    preset_summary,
)
from .panels import SIDEBAR_CATEGORY, draw_line_gaps  # one tab for the preview and the comparison


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
        row.label(text=f"{item.passes} p", icon="ERROR" if item.note else "NONE")


def _wrapped(layout: bpy.types.UILayout, text: str, width: int, icon: str = "NONE") -> None:
    """Labels of about `width` characters each (Blender's labels do not wrap); `icon` on the first."""
    column = layout.column(align=True)
    column.scale_y = 0.8
    for index, line in enumerate(textwrap.wrap(text, max(width, 20))):
        column.label(text=line, icon=icon if index == 0 else "BLANK1" if icon != "NONE" else "NONE")


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
                _wrapped(layout, preset_summary(info), chars)
            layout.prop(settings, "camera_size")
        else:
            scene = context.scene
            camera = scene.camera.name if scene.camera is not None else "none (add one)"
            light = scene_light(context, scene) or "the scene's only point/spot light"
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
        row.prop(settings, "hard")
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
            for note in filter(None, item.note.split("; ")):
                _wrapped(col, note, chars, icon="ERROR")
        _draw_image(layout, settings.plot_image, "Error vs time")
        _draw_image(layout, settings.mismatch_preview, "Mismatch of the selected row")

        row = layout.row(align=True)
        row.prop(settings, "export_path", text="")
        row.operator(OMNIWARP_OT_export_results.bl_idname, text="Export", icon="EXPORT")
        draw_line_gaps(layout)


CLASSES: tuple[type, ...] = (
    OMNIWARP_PG_result_row,
    OMNIWARP_PG_comparison,
    OMNIWARP_OT_build_preset,
    OMNIWARP_OT_compare,
    OMNIWARP_OT_export_results,
    OMNIWARP_UL_results,
    OMNIWARP_PT_compare,
)
