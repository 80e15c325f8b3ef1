"""Inside a real Blender binary, background (`blender -b --python THIS -- OUT_JSON`), with the
extension installed from its zip: disable and enable it three times in one run.

Each time it is enabled, the preview draws the room_omni preset once into an offscreen
target (so it holds GPU objects), and a timer-driven comparison is not needed for that.
After each disable it records what is left: the extension's classes and pointers among
bpy.types, its functions among bpy.app.handlers, its timers, its draw handler, and the
GPU objects its preview module still holds. Writes OUT_JSON.
"""
from __future__ import annotations

import importlib
import json
import sys
import traceback

import addon_utils
import bpy
import gpu
import numpy as np

sys.path.insert(0, "/omniwarp")  # the repository, bound read-only in the chroot (scripts/real_blender.sh)
from tests.support.extension_worker import ADDON_MODULE as PACKAGE, ext_handlers  # noqa: E402

OUT = sys.argv[sys.argv.index("--") + 1]


def _state(class_names: list[str], modules: dict) -> dict:
    viewport = modules.get("viewport")
    timers = [t.__name__ for t in (getattr(viewport, "_throttle_elapsed", None), getattr(viewport, "_read_grids", None))
              if t is not None and bpy.app.timers.is_registered(t)]
    return {
        "enabled": PACKAGE in {m.__name__ for m in addon_utils.modules() if addon_utils.check(m.__name__)[1]},
        "classes": sorted(n for n in class_names if getattr(bpy.types, n, None) is not None),
        "pointers": sorted(f"{owner.__name__}.{attr}" for owner, attr in ((bpy.types.Scene, "omniwarp"),
                                                                        (bpy.types.Scene, "omniwarp_compare"),
                                                                        (bpy.types.Light, "omniwarp"))
                           if hasattr(owner, attr)),
        "handlers": sorted(ext_handlers()),
        "timers": timers,
        "draw_handler": viewport is not None and viewport._STATE.handler is not None,
        "gpu_objects": viewport.live_resources() if viewport is not None else None,
        "backend_held": viewport is not None and viewport._STATE.backend is not None,
    }


def _draw_preview(modules: dict) -> int:
    """Build the preset, turn the preview on and draw it once offscreen; GPU objects held."""
    scene = bpy.context.scene
    scene.omniwarp_compare.source = "PRESET"
    scene.omniwarp_compare.preset = "room_omni"
    bpy.ops.omniwarp.build_preset()
    scene = bpy.context.window.scene if bpy.context.window else bpy.data.scenes[-1]
    light = next(o for o in scene.objects if o.type == "LIGHT")
    light.data.omniwarp.enabled = True
    scene.omniwarp.preview_enabled = True
    camera = scene.camera
    view = np.array(camera.matrix_world.inverted())
    size = (160, 120)
    projection = np.array(camera.calc_matrix_camera(bpy.context.evaluated_depsgraph_get(), x=size[0], y=size[1]))
    offscreen = gpu.types.GPUOffScreen(*size)
    try:
        with offscreen.bind():
            drawn = modules["viewport"].draw_view(scene, bpy.context.evaluated_depsgraph_get(), view, projection,
                                                  size, "cycles-test")
    finally:
        offscreen.free()
    held = modules["viewport"].live_resources()
    bpy.data.scenes.remove(scene)
    return int(held) if drawn else -1


def main() -> None:
    report: dict = {"rounds": []}
    gpu.init()
    registration = importlib.import_module(PACKAGE + ".addon.blender.registration")
    class_names = [cls.__name__ for cls in registration.CLASSES + registration.TOOL_CLASSES]
    report["initial"] = sorted(bpy.ops.preferences.addon_disable(module=PACKAGE))  # enabled by the install
    report["before"] = _state(class_names, {})
    for _ in range(3):
        round_report: dict = {}
        try:
            round_report["enable"] = sorted(bpy.ops.preferences.addon_enable(module=PACKAGE))
            modules = {"viewport": importlib.import_module(PACKAGE + ".addon.blender.viewport")}
            round_report["enabled"] = _state(class_names, modules)
            round_report["held_after_draw"] = _draw_preview(modules)
            round_report["disable"] = sorted(bpy.ops.preferences.addon_disable(module=PACKAGE))
            round_report["disabled"] = _state(class_names, modules)
        except Exception:
            round_report["error"] = traceback.format_exc()
        report["rounds"].append(round_report)
    with open(OUT, "w", encoding="utf-8") as stream:
        json.dump(report, stream, indent=1)


main()
