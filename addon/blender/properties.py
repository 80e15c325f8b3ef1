"""OmniWarp settings stored in .blend files, and the helpers that turn them into
pipeline inputs.

* `OMNIWARP_PG_light` hangs on every light as `bpy.types.Light.omniwarp`: the
  per-light shadow method (parameterization, warp, resolution, bias, culling).
  Its parameterization list depends on the light: point lights and spots of
  179° or more take dpsm, cube, ipsm and unfold; narrower spots and suns take
  sm and psm. A stored choice that no longer fits (the light changed type) is
  never an error: `shadow_settings_for` falls back (see
  `effective_parameterization`).
* `OMNIWARP_PG_scene` hangs on every scene as `bpy.types.Scene.omniwarp`: the
  viewport preview and its map overlay.

Every tooltip says what a setting does and what it costs. Changing a setting
marks the viewport preview stale through `events.notify("request_update")`, which
the viewport listens to once registered: this module never imports it.
"""
from __future__ import annotations

import logging

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

from ..core import frames
from ..core.errors import InputError
from ..core.frames import POINT_PARAMETERIZATIONS, PROJECTIVE_PARAMETERIZATIONS
from ..core.methods import PARAMETERIZATION_TEXT, WARP_TEXT
from ..core.scene import PROJECTIVE_EMISSIONS, Emission, LightSpec, spot_emission
from ..compat import blender as blender_compat
from ..readers import light_size
from ..render.frame import EXACT_SAMPLES, LIGHT_SAMPLES
from ..render.pipeline import BiasSettings, ShadowSettings
from ..render.shaders import SOFT_MAX_POINTS, SOFT_MAX_SEARCH
from . import events

log = logging.getLogger(__name__)

# An AREA light is one-sided: the hemispherical emission, with a size.
SUPPORTED_LIGHT_TYPES: tuple[str, ...] = ("POINT", "SPOT", "SUN", "AREA")

# The parameterizations the exact pass (ShadowSettings.exact) takes (the light panel greys
# the setting elsewhere).
EXACT_PARAMETERIZATIONS = frames.EXACT_PARAMETERIZATIONS

RESOLUTION_MIN = 256
RESOLUTION_MAX = 4096
RESOLUTION_DEFAULT = 1024


# ----------------------------------------------------------------------------
# update callbacks: told to the viewport through events (it may not be registered)
# ----------------------------------------------------------------------------
def _request_update(self: bpy.types.PropertyGroup, context: bpy.types.Context) -> None:
    """Property update callback: mark the viewport preview stale."""
    events.notify("request_update", "light settings")


def _request_scene_update(self: bpy.types.PropertyGroup, context: bpy.types.Context) -> None:
    """Update callback of scene-level preview settings: mark the preview stale."""
    events.notify("request_update", "preview settings")


def _overlay_changed(self: bpy.types.PropertyGroup, context: bpy.types.Context) -> None:
    """Overlay settings change only the drawing, not the maps: redraw the viewports."""
    events.redraw_3d_views()


def _preview_toggled(self: OMNIWARP_PG_scene, context: bpy.types.Context) -> None:
    """Turn the viewport preview on or off to match `preview_enabled`."""
    if events.notify("set_preview_enabled", context, bool(self.preview_enabled), default=False) is False:
        log.warning("OmniWarp viewport preview is not registered; the preview cannot be toggled")


# ----------------------------------------------------------------------------
# per light
# ----------------------------------------------------------------------------
EMISSION_ITEMS = (
    ("AUTO", "From light type",
     "Point light: omnidirectional. Spot light with a cone of 179° or more: hemispherical. "
     "Narrower spot: only its own cone, with a uniform or perspective shadow map (one pass). "
     "Sun: parallel light, with a uniform or perspective shadow map (one pass)", 0),
    ("OMNI", "Omnidirectional",
     "Shadows in every direction around the light, also for a narrow spot (its cone then only "
     "shapes the light). Cost: both paraboloid sides or all six cube faces (fewer when culling "
     "skips what the view never touches)", 1),
    ("HEMI", "Hemispherical",
     "Shadows only in the half space along the light's local -Z. Cost: one paraboloid side, "
     "at most five cube faces", 2),
)

# Stable numbers: they are what .blend files store, so never renumber an item. The
# tooltips are the method registry's (core/methods.py), which describes each once.
PARAMETERIZATION_ITEMS = tuple(
    (identifier, label, PARAMETERIZATION_TEXT[identifier.lower()], number)
    for identifier, label, number in (
        ("DPSM", "Dual paraboloid", 0),
        ("CUBE", "Cube", 1),
        ("IPSM", "Single paraboloid (IPSM)", 2),
        ("UNFOLD", "Sphere unfolding", 3),
        ("SM", "Uniform", 4),
        ("PSM", "Perspective (PSM)", 5),
    )
)
_PARAMETERIZATION_ITEM = {item[0]: item for item in PARAMETERIZATION_ITEMS}
_PARAMETERIZATION_NUMBER = {item[0]: item[3] for item in PARAMETERIZATION_ITEMS}
_PARAMETERIZATION_BY_NUMBER = {item[3]: item[0] for item in PARAMETERIZATION_ITEMS}

# The item lists the dynamic enum hands to Blender, built once and kept here for the
# life of the module: Blender keeps pointers to the strings of what a dynamic
# enum's callback returns, and misbehaves or crashes once Python frees them.
_PARAMETERIZATION_ITEM_CACHE: dict[str, list[tuple[str, str, str, int]]] = {
    "point": [_PARAMETERIZATION_ITEM[name.upper()] for name in POINT_PARAMETERIZATIONS],
    "projective": [_PARAMETERIZATION_ITEM[name.upper()] for name in PROJECTIVE_PARAMETERIZATIONS],
    "all": list(PARAMETERIZATION_ITEMS),
}
# What a light uses when its stored choice does not fit it (e.g. a POINT set to CUBE
# that became a SUN): the classic method of each family.
FALLBACK_PARAMETERIZATION = {"point": "dpsm", "projective": "psm"}
# The pipeline refuses a warp for these (ShadowSettings): one shared projection, or
# a map that is already a global warp.

# bpy.props gained get_transform in Blender 5.0: it rewrites a stale stored value on
# every read, so Python and the UI both see the method actually used. Blender 4.2-4.5
# refuse the keyword, so there the stale value stays and is resolved in Python.
_HAS_GET_TRANSFORM = blender_compat.has_get_transform()

WARP_ITEMS = tuple(
    (identifier, label, WARP_TEXT[identifier.lower()], number)
    for identifier, label, number in (("NONE", "None", 0), ("NOTW", "NoTW", 1), ("RTW", "RTW", 2))
)


def _method_family(light: bpy.types.Light) -> str:
    """'projective' for a light the spot/sun maps take (narrow spot cone, sun), else 'point'."""
    return "projective" if effective_emission(light) in PROJECTIVE_EMISSIONS else "point"


def parameterization_items(self: bpy.types.PropertyGroup,
                            context: bpy.types.Context | None) -> list[tuple[str, str, str, int]]:
    """Items callback of `parameterization`: only the methods that fit the owning light.

    The list comes from `_PARAMETERIZATION_ITEM_CACHE` (never built here; see there).
    Without a light to ask (the owner is not a Light), every item is offered.
    """
    light = getattr(self, "id_data", None)
    if not isinstance(light, bpy.types.Light):
        return _PARAMETERIZATION_ITEM_CACHE["all"]
    return _PARAMETERIZATION_ITEM_CACHE[_method_family(light)]


def _fallback_parameterization(light: bpy.types.Light, stored: str, was_set: bool) -> str:
    """The method (lower case) used when the stored one (`stored`, for the log) does not fit the light."""
    fallback = FALLBACK_PARAMETERIZATION[_method_family(light)]
    if was_set:  # unset is the default (DPSM), which a spot cone or sun simply does not use
        log.debug("light %r: stored parameterization %s does not fit its %s emission; using %s",
                  light.name, stored or "(unknown)", effective_emission(light), fallback)
    return fallback


def _parameterization_read(self: bpy.types.PropertyGroup, value: int, is_set: bool) -> int:
    """get_transform of `parameterization` (Blender 5.0+): a stale stored number reads as the fallback."""
    light = getattr(self, "id_data", None)
    if not isinstance(light, bpy.types.Light):
        return value
    stored = _PARAMETERIZATION_BY_NUMBER.get(value, "").lower()
    if stored in valid_parameterizations(light):
        return value
    return _PARAMETERIZATION_NUMBER[_fallback_parameterization(light, stored or str(value), is_set).upper()]


# Keywords of `parameterization` that only some Blender versions accept.
_PARAMETERIZATION_EXTRA: dict = {"get_transform": _parameterization_read} if _HAS_GET_TRANSFORM else {}


# The exact pass's choices of a sized light's points (squares: ShadowSettings.exact_samples).
EXACT_SAMPLE_ITEMS = tuple((str(n), str(n), f"{n} points of the light per view sample") for n in (16, 64, 144, 256))

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
        description="Which directions of a point or spot light receive light (and so need shadow maps). "
                    "Hemispherical needs about half the passes of omnidirectional. A sun ignores it",
        items=EMISSION_ITEMS,
        default="AUTO",
        update=_request_update,
    )
    # A dynamic enum: the items depend on the light (its type, cone and emission).
    # Blender only takes an integer default for those; 0 (DPSM) does not fit a spot
    # cone or a sun, which then fall back to PSM (see `effective_parameterization`).
    parameterization: EnumProperty(
        name="Parameterization",
        description="How the light's directions map onto shadow-map texels; only the methods that fit "
                    "this light are listed. Point and wide spot lights: dual paraboloid, cube, IPSM, "
                    "sphere unfolding. Narrower spots and suns: uniform or perspective map",
        items=parameterization_items,
        default=0,
        update=_request_update,
        **_PARAMETERIZATION_EXTRA,
    )
    warp: EnumProperty(
        name="Warp",
        description="Redistribute shadow-map resolution toward what the camera sees. "
                    "Any warp costs an analysis pass and extra triangles. Only dual paraboloid, cube "
                    "and IPSM take a warp; the other methods ignore it",
        items=WARP_ITEMS,
        default="NONE",
        update=_request_update,
    )
    resolution: IntProperty(
        name="Resolution",
        description="Side of each shadow map in texels: sharper shadows, but memory and fill time grow "
                    "with its square (cube: 6 × resolution² floats, dual paraboloid and sphere unfolding: "
                    "2 × resolution² floats, IPSM, uniform and perspective maps: 1 × resolution² floats)",
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
    exact: BoolProperty(
        name="Exact",
        description="Exact hard shadows: the view samples are kept in per-texel lists of the map and every "
                    "triangle is tested against them (an irregular z-buffer), so the shadow edges follow the "
                    "pixels, not the texels. Dual paraboloid, cube and IPSM, and the plain map (SM) of a spot "
                    "or sun. Cost: a list pass over the view "
                    "samples, and each triangle walks the lists of the texels it covers (about 1-2x the warped "
                    "map's time; about 2x a spot's or sun's plain map)",
        default=False,
        update=_request_update,
    )
    light_samples: IntProperty(
        name="Light Samples",
        description="Soft shadows of a light with a size (radius, sun angle, area light): points of the light "
                    "each view sample looks up in the maps. More give smoother penumbrae; each costs one map read "
                    "per pixel. Every light type and map; ignored for a light of size 0",
        default=LIGHT_SAMPLES,
        min=1,
        max=SOFT_MAX_POINTS,
        update=_request_update,
    )
    search_samples: IntProperty(
        name="Search Samples",
        description="Soft shadows: light points whose segments the blocker search follows, three map reads "
                    "each per pixel. More find small blockers in a wide penumbra",
        default=8,
        min=1,
        max=SOFT_MAX_SEARCH,
        update=_request_update,
    )
    exact_samples: EnumProperty(
        name="Exact Samples",
        description="Soft shadows of the exact method: points of the light each view sample tests every "
                    "triangle against (one per cell of a square grid on the light). More follow Cycles more "
                    "closely; the exact pass's cost grows with them where a triangle can shadow part of the light",
        items=EXACT_SAMPLE_ITEMS,
        default=str(EXACT_SAMPLES),
        update=_request_update,
    )
    cull: BoolProperty(
        name="Cull",
        description="Skip paraboloid sides and cube faces the view never touches, and objects that cannot "
                    "shadow anything in view. Saves passes and triangles; IPSM needs it (without it, IPSM "
                    "falls back to the dual paraboloid). Turn off only to measure the unculled cost",
        default=True,
        update=_request_update,
    )


def is_supported_light(light: bpy.types.Light | None) -> bool:
    """True for the light types OmniWarp shadows: POINT, SPOT, SUN and AREA."""
    return light is not None and getattr(light, "type", None) in SUPPORTED_LIGHT_TYPES


def enabled_light_objects(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """The scene's light objects of a supported type with OmniWarp enabled, by name."""
    found = [
        obj for obj in scene.objects
        if obj.type == "LIGHT" and is_supported_light(obj.data) and obj.data.omniwarp.enabled
    ]
    return sorted(found, key=lambda obj: obj.name)



def enabled_lights(scene: bpy.types.Scene, depsgraph) -> list:
    """(name, LightSpec, ShadowSettings) of every visible light with OmniWarp enabled."""
    return [(obj.name, light_spec_for(obj.evaluated_get(depsgraph)), shadow_settings_for(obj.data))
            for obj in enabled_light_objects(scene) if obj.visible_get(view_layer=depsgraph.view_layer)]


def is_narrow_spot(light: bpy.types.Light) -> bool:
    """True for a SPOT whose cone (spot_size, radians) is below 179° (float32 tolerance included)."""
    return light.type == "SPOT" and spot_emission(light.spot_size) == "spot"


def effective_emission(light: bpy.types.Light) -> Emission:
    """'omni', 'hemi', 'spot' or 'sun' for a light, resolving AUTO by its type.

    A SUN is always 'sun' and an AREA light 'hemi' (one-sided; the emission choice does
    not apply to either). An explicit OMNI or
    HEMI gives the point-light treatment, even to a narrow spot. AUTO: a POINT is
    omni; a SPOT whose spot_size is at least 179° is hemi; a narrower SPOT is 'spot'
    (its own cone, shadowed with sm or psm).
    """
    if light.type == "SUN":
        return "sun"
    if light.type == "AREA":
        return "hemi"
    choice = light.omniwarp.emission
    if choice == "OMNI":
        return "omni"
    if choice == "HEMI":
        return "hemi"
    if light.type == "SPOT":
        return "spot" if is_narrow_spot(light) else "hemi"
    return "omni"


def valid_parameterizations(light: bpy.types.Light) -> tuple[str, ...]:
    """The parameterizations (lower case, pipeline names) that fit the light's effective emission."""
    return frames.parameterizations_for(effective_emission(light))


def stored_parameterization(light: bpy.types.Light) -> str:
    """The light's stored parameterization (lower case), or '' when no item has its number.

    On Blender 5.0+ the get_transform already replaced a stale value, so this equals
    `effective_parameterization`. On 4.2-4.5 the raw stored number is read: reading the
    enum itself would print "current value matches no enum" on every stale read.
    """
    props = light.omniwarp
    if _HAS_GET_TRANSFORM:
        return props.parameterization.lower()
    number = props.get("parameterization", 0)  # unset: the default, item 0
    return _PARAMETERIZATION_BY_NUMBER.get(number, "").lower()


def effective_parameterization(light: bpy.types.Light) -> str:
    """The parameterization the pipeline gets for a light (lower case).

    The stored choice when it fits the light's effective emission; otherwise (the
    light changed type or cone, or the number is unknown) 'dpsm' for point lights
    and 'psm' for spot cones and suns, logged at debug level.
    """
    stored = stored_parameterization(light)
    if stored in valid_parameterizations(light):
        return stored
    return _fallback_parameterization(light, stored, light.omniwarp.is_property_set("parameterization"))


def takes_warp(parameterization: str) -> bool:
    """False for the methods the pipeline refuses a warp for (unfold, sm, psm)."""
    return frames.takes_warp(parameterization)


def effective_warp(light: bpy.types.Light, parameterization: str | None = None) -> str:
    """The warp the pipeline gets (lower case): the stored one, or 'none' where the method takes none."""
    parameterization = parameterization or effective_parameterization(light)
    warp = light.omniwarp.warp.lower()
    if warp != "none" and not takes_warp(parameterization):
        log.debug("light %r: %s takes no warp; %s ignored", light.name, parameterization, warp)
        return "none"
    return warp


def _ui_float(value: float) -> float:
    """A float32 RNA value as the decimal the user typed (0.30000001 -> 0.3).

    Six decimals are far below any bias that matters, and the defaults then equal
    `BiasSettings()` exactly, so settings from the UI compare equal to the pipeline's.
    """
    return round(float(value), 6)


def shadow_settings_for(light: bpy.types.Light) -> ShadowSettings:
    """The pipeline's `ShadowSettings` for a light's OmniWarp properties.

    Never fails on a stored method that no longer fits the light: see
    `effective_parameterization` and `effective_warp`.
    """
    props = light.omniwarp
    parameterization = effective_parameterization(light)
    try:
        bias = BiasSettings(
            constant=_ui_float(props.bias_constant),
            slope=_ui_float(props.bias_slope),
            normal=_ui_float(props.bias_normal),
        )
    except InputError as exc:
        # A NaN or infinite bias set from Python: named with its light, never drawn.
        raise InputError(f"light {light.name!r}: {exc}") from None
    return ShadowSettings(
        parameterization=parameterization,
        resolution=int(props.resolution),
        bias=bias,
        cull=bool(props.cull),
        warp=effective_warp(light, parameterization),
        # The exact pass draws footprints: PSM and unfold keep their own maps.
        exact=bool(props.exact) and parameterization in EXACT_PARAMETERIZATIONS,
        light_samples=int(props.light_samples),
        search_samples=int(props.search_samples),
        exact_samples=int(props.exact_samples),
    )


def light_spec_for(obj: bpy.types.Object) -> LightSpec:
    """A `LightSpec` for an (evaluated) light object: its world matrix, effective emission,
    its size (readers/light_size.py) and, for a spot cone, its full cone angle."""
    light = obj.data
    if not isinstance(light, bpy.types.Light):
        raise TypeError(f"object {obj.name!r} is not a light")
    matrix = np.array([list(row) for row in obj.matrix_world], dtype=np.float64)
    emission = effective_emission(light)
    # Only a spot cone has a cone angle; the other emissions keep LightSpec's default.
    cone = {"spot_size": float(light.spot_size)} if emission == "spot" else {}
    if light.type == "SPOT":
        cone["spot_blend"] = float(light.spot_blend)  # a 180 degree spot (hemi) fades too
    try:
        return LightSpec(emission=emission, matrix_world=matrix, energy=float(light.energy),
                         shape=light_size.light_shape(obj, matrix), **cone)
    except InputError as exc:
        raise InputError(f"light {obj.name!r}: {exc}") from None


def settings_problem(light: bpy.types.Light, obj: bpy.types.Object | None = None) -> str:
    """Why a light's OmniWarp settings (and, given its object, its energy and transform)
    cannot be drawn, "" if they can: the pipeline's own checks, for the light panel."""
    try:
        shadow_settings_for(light)
        if obj is not None and obj.data == light:
            light_spec_for(obj)
    except InputError as exc:
        return str(exc)
    return ""


# ----------------------------------------------------------------------------
# per scene: preview and overlay
# ----------------------------------------------------------------------------
OVERLAY_MAP_ITEMS = (
    ("DEPTH", "Depth",
     "The shadow maps' depth (paraboloid sides, cube faces, unfold halves, or the one map of a spot "
     "cone or sun). Cost: one read-back per map", 1),
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
