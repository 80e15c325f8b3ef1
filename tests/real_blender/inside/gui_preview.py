"""Inside a real Blender GUI (under Xvfb, tests/real_blender/inside/gui.sh), with the extension
installed from its zip: `blender --gpu-backend B FILE --python THIS -- OUT_DIR [METHOD]`.

Driven by a timer, step by step, each step after Blender has redrawn:
  1. s_setup: builds the room_omni preset (the comparison panel's Build), gives its light
     METHOD (default dpsm) at 1024, looks through its camera in the 3D view with the sidebar,
     toolbar, header and map overlay hidden, and opens every panel of the extension (each
     panel's and list's draws are counted, their errors kept);
  2. s_off: screenshots the 3D view's region with the preview off (`view_off.png`), turns the
     preview on (sample scale 1: its samples are the view's pixels, throttle 0);
  3. s_wait_preview: once the preview has a result, screenshots the view (`view_on.png`) and
     saves what the preview computed for it (`view.npz`: G-buffer, visibility, flags, the
     light's position); then shows the sidebar, toolbar, header and overlay;
  4. s_sidebar_tab: the sidebar's OmniWarp tab and the light's data properties;
  5. s_overlay: screenshots the view with the overlay (`view_overlay.png`), the window
     (`window.png`) and the light's properties (`light_panel.png`); saves the depth atlas
     the overlay shows (`atlas.npy`, row 0 at the bottom) and its count maps with the
     samples they count (`counts.npz`: the G-buffer of that view, one map a layer slot);
  6. s_compare, s_compare_shot, s_compare_shot_take: the comparison panel's Compare (dpsm,
     dpsm+notw and exact at 1024), then the sidebar scrolled to its end
     (`compare_panel.png`: the rows, the plot and the mismatch image);
then writes `gui.json` (backend, renderer, panels drawn and their errors, steps done, the
preview's last error, what the steps recorded) and quits.

A step that fails, or waits more than 60 ticks, writes its traceback into gui.json and
quits, so the caller never waits on a window that will not close. Screenshots are the X
screen (xwd): Blender's own screenshot operators read back black under Xvfb.
"""
from __future__ import annotations

import importlib
import json
import sys
import traceback
from pathlib import Path

import bpy
import numpy as np

sys.path.insert(0, "/omniwarp")  # the repository, bound read-only in the chroot (scripts/real_blender.sh)
from tests.support.extension_worker import ADDON_MODULE as PACKAGE  # noqa: E402
OUT = Path(sys.argv[sys.argv.index("--") + 1])
METHOD = sys.argv[sys.argv.index("--") + 2] if len(sys.argv) > sys.argv.index("--") + 2 else "dpsm"
REPORT: dict = {"drawn": {}, "panel_errors": [], "steps": []}


def _module(name: str):
    return importlib.import_module(f"{PACKAGE}.addon.{name}")


def _note_draw(name: str) -> None:
    REPORT["drawn"][name] = REPORT["drawn"].get(name, 0) + 1


def _counted_panel(original, name: str):
    def draw(self, context):  # Blender checks a panel's draw takes (self, context)
        _note_draw(name)
        try:
            return original(self, context)
        except Exception:
            REPORT["panel_errors"].append(traceback.format_exc())
            raise
    return draw


def _counted_list(original, name: str):
    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        _note_draw(name)
        try:
            return original(self, context, layout, data, item, icon, active_data, active_property, index, flt_flag)
        except Exception:
            REPORT["panel_errors"].append(traceback.format_exc())
            raise
    return draw_item


def _count_draws() -> None:
    """Count each panel's and list's draws, and open the panels that start closed (a test
    must see every panel drawn); re-registered so Blender reads the changed classes."""
    registration = _module("blender.registration")
    for cls in registration.CLASSES + registration.TOOL_CLASSES:
        method = "draw_item" if issubclass(cls, bpy.types.UIList) else "draw"
        if not issubclass(cls, (bpy.types.Panel, bpy.types.UIList)):
            continue
        original = getattr(cls, method)
        counted = _counted_list(original, cls.__name__) if method == "draw_item" else _counted_panel(original,
                                                                                                    cls.__name__)
        bpy.utils.unregister_class(cls)
        setattr(cls, method, counted)
        if issubclass(cls, bpy.types.Panel):
            cls.bl_options = set(getattr(cls, "bl_options", set())) - {"DEFAULT_CLOSED"}
        bpy.utils.register_class(cls)


def _areas(kind: str):
    return [a for a in bpy.context.window.screen.areas if a.type == kind]


def _view3d():
    area = max(_areas("VIEW_3D"), key=lambda a: a.width * a.height)
    region = next(r for r in area.regions if r.type == "WINDOW")
    return area, region


def _screenshot(path: Path, region=None) -> None:
    """The X screen as the user sees it (xwd, converted by ImageMagick), cropped to `region`
    when given. Blender's own screenshot operators read back black under Xvfb."""
    import subprocess

    full = path.with_name(path.stem + "_screen.png") if region is not None else path
    subprocess.run(["sh", "-c", f"xwd -root -silent | convert xwd:- '{full}'"], check=True)
    if region is None:
        return
    top = bpy.context.window.height - (region.y + region.height)  # window coordinates start at the bottom
    subprocess.run(["convert", str(full), "-crop", f"{region.width}x{region.height}+{region.x}+{top}", "+repage",
                    str(path)], check=True)
    full.unlink()


def _region(area, kind: str = "WINDOW"):
    return next(r for r in area.regions if r.type == kind)


def _setup() -> None:
    _count_draws()
    bpy.types.SpaceView3D.draw_handler_add(_count_view_draw, (), "WINDOW", "POST_PIXEL")
    scene = bpy.context.scene
    scene.omniwarp_compare.source = "PRESET"
    scene.omniwarp_compare.preset = "room_omni"
    bpy.ops.omniwarp.build_preset()
    scene = bpy.context.window.scene
    light = next(o for o in scene.objects if o.type == "LIGHT")
    settings = light.data.omniwarp
    settings.enabled = True
    parameterization, _, warp = METHOD.partition("+")
    settings.parameterization = parameterization.upper()
    settings.warp = (warp or "none").upper()
    settings.resolution = 1024
    for obj in scene.objects:
        obj.select_set(obj == light)
    bpy.context.view_layer.objects.active = light
    area, region = _view3d()
    space = area.spaces.active
    space.shading.type = "SOLID"
    space.show_gizmo = False
    overlay = space.overlay
    for name in ("show_floor", "show_axis_x", "show_axis_y", "show_cursor", "show_object_origins",
                 "show_outline_selected", "show_text", "show_stats", "show_extras", "show_relationship_lines"):
        setattr(overlay, name, False)
    # The measured shots see the view alone: no sidebar, toolbar or header over it, no overlay.
    space.show_region_ui = space.show_region_toolbar = space.show_region_header = False
    space.show_region_tool_header = False
    scene.omniwarp.overlay_enabled = False
    space.region_3d.view_perspective = "CAMERA"
    with bpy.context.temp_override(area=area, region=region):
        bpy.ops.view3d.view_center_camera()
    REPORT["light"] = light.name
    REPORT["region"] = [region.width, region.height]


def _preview_on() -> None:
    scene = bpy.context.window.scene
    scene.omniwarp.camera_resolution_scale = 1.0
    scene.omniwarp.throttle_ms = 0
    scene.omniwarp.preview_enabled = True


def _preview_ready() -> bool:
    viewport = _module("blender.viewport")
    state = viewport._STATE
    # No recompute spread over redraws under way (the backend's maps are then mid-frame).
    return bool(state.results) and state.last_drawn in ("computed", "cached") and state.pending is None


VIEW_DRAWS = {"count": 0, "mark": None}  # the 3D view's redraws; the count when the preview was first ready


def _count_view_draw() -> None:
    VIEW_DRAWS["count"] += 1


def _preview_shown() -> bool:
    """The preview ready, and the view redrawn twice since: a Vulkan swapchain shows a frame
    a redraw or two after it was drawn (loaded, the screenshot caught the view unshadowed)."""
    if not _preview_ready():
        VIEW_DRAWS["mark"] = None
        return False
    if VIEW_DRAWS["mark"] is None:
        VIEW_DRAWS["mark"] = VIEW_DRAWS["count"]
    if VIEW_DRAWS["count"] < VIEW_DRAWS["mark"] + 2:
        _view3d()[0].tag_redraw()
        return False
    VIEW_DRAWS["mark"] = None
    return True


def _save_view() -> None:
    """What the preview computed for the view: its G-buffer (row 0 at the top), the first
    light's visibility and flags, and the light's position (`view.npz`)."""
    viewport = _module("blender.viewport")
    blender_gpu = _module("render.backends.blender.gpu_objects")
    _, region = _view3d()
    result = viewport._STATE.results[region.as_pointer()]
    raw = blender_gpu.read_texture(result.visibility[0], "RG32F")[::-1]
    _, light, _, frame, _, _ = result.lights[0]
    np.savez(OUT / "view.npz", positions=result.gbuffer.positions, normals=result.gbuffer.normals,
             visibility=raw[..., 0], flags=raw[..., 1], light_position=np.asarray(light.position, dtype=np.float64))
    REPORT["drawn_layers"] = len(frame.plan.drawn)
    REPORT["resolution"] = int(frame.layout.resolution) if frame.layout else 0


def _overlay_on() -> None:
    scene = bpy.context.window.scene
    scene.omniwarp.overlay_enabled = True


def _save_atlas() -> None:
    viewport = _module("blender.viewport")
    _, region = _view3d()
    result = viewport._STATE.results[region.as_pointer()]
    frame = result.lights[0][3]
    backend = viewport._STATE.backend
    atlas = backend.textures.get("ow_atlas")
    if atlas is not None:
        np.save(OUT / "atlas.npy", _module("render.backends.blender.gpu_objects").read_texture(atlas, "R32F"))
    REPORT["tiles"] = {str(k): list(frame.layout.origin(v)) for k, v in frame.tile_of_slot.items()} if frame.layout else {}
    stats = result.lights[0][4]
    np.savez(OUT / "counts.npz", positions=result.gbuffer.positions, normals=result.gbuffer.normals,
             **{f"counts_{slot}": np.asarray(stats.before[slot]) for slot in stats.before})


STEPS = []


def step(fn):
    STEPS.append(fn)
    return fn


@step
def s_setup():
    _setup()


@step
def s_off():
    _, region = _view3d()
    _screenshot(OUT / "view_off.png", region)
    _preview_on()


@step
def s_wait_preview():
    if not _preview_shown():
        return "again"
    area, region = _view3d()
    _screenshot(OUT / "view_on.png", region)
    _save_view()
    # Then the UI as a user has it: sidebar, toolbar, header, and the overlay.
    space = area.spaces.active
    space.show_region_ui = space.show_region_toolbar = space.show_region_header = True
    _overlay_on()


@step
def s_sidebar_tab():
    """The sidebar's OmniWarp tab and the light's properties, once both have drawn (their tabs exist only then)."""
    area, _ = _view3d()
    sidebar = next(r for r in area.regions if r.type == "UI")
    sidebar.active_panel_category = _module("blender.panels").SIDEBAR_CATEGORY
    for props in _areas("PROPERTIES"):  # the light's data tab, once the editor knows the active light
        props.spaces.active.context = "DATA"




@step
def s_overlay():
    if not _preview_shown():
        return "again"
    area, region = _view3d()
    _screenshot(OUT / "view_overlay.png", region)
    _screenshot(OUT / "window.png")
    props = _areas("PROPERTIES")
    if props:
        _screenshot(OUT / "light_panel.png", _region(props[0]))
    _save_atlas()


@step
def s_compare():
    """The comparison panel's Compare on the preset (dpsm, dpsm+notw and exact at 1024): the
    results list and the plot then draw in the sidebar."""
    compare_props = _module("blender.compare_props")
    methods = _module("core.methods")
    settings = bpy.context.window.scene.omniwarp_compare
    settings.source = "PRESET"
    settings.preset = "room_omni"
    for method in methods.pipeline_methods():
        setattr(settings, compare_props.method_prop(method), method in ("dpsm", "dpsm+notw", "exact"))
    settings.resolutions = "1024"
    REPORT["compare"] = sorted(bpy.ops.omniwarp.compare("EXEC_DEFAULT"))
    REPORT["compare_rows"] = len(settings.results)
    REPORT["plot_set"] = settings.plot_image is not None


@step
def s_compare_shot():
    area, _ = _view3d()
    sidebar = _region(area, "UI")
    # The panel is long: scroll the sidebar to its end so the list and the plot show.
    with bpy.context.temp_override(area=area, region=sidebar):
        for _ in range(8):
            bpy.ops.view2d.scroll_down(page=True)
    REPORT["sidebar"] = [sidebar.width, sidebar.height]


@step
def s_compare_shot_take():
    area, _ = _view3d()
    _screenshot(OUT / "compare_panel.png", _region(area, "UI"))


_AT = {"index": 0, "tries": 0}


def _tick():
    try:
        if _AT["index"] >= len(STEPS):
            _finish()
            return None
        fn = STEPS[_AT["index"]]
        outcome = fn()
        if outcome == "again" and _AT["tries"] < 60:
            _AT["tries"] += 1
        else:
            if outcome == "again":
                raise TimeoutError(f"step {fn.__name__} waited 60 ticks")
            REPORT["steps"].append(fn.__name__)
            _AT["index"] += 1
            _AT["tries"] = 0
        for area in bpy.context.window.screen.areas:
            area.tag_redraw()
        return 0.5
    except Exception:
        REPORT["error"] = traceback.format_exc()
        _finish()
        return None


def _finish() -> None:
    import gpu

    REPORT["backend"] = gpu.platform.backend_type_get()
    REPORT["renderer"] = gpu.platform.renderer_get()
    try:
        REPORT["preview_error"] = _module("blender.viewport").last_error()
    except Exception:
        REPORT["preview_error"] = traceback.format_exc()
    (OUT / "gui.json").write_text(json.dumps(REPORT, indent=1), encoding="utf-8")
    bpy.ops.wm.quit_blender()


OUT.mkdir(parents=True, exist_ok=True)
bpy.app.timers.register(_tick, first_interval=1.0)
