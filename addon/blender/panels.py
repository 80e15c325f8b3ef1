"""OmniWarp panels: per-light settings in the Light properties, and the shadow
preview (with its map overlay) in the 3D viewport's sidebar, tab "OmniWarp"."""
from __future__ import annotations

import logging

import bpy

from ..readers import light_size
from ..compat import blender as blender_compat
from . import events
from .properties import (
    EXACT_PARAMETERIZATIONS,
    effective_emission,
    effective_parameterization,
    effective_warp,
    enabled_light_objects,
    is_narrow_spot,
    is_supported_light,
    settings_problem,
    stored_parameterization,
    takes_warp,
    valid_parameterizations,
)

log = logging.getLogger(__name__)

SIDEBAR_CATEGORY = "OmniWarp"

_EMISSION_LABELS = {
    "omni": "Omnidirectional",
    "hemi": "Hemispherical",
    "spot": "Spot cone",
    "sun": "Sun (parallel)",
}
# Light types whose emission the user may choose (a sun's light is always parallel).
_EMISSION_CHOICE_TYPES = ("POINT", "SPOT")


def _light_summary(light: bpy.types.Light) -> str:
    """One line describing what is previewed for a light, e.g. 'DPSM + NOTW, 1024 px, hemi'.

    It names what the pipeline gets (the effective method and warp), not what is stored.
    """
    parameterization = effective_parameterization(light)
    method = parameterization.upper()
    warp = effective_warp(light, parameterization).upper()
    if warp != "NONE":
        method = f"{method} + {warp}"
    return f"{method}, {light.omniwarp.resolution} px, {effective_emission(light)}"


def _note(layout: bpy.types.UILayout, text: str) -> None:
    """A right-aligned info line under the setting it explains."""
    row = layout.row()
    row.alignment = "RIGHT"
    row.label(text=text, icon="INFO")


def draw_line_gaps(layout: bpy.types.UILayout) -> None:
    """One line per API this Blender line lacks (docs/versions.md); nothing on 5.2."""
    for gap in blender_compat.line_gaps():
        layout.label(text=gap.text, icon="INFO")


class OMNIWARP_PT_light(bpy.types.Panel):
    """OmniWarp shadow settings of the active light (Properties editor, Light tab)."""

    bl_idname = "OMNIWARP_PT_light"
    bl_label = "OmniWarp Shadows"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "data"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return is_supported_light(getattr(context, "light", None))

    def draw_header(self, context: bpy.types.Context) -> None:
        self.layout.prop(context.light.omniwarp, "enabled", text="")

    def draw(self, context: bpy.types.Context) -> None:
        light = context.light
        props = light.omniwarp
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.active = props.enabled

        problem = settings_problem(light, getattr(context, "object", None))
        if problem:
            # A NaN or infinite value set from Python: the preview pauses instead of drawing it.
            alert = layout.box()
            alert.alert = True
            alert.label(text="Cannot be drawn, preview paused:", icon="ERROR")
            alert.label(text=problem[:120])

        emission = effective_emission(light)
        if light.type in _EMISSION_CHOICE_TYPES:
            layout.prop(props, "emission")
        if props.emission == "AUTO" or light.type not in _EMISSION_CHOICE_TYPES:
            row = layout.row()
            row.alignment = "RIGHT"
            row.label(text=f"Treated as: {_EMISSION_LABELS[emission]}")
        if props.emission == "OMNI" and is_narrow_spot(light):
            _note(layout, "Spot narrower than 179°: shadowed in all directions")

        layout.prop(props, "parameterization")
        parameterization = effective_parameterization(light)
        if stored_parameterization(light) not in valid_parameterizations(light):
            # Only before Blender 5.0: there the field shows a stale choice as blank.
            _note(layout, f"Stored method does not fit this light: using {parameterization.upper()}")

        # Greyed out rather than hidden, so the stored warp is still visible for
        # when the light goes back to a method that takes one.
        row = layout.row()
        row.active = takes_warp(parameterization)
        row.prop(props, "warp")
        if not takes_warp(parameterization):
            _note(layout, f"{parameterization.upper()} takes no warp")
        layout.prop(props, "resolution")
        # Greyed out, like the warp, where the method draws no footprints.
        row = layout.row()
        row.active = parameterization in EXACT_PARAMETERIZATIONS
        row.prop(props, "exact")

        box = layout.box()
        box.label(text="Bias (texel footprints)")
        col = box.column(align=True)
        col.prop(props, "bias_constant")
        col.prop(props, "bias_slope")
        col.prop(props, "bias_normal")

        # Every light type with a size is softened (render/soft.py): the filter's points, or
        # the exact pass's.
        if light_size.has_size(light):
            box = layout.box()
            box.label(text="Soft shadows (the light's size)")
            col = box.column(align=True)
            if props.exact and parameterization in EXACT_PARAMETERIZATIONS:
                col.prop(props, "exact_samples")  # the exact pass samples the light itself
            else:
                col.prop(props, "light_samples")
                col.prop(props, "search_samples")
        layout.prop(props, "cull")
        draw_line_gaps(layout)


def _preview_error() -> str:
    """The viewport preview's last failure (none while it is not registered)."""
    return events.notify("last_error", default="")


class OMNIWARP_PT_viewport(bpy.types.Panel):
    """The viewport shadow preview: on/off, look and cost settings, and what it previews."""

    bl_idname = "OMNIWARP_PT_viewport"
    bl_label = "Shadow preview"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = SIDEBAR_CATEGORY

    def draw(self, context: bpy.types.Context) -> None:
        scene = context.scene
        settings = scene.omniwarp
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False

        layout.prop(settings, "preview_enabled")
        col = layout.column()
        col.active = settings.preview_enabled
        col.prop(settings, "shadow_strength")
        col.prop(settings, "camera_resolution_scale")
        col.prop(settings, "throttle_ms")
        error = _preview_error()
        if error:
            alert = layout.box()
            alert.alert = True
            alert.label(text="Preview paused after an error:", icon="ERROR")
            alert.label(text=error[:120])

        box = layout.box()
        lights = enabled_light_objects(scene)
        if not lights:
            box.label(text="No light has OmniWarp enabled", icon="INFO")
            box.label(text="Enable it in a point, spot, sun or area light's properties")
            return
        box.label(text=f"Previewed lights ({len(lights)})")
        for obj in lights:
            row = box.row()
            row.label(text=obj.name, icon="LIGHT")
            row.label(text=_light_summary(obj.data))


class OMNIWARP_PT_overlay(bpy.types.Panel):
    """Overlay of the shadow, count and importance maps (sub-panel of the preview)."""

    bl_idname = "OMNIWARP_PT_overlay"
    bl_label = "Map overlay"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = SIDEBAR_CATEGORY
    bl_parent_id = "OMNIWARP_PT_viewport"

    def draw_header(self, context: bpy.types.Context) -> None:
        self.layout.prop(context.scene.omniwarp, "overlay_enabled", text="")

    def draw(self, context: bpy.types.Context) -> None:
        settings = context.scene.omniwarp
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.active = settings.overlay_enabled

        layout.prop(settings, "overlay_maps", expand=True)
        layout.prop(settings, "overlay_size")
        layout.prop(settings, "overlay_corner")
        layout.prop(settings, "overlay_stats")


CLASSES: tuple[type, ...] = (OMNIWARP_PT_light, OMNIWARP_PT_viewport, OMNIWARP_PT_overlay)
