"""The preview as the viewport draws it, offscreen: the G-buffer, the pipeline per
light, the shadow composite and the map overlay, written as images with the error
against a Cycles reference (`run`). `headless.py` is the process that calls it
(`omniwarp preview`); the viewport shares its overlay panels and stats line.
"""
from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import numpy as np

from ..core import metrics
from ..core import methods as method_registry
from ..core.png import write_png
from ..core.scene import LightSpec
from ..reference.data import ReferenceData
from ..render.pipeline import Measure, ShadowPipeline, ShadowSettings, count_statistics
from ..render.resident import ResidentScene
from ..render.shaders import OVERLAY_MODES

log = logging.getLogger(__name__)

OVERLAY_SIZE = (960, 300)


def _write_png(path: Path, rgba_bottom_up: np.ndarray) -> None:
    write_png(path, rgba_bottom_up[::-1])  # clipped to [0, 1] there


def _offscreen_draw(size: tuple[int, int], draw) -> np.ndarray:
    """Run `draw()` into a float offscreen target; return (H, W, 4) RGBA, row 0 at the bottom."""
    import gpu

    from ..render.backends.blender.gpu_objects import float_texture, framebuffer, read_texture

    width, height = size
    color = float_texture((width, height), "RGBA32F")
    target = framebuffer(color_slots=(color,))
    with target.bind():
        target.clear(color=(0.08, 0.08, 0.09, 1.0))
        gpu.state.viewport_set(0, 0, width, height)
        with gpu.matrix.push_pop():
            with gpu.matrix.push_pop_projection():
                gpu.matrix.load_identity()
                gpu.matrix.load_projection_matrix(_pixel_projection(width, height))
                draw()
    return read_texture(color, "RGBA32F")


def _pixel_projection(width: int, height: int):
    """Orthographic projection for drawing text in pixels (blf uses the gpu matrix stack)."""
    from mathutils import Matrix

    return Matrix(((2.0 / width, 0, 0, -1.0), (0, 2.0 / height, 0, -1.0), (0, 0, -1.0, 0), (0, 0, 0, 1.0)))


def overlay_panels(result, stats, label: str, maps: set[str], thumb: int = 256) -> tuple[list, float]:
    """Thumbnails of one light: its depth layers, then count and importance maps.

    Maps are pooled to at most twice the thumbnail size first (max for counts, min
    for depth), so single busy texels stay visible instead of aliasing away.
    """
    from ..render.backends.blender.draw import OverlayPanel, pool_image

    panels = []
    res = result.layout.resolution if result.layout else 0
    top = max(stats.max_count_before, stats.max_count_after, 1.0)
    for layer in result.plan.drawn:
        if "DEPTH" in maps and result.atlas is not None:
            x, y = result.layout.origin(result.tile_of_slot[layer.slot])
            depth = pool_image(result.atlas[y:y + res, x:x + res], 2 * thumb, np.min)
            panels.append(OverlayPanel(f"depth {layer.name}", depth, OVERLAY_MODES["depth"]))
            if result.haze is not None:  # the media's transmittance map (passes/media.read_haze)
                kept = pool_image(result.haze[y:y + res, x:x + res], 2 * thumb, np.min)
                panels.append(OverlayPanel(f"transmittance {layer.name}", kept, OVERLAY_MODES["transmittance"]))
        if "COUNT" in maps:
            panels.append(OverlayPanel(f"count {layer.name}", pool_image(stats.before[layer.slot], 2 * thumb),
                                       OVERLAY_MODES["count"], top))
        if "IMPORTANCE" in maps:
            panels.append(OverlayPanel(f"importance {layer.name}", pool_image(stats.after[layer.slot], 2 * thumb),
                                       OVERLAY_MODES["count"], top))
    return panels, top


def stats_line(name: str, result, stats) -> str:
    """One line per light: passes, texels, max count before/after, ms per stage."""
    t = result.time_ms
    skipped = result.geometry.skipped_triangles
    return (f"{name}: {result.passes} passes, {result.texels / 1e6:.2f} M texels, max count "
            f"{stats.max_count_before:.0f} -> {stats.max_count_after:.0f}, ms: prepare {t['prepare']:.0f} "
            f"analysis {t['analysis']:.0f} maps {t['shadow_maps']:.0f} test {t['shadow_test']:.0f}"
            + (f", {skipped} broken triangles skipped" if skipped else ""))


def _resident(triangles: "np.ndarray | ResidentScene") -> ResidentScene:
    """A resident scene as given (with its see-through parts), or one of a triangle soup."""
    return triangles if isinstance(triangles, ResidentScene) else ResidentScene.of_triangles(triangles)


def run(reference: ReferenceData, lights: list[tuple[str, LightSpec, ShadowSettings]],
        triangles: "np.ndarray | ResidentScene",
        out_dir: Path, strength: float = 0.6, maps: frozenset[str] = frozenset({"DEPTH", "COUNT", "IMPORTANCE"}),
        thumb: int = 150,
        occluders: "dict[str, np.ndarray | ResidentScene] | None" = None) -> dict:
    """Render the preview of `lights` from the reference's camera and write the three files.

    `triangles` are what the camera sees (the G-buffer); `occluders` gives, per light
    name, what blocks that light (`scene_cache.shadow_inputs`), else `triangles` do. Either
    may be a resident scene, which keeps its see-through materials (the G-buffer then
    sees through them where alpha < 1/2, as Cycles' camera does).
    """
    from ..render.backends.blender.backend import BlenderGPUBackend
    from ..render.backends.blender.gpu_objects import ensure_gpu
    from ..render.backends.blender.draw import draw_overlay, draw_shadow_composite, render_gbuffer, visibility_texture

    ensure_gpu()
    out_dir.mkdir(parents=True, exist_ok=True)
    camera = reference.camera()  # shift, sensor fit, pixel aspect, ortho and clip as captured
    view = np.linalg.inv(camera.matrix_world)
    view_proj = camera.projection() @ view
    backend = BlenderGPUBackend()
    try:
        pipeline = ShadowPipeline(backend)
        # Resident before the clock starts, as in the viewport: the timed G-buffer is a
        # plain draw of the scene from the camera.
        seen = _resident(triangles)
        backend.sync_scene(seen)
        t0 = time.perf_counter()
        gbuffer = render_gbuffer(backend, seen, view_proj, camera.eye_homogeneous(), camera.resolution)
        backend.finish()
        gbuffer_ms = (time.perf_counter() - t0) * 1e3
        samples = gbuffer.samples(camera)  # stays on the GPU, as in the viewport
        per_light = []
        for name, light, settings in lights:
            # Resident once per light, as compare has it: the warm-up frame uploads it.
            blockers = _resident((occluders or {}).get(name, seen))
            pipeline.render(light, blockers, samples, settings)  # warm-up (shader compile, upload)
            result = pipeline.render(light, blockers, samples, settings, Measure(keep_atlas=True, sync_stages=True))
            stats = count_statistics(pipeline, light, settings, result, samples)
            raw = np.stack([result.visibility, result.flags.astype(np.float32)], axis=-1)
            per_light.append((name, light, settings, result, stats, raw))

        textures = [visibility_texture(raw) for (*_, raw) in per_light]

        def draw_preview() -> None:
            for index, ((_, light, _, _, _, _), texture) in enumerate(zip(per_light, textures)):
                draw_shadow_composite(backend, gbuffer, texture, light, strength, camera.resolution,
                                      draw_base=(index == 0))

        _write_png(out_dir / "preview.png", _offscreen_draw(camera.resolution, draw_preview))

        panels, lines, top = [], [], 1.0
        for name, _, _, result, stats, _ in per_light:
            light_panels, light_top = overlay_panels(result, stats, name, set(maps), thumb)
            panels += light_panels
            top = max(top, light_top)
            lines.append(stats_line(name, result, stats))
        width = max(OVERLAY_SIZE[0], 24 + len(panels) * (thumb + 6))
        overlay = _offscreen_draw((width, OVERLAY_SIZE[1]), lambda: draw_overlay(
            backend, panels, (width, OVERLAY_SIZE[1]), thumb, "BOTTOM_LEFT", lines,
            top if {"COUNT", "IMPORTANCE"} & set(maps) else None))
        _write_png(out_dir / "overlay.png", overlay)

        report = _report(reference, per_light, gbuffer, gbuffer_ms, backend.renderer())
        (out_dir / "preview.json").write_text(json.dumps(report, indent=1), encoding="utf-8")
        return report
    finally:
        backend.release()


def _report(reference: ReferenceData, per_light, gbuffer, gbuffer_ms: float, renderer: str) -> dict:
    """Error of the combined preview visibility against Cycles, and the times."""
    name, light, settings, result, stats, _ = per_light[0]
    evaluable = metrics.evaluable_mask(reference.position, reference.normal, reference.hit, reference.unshadowed, light)
    # The preview's own G-buffer must see the same surfaces as Cycles to be compared.
    agree = gbuffer.hit == reference.hit
    judged = metrics.judge(result.visibility, reference.shadowed, reference.unshadowed, evaluable & agree,
                           sized=light.sized, noise=reference.visibility_noise)
    figure = judged.figure
    lights = []
    for name, light, settings, result, stats, _ in per_light:
        lights.append({
            "light": name, "emission": light.emission,
            "method": method_registry.label_for(settings.parameterization, settings.warp, settings.cut,
                                                settings.edge_aa, settings.exact),
            "parameterization": settings.parameterization, "warp": settings.warp, "cut": settings.cut,
            "edge_aa": settings.edge_aa, "resolution": settings.resolution, "passes": result.passes,
            "texels": result.texels, "triangles_drawn": result.geometry.triangles_drawn,
            "max_count_before": stats.max_count_before, "max_count_after": stats.max_count_after,
            "texel_utilization": stats.texel_utilization, "time_ms": result.time_ms,
            "skipped_triangles": result.geometry.skipped_triangles,
        })
    return {
        "error_pct": figure.error_pct, "false_shadow_pct": figure.false_shadow_pct,
        "false_lit_pct": figure.false_lit_pct, "evaluated_pixels": figure.evaluated_pixels,
        "gbuffer_hit_agreement": float(agree.mean()),
        # Mean |visibility - reference| in %, and a sized light's own noise (docs/soft.md).
        **{key: value for key, value in judged.columns().items()
           if key in ("soft_error_pct", "reference_noise_pct") and value is not None},
        "time_ms": {"gbuffer": gbuffer_ms, **{k: sum(entry["time_ms"][k] for entry in lights)
                                              for k in ("total", "prepare", "analysis", "shadow_maps", "shadow_test")}},
        "lights": lights, "renderer": renderer, "backend": "blender-gpu", "camera_size": list(reference.resolution),
        "reference": reference.meta.get("preset", "custom"),
    }
