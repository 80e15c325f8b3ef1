"""OmniWarp settings stored in .blend files, and the helpers that turn them into
pipeline inputs.

* `OMNIWARP_PG_light` hangs on every light as `bpy.types.Light.omniwarp`: the
  per-light shadow method (parameterization, warp, resolution, bias, culling).
* `OMNIWARP_PG_scene` hangs on every scene as `bpy.types.Scene.omniwarp`: the
  viewport preview and its map overlay.

Every tooltip says what a setting does and what it costs. Changing a setting
marks the viewport preview stale through `viewport.request_update()`; the
viewport module is looked up lazily, so this module imports (and registers)
without it.
"""
from __future__ import annotations

import importlib
import importlib.util
import logging
import math
from types import ModuleType

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

from ..core.scene import Emission, LightSpec
from ..render.pipeline import BiasSettings, ShadowSettings

log = logging.getLogger(__name__)

SUPPORTED_LIGHT_TYPES: tuple[str, ...] = ("POINT", "SPOT")
# A spot this wide (or wider) is a hemispherical light. spot_size is stored as a
# float32, so allow its rounding error below the threshold.
HEMI_SPOT_SIZE = math.radians(179.0)
_SPOT_SIZE_TOLERANCE = 1e-6

RESOLUTION_MIN = 256
RESOLUTION_MAX = 4096
RESOLUTION_DEFAULT = 1024


# ----------------------------------------------------------------------------
# update callbacks: the viewport module is optional at import time
# ----------------------------------------------------------------------------
def _viewport_module() -> ModuleType | None:
    """The sibling `viewport` module, or None while it is not importable."""
    name = f"{__package__}.viewport"
    if importlib.util.find_spec(name) is None:
        return None
    return importlib.import_module(name)


def _notify_viewport(action: str, *args) -> None:
    """Call `viewport.<action>(*args)` if the viewport module is importable (tests may lack it)."""
    viewport = _viewport_module()
    if viewport is None:
        log.debug("viewport module not available; %s skipped", action)
        return
    getattr(viewport, action)(*args)


def _request_update(self: bpy.types.PropertyGroup, context: bpy.types.Context) -> None:
    """Property update callback: mark the viewport preview stale."""
    _notify_viewport("request_update", "light settings")


def _request_scene_update(self: bpy.types.PropertyGroup, context: bpy.types.Context) -> None:
    """Update callback of scene-level preview settings: mark the preview stale."""
    _notify_viewport("request_update", "preview settings")


def _overlay_changed(self: bpy.types.PropertyGroup, context: bpy.types.Context) -> None:
    """Overlay settings change only the drawing, not the maps: redraw the viewports."""
    _notify_viewport("tag_redraw_all")


def _preview_toggled(self: OMNIWARP_PG_scene, context: bpy.types.Context) -> None:
    """Turn the viewport preview on or off to match `preview_enabled`."""
    viewport = _viewport_module()
    if viewport is None:
        log.warning("OmniWarp viewport module is not available; preview cannot be toggled")
        return
    viewport.set_preview_enabled(context, bool(self.preview_enabled))


# ----------------------------------------------------------------------------
# per light
# ----------------------------------------------------------------------------
EMISSION_ITEMS = (
    ("AUTO", "From light type",
     "Point light: omnidirectional. Spot light with a cone of 179° or more: hemispherical. "
     "Narrower spots are treated as omnidirectional (all directions are shadowed; the cone only "
     "shapes the light), which costs as much as a point light", 0),
    ("OMNI", "Omnidirectional",
     "Shadows in every direction around the light. Cost: both paraboloid sides or all six cube faces "
     "(fewer when culling skips what the view never touches)", 1),
    ("HEMI", "Hemispherical",
     "Shadows only in the half space along the light's local -Z. Cost: one paraboloid side, "
     "at most five cube faces", 2),
)

PARAMETERIZATION_ITEMS = (
    ("DPSM", "Dual paraboloid",
     "Two paraboloid maps, one per hemisphere. Cost: at most two passes, but triangles that the "
     "curved projection bends are tessellated first (more triangles, more CPU time)", 0),
    ("CUBE", "Cube",
     "Six 90° perspective faces. Cost: up to six passes (each redraws the geometry it sees), "
     "no tessellation", 1),
)

WARP_ITEMS = (
    ("NONE", "None",
     "Uniform shadow map: no analysis pass, no extra triangles", 0),
    ("NOTW", "NoTW",
     "Non-orthogonal texture warping: moves map resolution to where the camera needs it. "
     "Cost: an analysis pass over the view samples, plus more triangles (warped edges are "
     "tessellated)", 1),
    ("RTW", "RTW",
     "Rectilinear texture warping (Rosen 2012), offered as a comparison to NoTW. "
     "Cost: the same analysis pass, plus more triangles", 2),
)


class OMNIWARP_PG_light(bpy.types.PropertyGroup):
    """OmniWarp shadow settings of one light (`light.omniwarp`)."""

    enabled: BoolProperty(
        name="OmniWarp Shadows",
        description="Draw this light's shadows with OmniWarp in the viewport preview and comparisons. "
                    "Cost: shadow-map passes and GPU memory for this light on every preview update",
        default=False,
        update=_request_update,
    )
    emission: EnumProperty(
        name="Emission",
        description="Which directions receive light (and so need shadow maps). "
                    "Hemispherical needs about half the passes of omnidirectional",
        items=EMISSION_ITEMS,
        default="AUTO",
        update=_request_update,
    )
    parameterization: EnumProperty(
        name="Parameterization",
        description="How directions around the light map onto shadow-map texels. "
                    "Dual paraboloid: two passes and tessellation. Cube: up to six passes",
        items=PARAMETERIZATION_ITEMS,
        default="DPSM",
        update=_request_update,
    )
    warp: EnumProperty(
        name="Warp",
        description="Redistribute shadow-map resolution toward what the camera sees. "
                    "Any warp costs an analysis pass and extra triangles",
        items=WARP_ITEMS,
        default="NONE",
        update=_request_update,
    )
    resolution: IntProperty(
        name="Resolution",
        description="Side of each shadow map in texels: sharper shadows, but memory and fill time grow "
                    "with its square (cube: 6 × resolution² floats, dual paraboloid: 2 × resolution² floats)",
        default=RESOLUTION_DEFAULT,
        min=RESOLUTION_MIN,
        max=RESOLUTION_MAX,
        subtype="NONE",
        update=_request_update,
    )
    bias_constant: FloatProperty(
        name="Constant",
        description="Constant depth bias, in units of one shadow texel's footprint at the surface. "
                    "Removes acne; too much detaches shadows from their casters (peter-panning). "
                    "No run-time cost",
        default=0.3,
        min=0.0,
        soft_min=0.0,
        soft_max=4.0,
        update=_request_update,
    )
    bias_slope: FloatProperty(
        name="Slope",
        description="Extra depth bias that grows with the receiver's slope to the light, in texel "
                    "footprints. Removes acne on grazing surfaces; too much causes light leaks. "
                    "No run-time cost",
        default=0.7,
        min=0.0,
        soft_min=0.0,
        soft_max=4.0,
        update=_request_update,
    )
    bias_normal: FloatProperty(
        name="Normal",
        description="Offset of the tested point along the surface normal, in texel footprints. "
                    "Removes acne without pushing the whole shadow away; too much thins contact "
                    "shadows. No run-time cost",
        default=0.7,
        min=0.0,
        soft_min=0.0,
        soft_max=4.0,
        update=_request_update,
    )
    cull: BoolProperty(
        name="Cull",
        description="Skip paraboloid sides and cube faces the view never touches, and objects outside "
                    "them. Saves passes and triangles; turn off only to measure the unculled cost",
        default=True,
        update=_request_update,
    )


def is_supported_light(light: bpy.types.Light | None) -> bool:
    """True for the light types OmniWarp shadows: POINT and SPOT."""
    return light is not None and getattr(light, "type", None) in SUPPORTED_LIGHT_TYPES


def enabled_light_objects(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """The scene's light objects of a supported type with OmniWarp enabled, by name."""
    found = [
        obj for obj in scene.objects
        if obj.type == "LIGHT" and is_supported_light(obj.data) and obj.data.omniwarp.enabled
    ]
    return sorted(found, key=lambda obj: obj.name)


def effective_emission(light: bpy.types.Light) -> Emission:
    """'omni' or 'hemi' for a light, resolving AUTO by its type.

    AUTO: a POINT is omni; a SPOT whose spot_size (radians) is at least 179° is
    hemi; narrower spots are treated as omni.
    """
    choice = light.omniwarp.emission
    if choice == "OMNI":
        return "omni"
    if choice == "HEMI":
        return "hemi"
    if light.type == "SPOT" and float(light.spot_size) >= HEMI_SPOT_SIZE - _SPOT_SIZE_TOLERANCE:
        return "hemi"
    return "omni"


def _ui_float(value: float) -> float:
    """A float32 RNA value as the decimal the user typed (0.30000001 -> 0.3).

    Six decimals are far below any bias that matters, and the defaults then equal
    `BiasSettings()` exactly, so settings from the UI compare equal to the pipeline's.
    """
    return round(float(value), 6)


def shadow_settings_for(light: bpy.types.Light) -> ShadowSettings:
    """The pipeline's `ShadowSettings` for a light's OmniWarp properties."""
    props = light.omniwarp
    return ShadowSettings(
        parameterization=props.parameterization.lower(),
        resolution=int(props.resolution),
        bias=BiasSettings(
            constant=_ui_float(props.bias_constant),
            slope=_ui_float(props.bias_slope),
            normal=_ui_float(props.bias_normal),
        ),
        cull=bool(props.cull),
        warp=props.warp.lower(),
    )


def light_spec_for(obj: bpy.types.Object) -> LightSpec:
    """A `LightSpec` for an (evaluated) light object: its world matrix and effective emission."""
    light = obj.data
    if not isinstance(light, bpy.types.Light):
        raise TypeError(f"object {obj.name!r} is not a light")
    matrix = np.array([list(row) for row in obj.matrix_world], dtype=np.float64)
    return LightSpec(
        emission=effective_emission(light),
        matrix_world=matrix,
        energy=float(light.energy),
    )


# ----------------------------------------------------------------------------
# per scene: preview and overlay
# ----------------------------------------------------------------------------
OVERLAY_MAP_ITEMS = (
    ("DEPTH", "Depth",
     "The shadow maps' depth (paraboloid sides or cube faces). Cost: one read-back per map", 1),
    ("COUNT", "Count",
     "View samples per shadow texel: where the map lacks or wastes resolution. "
     "Cost: the analysis pass when the light is not warped", 2),
    ("IMPORTANCE", "Importance",
     "The count map after warping: how evenly the warp spread the resolution. "
     "Only for warped lights", 4),
)

OVERLAY_CORNER_ITEMS = (
    ("BOTTOM_LEFT", "Bottom left", "Draw the map overlay in the viewport's bottom-left corner", 0),
    ("BOTTOM_RIGHT", "Bottom right", "Draw the map overlay in the viewport's bottom-right corner", 1),
    ("TOP_LEFT", "Top left", "Draw the map overlay in the viewport's top-left corner", 2),
    ("TOP_RIGHT", "Top right", "Draw the map overlay in the viewport's top-right corner", 3),
)


class OMNIWARP_PG_scene(bpy.types.PropertyGroup):
    """Viewport preview and overlay settings of one scene (`scene.omniwarp`)."""

    preview_enabled: BoolProperty(
        name="Preview",
        description="Draw OmniWarp shadows of the enabled lights in the 3D viewport. "
                    "Cost: a G-buffer pass plus every enabled light's shadow maps on each update",
        default=False,
        update=_preview_toggled,
    )
    shadow_strength: FloatProperty(
        name="Shadow Strength",
        description="How dark shadowed surfaces are drawn in the preview (0: invisible, 1: black). "
                    "No cost",
        default=0.6,
        min=0.0,
        max=1.0,
        subtype="FACTOR",
        update=_overlay_changed,
    )
    overlay_enabled: BoolProperty(
        name="Map Overlay",
        description="Show the shadow, count and importance maps in a corner of the viewport. "
                    "Cost: reading the maps back from the GPU after each update",
        default=True,
        update=_overlay_changed,
    )
    overlay_maps: EnumProperty(
        name="Maps",
        description="Which maps the overlay shows; each adds a read-back and a row of images",
        items=OVERLAY_MAP_ITEMS,
        options={"ENUM_FLAG"},
        default={"DEPTH", "COUNT", "IMPORTANCE"},
        update=_overlay_changed,
    )
    overlay_size: IntProperty(
        name="Size",
        description="Side of each overlay image in pixels. Larger images cover more of the viewport; "
                    "the cost is negligible",
        default=160,
        min=64,
        max=512,
        subtype="PIXEL",
        update=_overlay_changed,
    )
    overlay_corner: EnumProperty(
        name="Corner",
        description="Viewport corner the overlay is drawn in. No cost",
        items=OVERLAY_CORNER_ITEMS,
        default="BOTTOM_LEFT",
        update=_overlay_changed,
    )
    overlay_stats: BoolProperty(
        name="Stats",
        description="Draw a line of stats per light (passes, triangles drawn, texels, time) under "
                    "the overlay. No measurable cost",
        default=True,
        update=_overlay_changed,
    )
    camera_resolution_scale: FloatProperty(
        name="Sample Scale",
        description="Resolution of the preview's G-buffer (the view samples) relative to the viewport "
                    "region. Lower is faster (the analysis and the shadow test scale with the sample "
                    "count) but the shadows look blockier",
        default=0.5,
        min=0.1,
        max=1.0,
        subtype="FACTOR",
        update=_request_scene_update,
    )
    throttle_ms: IntProperty(
        name="Throttle (ms)",
        description="Minimum time in milliseconds between two preview recomputes while the view or "
                    "scene changes. Higher keeps navigation smooth at the cost of shadows lagging "
                    "behind; 0 recomputes on every change",
        default=250,
        min=0,
        max=2000,
        update=_request_scene_update,
    )


CLASSES: tuple[type, ...] = (OMNIWARP_PG_light, OMNIWARP_PG_scene)
