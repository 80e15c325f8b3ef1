"""Viewport preview and map overlay: one POST_PIXEL draw handler on the 3D view.

Each redraw of a 3D view with the preview on:
  1. works out whether its result is stale: the view or projection changed, or a
     light setting, geometry or transform changed (`request_update`);
  2. if stale and the last recompute is older than the scene's throttle, renders
     the G-buffer at the region's size times the resolution scale, runs the
     pipeline per enabled light on Blender's `gpu` backend, and keeps the result;
     if it is too soon, a timer asks for a redraw once the throttle has passed;
  3. draws the shadow composite (shadowed surfaces darkened) if the result belongs
     to the current view, then the map overlay in the chosen corner.

GPU objects are created lazily in the draw callback (where a GL context is
current) and freed on unregister.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any

import bpy
import numpy as np

from ..core.errors import OmniWarpError
from ..core.scene import camera_from_matrices
from ..render.pipeline import ShadowPipeline, ViewSamples, count_statistics
from . import properties

log = logging.getLogger(__name__)


@dataclass
class _ViewResult:
    key: tuple
    gbuffer: Any
    lights: list = field(default_factory=list)  # (name, LightSpec, settings, FrameResult, stats, raw)
    computed_at: float = 0.0
    version: int = -1  # the update version it was computed for


@dataclass
class _State:
    handler: Any = None
    backend: Any = None
    pipeline: ShadowPipeline | None = None
    results: dict[int, _ViewResult] = field(default_factory=dict)  # by region pointer
    version: int = 0  # bumped by every change that makes all views stale
    timer_pending: bool = False
    last_error: str = ""


_STATE = _State()


# Contract used by properties.py and scene_cache.py -------------------------------
def register() -> None:
    """Install the draw handler (idempotent)."""
    if _STATE.handler is None:
        _STATE.handler = bpy.types.SpaceView3D.draw_handler_add(_draw, (), "WINDOW", "POST_PIXEL")
    _STATE.version += 1


def unregister() -> None:
    """Remove the draw handler and free every GPU object (idempotent)."""
    if _STATE.handler is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_STATE.handler, "WINDOW")
        _STATE.handler = None
    if bpy.app.timers.is_registered(_throttle_elapsed):
        bpy.app.timers.unregister(_throttle_elapsed)
    _STATE.timer_pending = False
    _free()


def _free() -> None:
    _STATE.results.clear()
    _STATE.pipeline = None
    if _STATE.backend is not None:
        _STATE.backend.release()
        _STATE.backend = None


def set_preview_enabled(context: bpy.types.Context, enabled: bool) -> None:
    """Turn the preview on or off; off frees the cached results and GPU objects."""
    if not enabled:
        _free()
    _STATE.version += 1
    tag_redraw_all()


def request_update(reason: str) -> None:
    """Mark every preview stale (light settings, geometry or transforms changed)."""
    log.debug("preview update requested: %s", reason)
    _STATE.version += 1
    tag_redraw_all()


def tag_redraw_all() -> None:
    """Redraw every 3D view of every window."""
    wm = bpy.context.window_manager
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


def _throttle_elapsed() -> None:
    _STATE.timer_pending = False
    tag_redraw_all()
    return None  # one-shot timer


# Computation --------------------------------------------------------------------
def _lights(scene: bpy.types.Scene, depsgraph) -> list:
    chosen = []
    for obj in scene.objects:
        if obj.type == "LIGHT" and properties.is_supported_light(obj.data) and obj.data.omniwarp.enabled:
            if obj.visible_get(view_layer=depsgraph.view_layer):
                evaluated = obj.evaluated_get(depsgraph)
                chosen.append((obj.name, properties.light_spec_for(evaluated), properties.shadow_settings_for(obj.data)))
    return chosen


def compute_view(backend, pipeline: ShadowPipeline, triangles: np.ndarray, view_matrix: np.ndarray,
                 projection: np.ndarray, size: tuple[int, int], lights: list) -> tuple[Any, list]:
    """G-buffer of one view and the pipeline result of every light (explicit inputs, for tests too)."""
    from ..render.blender_draw import render_gbuffer

    view_proj = projection @ view_matrix
    camera_position = np.linalg.inv(view_matrix)[:3, 3]
    gbuffer = render_gbuffer(backend, triangles, view_proj, camera_position, size)
    camera = camera_from_matrices(view_matrix, projection, size)
    samples = ViewSamples(gbuffer.positions[..., :3].astype(np.float64),
                          gbuffer.normals[..., :3].astype(np.float64), gbuffer.hit, camera)
    results = []
    for name, light, settings in lights:
        result = pipeline.render(light, triangles, samples, settings, keep_atlas=True)
        stats = count_statistics(pipeline, light, settings, result)
        raw = np.stack([result.visibility, result.flags.astype(np.float32)], axis=-1)
        results.append((name, light, settings, result, stats, raw))
    return gbuffer, results


def _ensure_backend() -> None:
    if _STATE.backend is None:
        from ..render.blender_backend import BlenderGPUBackend

        _STATE.backend = BlenderGPUBackend()
        _STATE.pipeline = ShadowPipeline(_STATE.backend)


def _view_key(rv3d, size: tuple[int, int]) -> tuple:
    view = tuple(round(v, 6) for row in rv3d.view_matrix for v in row)
    proj = tuple(round(v, 6) for row in rv3d.window_matrix for v in row)
    return view, proj, size


def _draw() -> None:
    """POST_PIXEL callback of every 3D view."""
    context = bpy.context
    scene = context.scene
    settings = getattr(scene, "omniwarp", None)
    region, rv3d = context.region, context.region_data
    if settings is None or not settings.preview_enabled or region is None or rv3d is None:
        return
    scale = settings.camera_resolution_scale
    size = (max(8, int(region.width * scale)), max(8, int(region.height * scale)))
    key = _view_key(rv3d, size)
    cached = _STATE.results.get(region.as_pointer())
    stale = cached is None or cached.key != key or cached.version != _STATE.version
    now = time.perf_counter()
    if stale:
        last = max((r.computed_at for r in _STATE.results.values()), default=0.0)
        if now - last >= settings.throttle_ms / 1000.0:
            cached = _recompute(context, scene, region, rv3d, size, key)
        elif not _STATE.timer_pending:
            _STATE.timer_pending = True
            bpy.app.timers.register(_throttle_elapsed, first_interval=settings.throttle_ms / 1000.0)
    if cached is None:
        return
    import gpu

    from ..render.blender_draw import draw_overlay, draw_shadow_composite
    from .headless import overlay_panels, stats_line

    target = (region.width, region.height)
    if cached.key == key and cached.gbuffer is not None:
        for _, light, _, _, _, raw in cached.lights:
            draw_shadow_composite(_STATE.backend, cached.gbuffer, raw, light.position, settings.shadow_strength,
                                  target, draw_base=False)
    if settings.overlay_enabled and cached.lights:
        panels, lines, top = [], [], 1.0
        for name, _, _, result, stats, _ in cached.lights:
            light_panels, light_top = overlay_panels(result, stats, name, set(settings.overlay_maps),
                                                     settings.overlay_size)
            panels += light_panels
            top = max(top, light_top)
            if settings.overlay_stats:
                lines.append(stats_line(name, result, stats))
        counts_shown = {"COUNT", "IMPORTANCE"} & set(settings.overlay_maps)
        gpu.state.viewport_set(0, 0, region.width, region.height)
        draw_overlay(_STATE.backend, panels, target, settings.overlay_size, settings.overlay_corner, lines,
                     top if counts_shown else None)
    if _STATE.last_error:
        import blf

        blf.position(0, 12, region.height - 40, 0)
        blf.draw(0, f"OmniWarp: {_STATE.last_error}")


def _recompute(context, scene, region, rv3d, size, key) -> _ViewResult | None:
    import gpu

    from .scene_cache import CACHE

    depsgraph = context.evaluated_depsgraph_get()
    viewport = gpu.state.viewport_get()
    try:
        _ensure_backend()
        CACHE.update(depsgraph)
        triangles = CACHE.world_triangles()
        lights = _lights(scene, depsgraph)
        gbuffer, results = compute_view(_STATE.backend, _STATE.pipeline, triangles,
                                        np.array(rv3d.view_matrix), np.array(rv3d.window_matrix), size, lights)
        entry = _ViewResult(key, gbuffer, results, time.perf_counter(), _STATE.version)
        _STATE.results[region.as_pointer()] = entry
        _STATE.last_error = ""
        return entry
    except OmniWarpError as exc:
        # A named failure (bad geometry, a shader that does not build) is shown in the
        # view and logged; drawing Blender's own viewport must go on regardless.
        _STATE.last_error = str(exc)
        log.error("preview failed: %s", exc)
        # Remember the failure for this view and version, so it is not retried every redraw.
        _STATE.results[region.as_pointer()] = _ViewResult(key, None, [], time.perf_counter(), _STATE.version)
        return None
    finally:
        gpu.state.viewport_set(*viewport)
