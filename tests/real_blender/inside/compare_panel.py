"""Inside a real Blender binary (`blender -b --python THIS -- OUT_JSON SOURCE [BLEND]`), with
the extension installed from its zip: the comparison operator as the panel runs it.

SOURCE is a preset name (the panel's Preset source) or CURRENT (the scene of the .blend the
binary opened). Writes OUT_JSON with the operator's result, the rows as Export writes them
(JSON and CSV beside OUT_JSON), the plot image's statistics and the log's warnings.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import bpy
import numpy as np

sys.path.insert(0, "/omniwarp")  # the repository, bound read-only in the chroot (scripts/real_blender.sh)
from tests.support.extension_worker import ADDON_MODULE as PACKAGE  # noqa: E402
METHODS = ("dpsm", "dpsm+notw", "exact")


def _image_stats(image) -> dict:
    if image is None:
        return {"name": None}
    pixels = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return {"name": image.name, "size": list(image.size), "std": float(pixels.std()) if pixels.size else 0.0}


def main(out_json: str, source: str) -> None:
    import importlib

    out = Path(out_json)
    compare_job = importlib.import_module(PACKAGE + ".addon.blender.compare_job")
    compare_props = importlib.import_module(PACKAGE + ".addon.blender.compare_props")
    methods = importlib.import_module(PACKAGE + ".addon.core.methods")
    scene = bpy.context.scene
    settings = scene.omniwarp_compare
    if source == "CURRENT":
        settings.source = "CURRENT"
    else:
        settings.source = "PRESET"
        settings.preset = source
    for method in methods.pipeline_methods():
        setattr(settings, compare_props.method_prop(method), method in METHODS)
    settings.resolutions = "1024"
    settings.frames = 1
    report: dict = {"result": sorted(bpy.ops.omniwarp.compare("EXEC_DEFAULT"))}
    report["backend"] = __import__("gpu").platform.backend_type_get()  # initialised by the operator
    report["status"] = settings.status
    report["rows"] = compare_job.rows_for_export(bpy.context.scene)
    report["plot"] = _image_stats(settings.plot_image)
    exports = {}
    for suffix in ("json", "csv"):
        settings.export_path = str(out.with_name(out.stem + "_export." + suffix))
        exports[suffix] = sorted(bpy.ops.omniwarp.export_results())
    report["exports"] = exports
    out.write_text(json.dumps(report, indent=1, default=str), encoding="utf-8")


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:]
    main(*argv[:2])
