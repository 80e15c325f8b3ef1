"""Runs Blender `gpu` work in its own process for the tests (one GL owner per process).

    python tests/support/blender_gpu_worker.py backends OUT.npz
    python tests/support/blender_gpu_worker.py viewport OUT.json
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

CASES = (("dpsm", "none"), ("cube", "none"), ("dpsm", "notw"), ("cube", "rtw"))


def backends(out: str) -> None:
    """The pipeline on Blender's gpu backend for the seam scene, every case."""
    from addon.render.blender_backend import BlenderGPUBackend, ensure_gpu
    from addon.render.pipeline import ShadowPipeline, ShadowSettings
    from tests.gl.test_pipeline_extremes import _seam_straddler
    from tests.support.oracle import view_samples

    ensure_gpu()
    scene = _seam_straddler()
    samples, _, _ = view_samples(scene)
    backend = BlenderGPUBackend()
    pipeline = ShadowPipeline(backend)
    arrays = {}
    for param, warp in CASES:
        result = pipeline.render(scene.light, scene.world_triangles(), samples, ShadowSettings(param, 256, warp=warp),
                                 keep_atlas=True)
        arrays[f"{param}_{warp}_visibility"] = result.visibility
        arrays[f"{param}_{warp}_atlas"] = result.atlas
    backend.release()
    np.savez(out, **arrays)


def viewport(out: str) -> None:
    """Register the extension, preview a preset light through the viewport's own
    compute function with explicit matrices, then unregister."""
    import bpy

    from addon.blender import registration, viewport as vp
    from addon.blender.scene_cache import CACHE
    from addon.core.presets import build_preset
    from addon.reference.blender_scene import build_blender_scene
    from addon.reference.capture import evaluated_depsgraph
    from addon.render.blender_backend import ensure_gpu

    ensure_gpu()
    handlers_before = len(bpy.app.handlers.depsgraph_update_post)
    registration.register()
    spec = build_preset("room_hemi", (96, 72))
    scene = build_blender_scene(spec)
    light_obj = next(o for o in scene.objects if o.type == "LIGHT")
    light_obj.data.omniwarp.enabled = True
    light_obj.data.omniwarp.parameterization = "CUBE"
    light_obj.data.omniwarp.warp = "NOTW"
    light_obj.data.omniwarp.resolution = 256
    depsgraph = evaluated_depsgraph(scene)
    CACHE.update(depsgraph)
    vp._ensure_backend()
    lights = vp._lights(scene, depsgraph)
    view = np.linalg.inv(spec.camera.matrix_world)
    gbuffer, results = vp.compute_view(vp._STATE.backend, vp._STATE.pipeline, CACHE.world_triangles(), view,
                                       spec.camera.projection(), spec.camera.resolution, lights)
    name, light, settings, result, stats, raw = results[0]
    report = {
        "lights": len(results), "passes": result.passes, "param": settings.parameterization, "warp": settings.warp,
        "hit_share": float(gbuffer.hit.mean()), "shadowed_share": float((raw[..., 0][gbuffer.hit] < 0.5).mean()),
        "finite_atlas": bool(np.isfinite(result.atlas).all()),
        "max_before": stats.max_count_before, "max_after": stats.max_count_after,
        "handler_installed": vp._STATE.handler is not None,
    }
    registration.unregister()
    registration.unregister()  # idempotent
    report["handler_removed"] = vp._STATE.handler is None and vp._STATE.backend is None
    report["depsgraph_handlers_restored"] = len(bpy.app.handlers.depsgraph_update_post) == handlers_before
    report["pointer_removed"] = not hasattr(bpy.types.Light, "omniwarp")
    Path(out).write_text(json.dumps(report))


if __name__ == "__main__":
    {"backends": backends, "viewport": viewport}[sys.argv[1]](sys.argv[2])
