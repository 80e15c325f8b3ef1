"""Runs the sidebar comparison tool in its own process for the tests: it draws with
Blender's `gpu`, and the pytest process owns moderngl (one GL owner per process).

    python tests/support/comparison_worker.py OUT_DIR CAMERA_W CAMERA_H

$OMNIWARP_CACHE must name the cache folder that already holds the room_omni
reference at CAMERA_W x CAMERA_H (the parent renders it), so nothing is rendered
here for the preset. Writes OUT_DIR/worker.json with what the tests check, and the
exported OUT_DIR/results.json and OUT_DIR/results.csv.
"""
from __future__ import annotations

import json
import logging
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

METHODS = ("dpsm", "dpsm+notw")


class Reports:
    """Stands in for Operator.report when an operator method is called on a fake self."""

    def __init__(self) -> None:
        self.items: list[tuple[str, str]] = []

    def __call__(self, kinds: set[str], message: str) -> None:
        self.items.extend((kind, message) for kind in kinds)


def _image_stats(image) -> dict:
    if image is None:
        return {"name": None}
    pixels = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return {"name": image.name, "size": list(image.size), "pixels": int(pixels.size),
            "std": float(pixels.std()), "filepath": image.filepath}


def _ui_rows(settings) -> list[dict]:
    return [{"method": r.method, "resolution": r.resolution, "error_pct": r.error_pct,
             "false_shadow_pct": r.false_shadow_pct, "false_lit_pct": r.false_lit_pct, "total_ms": r.total_ms,
             "analysis_ms": r.analysis_ms, "maps_ms": r.maps_ms, "test_ms": r.test_ms, "passes": r.passes,
             "mismatch_image": r.mismatch_image, "mismatch_exists": Path(r.mismatch_image).is_file(),
             "preset": r.preset} for r in settings.results]


def _exec_run(bpy, out: Path, report: dict) -> None:
    """The synchronous path (EXEC_DEFAULT), then both exports."""
    from addon.blender import compare_job, compare_props
    from addon.core import methods as method_registry

    scene = bpy.context.scene
    settings = scene.omniwarp_compare
    settings.source = "PRESET"
    settings.preset = "room_omni"
    for method in method_registry.pipeline_methods():
        setattr(settings, compare_props.method_prop(method), method in METHODS)
    settings.resolutions = "512"
    settings.frames = 1
    report["exec_result"] = sorted(bpy.ops.omniwarp.compare("EXEC_DEFAULT"))
    report["ui_rows"] = _ui_rows(settings)
    report["rows"] = compare_job.rows_for_export(scene)
    report["plot"] = _image_stats(settings.plot_image)
    report["mismatch"] = _image_stats(settings.mismatch_preview)
    report["status"] = settings.status
    report["progress"] = settings.progress
    report["running_after"] = compare_job.is_running()
    exports = {}
    for suffix in ("json", "csv"):
        settings.export_path = str(out / f"results.{suffix}")
        exports[suffix] = sorted(bpy.ops.omniwarp.export_results())
    report["exports"] = exports


def _modal_run(bpy, report: dict) -> None:
    """The modal path, driven by fake timer events: Esc after the first row, then a full run."""
    from addon.blender import compare_job, compare_ops, compare_props
    from addon.core import methods as method_registry

    context = bpy.context
    settings = context.scene.omniwarp_compare
    op_cls = compare_ops.OMNIWARP_OT_compare
    timer = SimpleNamespace(type="TIMER", value="NOTHING")
    esc = SimpleNamespace(type="ESC", value="PRESS")
    mouse = SimpleNamespace(type="MOUSEMOVE", value="NOTHING")

    settings.resolutions = "256,512"
    for method in method_registry.pipeline_methods():
        setattr(settings, compare_props.method_prop(method), method == "dpsm")
    fake = SimpleNamespace(report=Reports(), _timer=None)
    job = compare_job.start_job(context, fake.report)
    compare_job.set_active(job)
    cancel: dict = {"poll_while_running": op_cls.poll(context)}
    cancel["ticks"] = [sorted(op_cls.modal(fake, context, timer)) for _ in range(2)]  # reference, row 1
    cancel["mouse"] = sorted(op_cls.modal(fake, context, mouse))
    cancel["esc"] = sorted(op_cls.modal(fake, context, esc))
    cancel["rows"] = len(settings.results)
    cancel["running_after"] = compare_job.is_running()
    cancel["backend_released"] = job.pipeline is None
    cancel["status"] = settings.status
    cancel["poll_after"] = op_cls.poll(context)
    report["modal_cancel"] = cancel

    settings.resolutions = "256"
    fake = SimpleNamespace(report=Reports(), _timer=None)
    job = compare_job.start_job(context, fake.report)
    compare_job.set_active(job)
    results = []
    for _ in range(10):
        results.append(sorted(op_cls.modal(fake, context, timer)))
        if results[-1] != ["PASS_THROUGH"]:
            break
    report["modal_full"] = {"results": results, "rows": len(settings.results), "progress": settings.progress,
                            "running_after": compare_job.is_running(), "backend_released": job.pipeline is None,
                            "reports": fake.report.items}


def _current_scene_run(bpy, report: dict) -> None:
    """Build the preset into a new scene, then measure it as the current scene."""
    from addon.blender import compare_props
    from addon.core import methods as method_registry

    before = bpy.context.scene
    settings = before.omniwarp_compare
    report["build"] = sorted(bpy.ops.omniwarp.build_preset())
    scene = bpy.context.scene
    report["build_new_scene"] = scene != before
    report["build_new_scene_values"] = {"before": before.name, "after": scene.name}
    current = scene.omniwarp_compare
    current.source = "CURRENT"
    for method in method_registry.pipeline_methods():
        setattr(current, compare_props.method_prop(method), method == "dpsm")
    current.resolutions = "512"
    current.frames = 1
    report["current_copied_settings"] = tuple(current.camera_size) == tuple(settings.camera_size)
    report["current_copied_settings_values"] = {"camera_size": list(settings.camera_size),
                                                "current_camera_size": list(current.camera_size)}
    report["current_result"] = sorted(bpy.ops.omniwarp.compare("EXEC_DEFAULT"))
    report["current_rows"] = _ui_rows(current)
    bpy.context.window.scene = before


def main(out_dir: str, width: str, height: str) -> None:
    logging.basicConfig(level=logging.WARNING)
    import bpy

    from addon.blender import registration
    from addon.render.backends.blender.gpu_objects import ensure_gpu

    out = Path(out_dir)
    ensure_gpu()
    registration.register()
    bpy.context.scene.omniwarp_compare.camera_size = (int(width), int(height))
    report: dict = {}
    _exec_run(bpy, out, report)
    _modal_run(bpy, report)
    _current_scene_run(bpy, report)
    registration.unregister()
    from addon.blender import compare_job, compare_props

    report["state_freed"] = not compare_job._ROWS and not compare_props._PRESET_ITEMS and not compare_job.is_running()
    # Shown by tests/support/checks.py when the flag fails.
    report["state_freed_values"] = {"row_lists": len(compare_job._ROWS),
                                    "preset_items": len(compare_props._PRESET_ITEMS),
                                    "running": compare_job.is_running()}
    report["pointer_removed"] = not hasattr(bpy.types.Scene, "omniwarp_compare")
    (out / "worker.json").write_text(json.dumps(report, indent=1, default=_json_default), encoding="utf-8")


def _json_default(value):
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    raise TypeError(f"cannot encode {type(value).__name__}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
