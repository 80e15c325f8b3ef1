"""Viewport preview and map overlay: one POST_PIXEL draw handler on the 3D view.

Each redraw of a 3D view with the preview on:
  1. works out whether its result is stale: the view or projection changed, or a
     light setting, geometry or transform changed (`request_update` bumps a version);
  2. if stale and the last recompute is older than the scene's throttle, renders
     the G-buffer at the region's size times the resolution scale, runs the
     pipeline per enabled light on Blender's `gpu` backend, and keeps the result;
     if it is too soon, a one-shot timer asks for a redraw once the throttle passed.
     A recompute whose last one took over SPREAD_OVER_S (a million triangles on
     llvmpipe: seconds) is spread over redraws: each goes on with it for about
     STEP_BUDGET_S (render/pacing.py cuts its long draws into slices) and asks for the
     next redraw, while the last result stays drawn, reprojected;
  3. draws the shadow composite (shadowed surfaces darkened): the result's own if it
     belongs to the current view; otherwise (the view moved within the throttle) the
     result reprojected into this view, through a G-buffer of this view (a pixel the
     result's view did not see is drawn lit); then the map overlay in the chosen corner.
     While recomputes are spread, no redraw draws a G-buffer of its own: the spread
     recompute's, once drawn, or the newest one at hand serves (its pixels trail the
     view for a few redraws).

`draw_view` does all of that from explicit matrices and sizes, so tests drive it
without a window. GPU objects are created lazily (a GL context is current in a
draw callback), reused across redraws, and freed on unregister, file load and
when the preview is switched off.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import bpy
import numpy as np

from ..core import validate
from ..core.errors import InputError
from ..core.scene import camera_from_matrices
from ..render.pacing import Steps, drive
from ..render.pipeline import Measure, ShadowPipeline, count_statistics
from ..render.resident import ResidentScene
from . import events, properties

log = logging.getLogger(__name__)


@dataclass
class _ViewResult:
    key: tuple
    version: int
    gbuffer: Any = None
    # (name, LightSpec, settings, FrameResult, stats, visibility): the visibility an RG32F
    # texture of the G-buffer's size (row 0 at the bottom) that stays on the GPU
    lights: list = field(default_factory=list)
    visibility: list = field(default_factory=list)  # each light's visibility texture
    panels: list = field(default_factory=list)  # overlay panels (they keep their textures)
    lines: list = field(default_factory=list)
    top: float = 1.0
    computed_at: float = 0.0
    seen: Any = None  # the resident scene its G-buffer drew: a moved view's G-buffer draws it too
    reprojection: Any = None  # backends/blender/draw.Reprojection of its view
    moved: Any = None  # the G-buffer of the latest moved view (reused while its size holds)
    moved_key: tuple | None = None  # the view `moved` was drawn for: redrawn only when the view moves
    overlay: bool = True  # whether the overlay's maps and statistics were read for it


@dataclass
class _State:
    handler: Any = None
    backend: Any = None
    pipeline: ShadowPipeline | None = None
    results: dict[Any, _ViewResult] = field(default_factory=dict)  # by region
    version: int = 0  # bumped by every change that makes all views stale
    timer_pending: bool = False
    grid_layer: tuple[str, str] | None = None  # (scene, view layer) whose grids `_read_grids` reads
    pending: "_Pending | None" = None  # a recompute spread over redraws (one at a time: one backend)
    compute_s: float = 0.0  # how long the last recompute took in draw callbacks (all of its steps)
    last_drawn: str = ""  # what the last redraw drew: "computed", "cached", "reprojected" or "none"
    last_error: str = ""
    reported: set[str] = field(default_factory=set)  # errors already logged once


@dataclass
class _Pending:
    """A recompute spread over redraws: its stepped pass and what it is for."""

    steps: Any  # compute_view_steps(...)
    region: Any
    key: tuple
    version: int
    seen: Any
    view_proj: np.ndarray
    projection: np.ndarray
    spent: float = 0.0  # seconds of draw callbacks it took so far
    touched: float = field(default_factory=time.perf_counter)  # when a redraw last went on with it
    gbuffer: Any = None  # its view's G-buffer, once its first stage has drawn it


# How long one redraw may go on with a spread recompute before it draws what it has: with
# the pacer's slices (pacing.STEP_S) a callback stays near 0.1 s on llvmpipe.
STEP_BUDGET_S = 0.05
# A recompute is spread over redraws when the last one took longer than this; a shorter
# one is done in the redraw that needs it, as it always was.
SPREAD_OVER_S = 0.2
ORPHAN_S = 2.0  # a spread recompute its region has not gone on with for this long is dropped

_STATE = _State()


# Contract used by properties.py and scene_cache.py ------------------------------
def register() -> None:
    """Install the draw handler and the file-load and undo handlers (idempotent)."""
    if _STATE.handler is None:
        _STATE.handler = bpy.types.SpaceView3D.draw_handler_add(_draw, (), "WINDOW", "POST_PIXEL")
    for event, callback in _EVENTS:
        events.listen(event, callback)
    for handlers, callback in _APP_HANDLERS:
        if callback not in handlers:
            handlers.append(callback)
    _STATE.version += 1


def unregister() -> None:
    """Remove every handler, in mirror order, and free every GPU object (idempotent)."""
    for event, _ in reversed(_EVENTS):
        events.forget(event)
    for handlers, callback in reversed(_APP_HANDLERS):
        while callback in handlers:
            handlers.remove(callback)
    for timer in (_throttle_elapsed, _read_grids, _go_on):
        if bpy.app.timers.is_registered(timer):
            bpy.app.timers.unregister(timer)
    _STATE.timer_pending = False
    if _STATE.handler is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_STATE.handler, "WINDOW")
        _STATE.handler = None
    free_resources()


def free_resources() -> None:
    """Drop cached results, a spread recompute and the backend (with all its GPU objects)."""
    _drop_pending()
    _STATE.results.clear()
    _STATE.pipeline = None
    if _STATE.backend is not None:
        _STATE.backend.release()
        _STATE.backend = None


def live_resources() -> int:
    """Distinct GPU objects the preview holds now: the backend's and the cached results'."""
    from ..render.backends.blender.gpu_objects import count_gpu_objects

    return count_gpu_objects(_STATE.backend, _STATE.results)


def set_preview_enabled(context: bpy.types.Context, enabled: bool) -> None:
    """Turn the preview on or off; off frees the cached results and GPU objects."""
    if not enabled:
        free_resources()
    _STATE.version += 1
    _STATE.last_error = ""
    events.redraw_3d_views()


def request_update(reason: str) -> None:
    """Mark every preview stale (light settings, geometry or transforms changed)."""
    log.debug("preview update requested: %s", reason)
    _STATE.version += 1
    events.redraw_3d_views()


@bpy.app.handlers.persistent
def _on_load_post(*_args) -> None:
    # Results refer to the old file's lights and geometry: drop them with their textures.
    free_resources()
    _STATE.version += 1


@bpy.app.handlers.persistent
def _on_undo_redo(*_args) -> None:
    _STATE.version += 1


_APP_HANDLERS = (
    (bpy.app.handlers.load_post, _on_load_post),
    (bpy.app.handlers.undo_post, _on_undo_redo),
    (bpy.app.handlers.redo_post, _on_undo_redo),
)


def _throttle_elapsed() -> None:
    _STATE.timer_pending = False
    events.redraw_3d_views()
    return None  # one-shot timer


def _go_on() -> None:
    """One-shot timer: a redraw, for a spread recompute to go on."""
    events.redraw_3d_views()
    return None


def _slow() -> bool:
    """Whether the last recompute took long enough to be spread over redraws."""
    return _STATE.compute_s > SPREAD_OVER_S


def _drop_pending() -> None:
    pending, _STATE.pending = _STATE.pending, None
    if pending is not None:
        pending.steps.close()
        if _STATE.backend is not None:
            _STATE.backend.pacer.stepping = False


def _advance(pending: _Pending, settings) -> _ViewResult | None:
    """Go on with a spread recompute for STEP_BUDGET_S; its result once it has ended (else
    a redraw is asked for, to go on)."""
    backend = _STATE.backend
    start = time.perf_counter()
    backend.pacer.stepping = True
    backend.pacer.deadline = start + STEP_BUDGET_S
    try:
        while time.perf_counter() - start < STEP_BUDGET_S:
            next(pending.steps)
    except StopIteration as done:
        _STATE.pending = None
        _STATE.compute_s = pending.spent + time.perf_counter() - start
        gbuffer, results = done.value
        return _build_result(pending.key, gbuffer, results, settings, pending.seen, pending.view_proj,
                             pending.projection, version=pending.version)
    except BaseException:
        _drop_pending()
        raise
    finally:
        backend.pacer.stepping = False
        backend.pacer.deadline = None
    pending.spent += time.perf_counter() - start
    pending.touched = time.perf_counter()
    if bpy.app.timers is not None and not bpy.app.timers.is_registered(_go_on):
        bpy.app.timers.register(_go_on, first_interval=0.0)
    return None


def _read_grids() -> float | None:
    """Read the density grids that need geometry nodes (scene_grids.py): they add objects
    to bpy.data, which a draw may not, so the draw leaves them to this one-shot timer, for
    the scene and view layer it drew. While a render runs it waits (a second at a time):
    the readers' objects are not added under a render's feet."""
    from .scene_cache import CACHE

    if getattr(bpy.app, "is_job_running", None) is not None and bpy.app.is_job_running("RENDER"):
        return 1.0
    names, _STATE.grid_layer = _STATE.grid_layer, None
    scene = bpy.data.scenes.get(names[0]) if names else None
    layer = scene.view_layers.get(names[1]) if scene is not None else None
    if layer is None:
        return None
    try:
        if CACHE.read_grids(scene, layer):
            request_update("density grids read")
    except (RuntimeError, ReferenceError, KeyError, ValueError) as exc:
        log.warning("the viewport could not read its density grids: %s", exc)
    return None


def _schedule_grid_read(scene: bpy.types.Scene, depsgraph) -> None:
    """Register `_read_grids` when the cache has grids waiting for it."""
    from .scene_cache import CACHE

    if CACHE.grids.pending and bpy.app.timers is not None and not bpy.app.timers.is_registered(_read_grids):
        _STATE.grid_layer = (scene.name_full, depsgraph.view_layer.name)
        bpy.app.timers.register(_read_grids, first_interval=0.0)


def compute_view(backend, pipeline: ShadowPipeline, seen: ResidentScene, view_matrix: np.ndarray,
                 projection: np.ndarray, size: tuple[int, int], lights: list,
                 occluders: dict[str, ResidentScene] | None = None, overlay: bool = True) -> tuple[Any, list]:
    """G-buffer of one view and the pipeline result of every light (explicit inputs).

    `seen` is what the camera sees, resident; `occluders` gives, per light name, what
    blocks that light (`scene_cache.resident_inputs`), else `seen` does. The G-buffer
    stays on the GPU as the frame's samples, and each light's visibility stays there too:
    drawn into a texture of its own, never read back. Only for the `overlay` are the maps
    read back and the count statistics scattered (stats None otherwise).
    """
    return drive(compute_view_steps(backend, pipeline, seen, view_matrix, projection, size, lights, occluders,
                                    overlay))


def compute_view_steps(backend, pipeline: ShadowPipeline, seen: ResidentScene, view_matrix: np.ndarray,
                       projection: np.ndarray, size: tuple[int, int], lights: list,
                       occluders: dict[str, ResidentScene] | None = None,
                       overlay: bool = True, drawn: Callable[[Any], None] | None = None) -> Steps[tuple[Any, list]]:
    """`compute_view` as a stepped pass (render/pacing.py): it yields between slices of its
    long draws while the backend's pacer is stepping (`_advance`). `drawn` is given the
    G-buffer as soon as it is drawn (a spread recompute's reprojection draws with it)."""
    from ..render.backends.blender.draw import render_gbuffer_steps

    view_proj = projection @ view_matrix
    # Perspective, lens-shifted or orthographic: the view's real frustum, so culling works.
    camera = camera_from_matrices(view_matrix, projection, size)
    eye = np.linalg.inv(view_matrix)[:3, 3] if camera is None else camera.eye_homogeneous()
    gbuffer = yield from render_gbuffer_steps(backend, seen, view_proj, eye, size)
    if drawn is not None:
        drawn(gbuffer)
    samples = gbuffer.samples(camera)  # stays on the GPU
    results = []
    for name, light, settings in lights:
        yield from backend.pacer.pause()
        result = yield from pipeline.render_steps(light, (occluders or {}).get(name, seen), samples, settings,
                                                  Measure(keep_atlas=overlay))
        stats = count_statistics(pipeline, light, settings, result, samples) if overlay else None
        texture = backend.device.texture(size, "RG32F")
        target = backend.device.target((texture,))
        try:
            pipeline.visibility_into(result, target)
        finally:
            backend.device.free(target)
        result.discard()  # composited from its texture: nothing is read back
        results.append((name, light, settings, result, stats, texture))
    return gbuffer, results


def _ensure_backend() -> None:
    if _STATE.backend is None:
        from ..render.backends.blender.backend import BlenderGPUBackend

        _STATE.backend = BlenderGPUBackend()
        _STATE.pipeline = ShadowPipeline(_STATE.backend)


def _view_key(view_matrix: np.ndarray, projection: np.ndarray, size: tuple[int, int]) -> tuple:
    return (tuple(np.round(np.asarray(view_matrix, float), 6).ravel()),
            tuple(np.round(np.asarray(projection, float), 6).ravel()), size)


def _build_result(key: tuple, gbuffer, lights: list, settings, seen=None, view_proj=None,
                  projection=None, version: int | None = None) -> _ViewResult:
    from ..render.backends.blender.draw import Reprojection
    from .preview import overlay_panels, stats_line

    version = _STATE.version if version is None else version  # a spread recompute's: when it began
    entry = _ViewResult(key, version, gbuffer, lights, computed_at=time.perf_counter(), seen=seen,
                        overlay=bool(settings.overlay_enabled))
    if view_proj is not None and gbuffer is not None:
        entry.reprojection = Reprojection.of(view_proj, projection, gbuffer)
    entry.visibility = [texture for (*_, texture) in lights]
    for name, _, _, result, stats, _ in lights:
        if stats is None:
            continue  # the overlay was off: its maps were not read
        panels, top = overlay_panels(result, stats, name, set(settings.overlay_maps), settings.overlay_size)
        entry.panels += panels
        entry.top = max(entry.top, top)
        entry.lines.append(stats_line(name, result, stats))
    return entry


def draw_view(scene: bpy.types.Scene, depsgraph, view_matrix: np.ndarray, projection: np.ndarray,
              target_size: tuple[int, int], region_key: Any, now: float | None = None) -> bool:
    """Recompute if stale (and allowed by the throttle), then draw into the bound target.

    Returns True when a fresh or cached result for this exact view was drawn.
    """
    import gpu

    from ..render.backends.blender.draw import draw_overlay, draw_shadow_composite
    from .scene_cache import CACHE, resident_inputs

    settings = scene.omniwarp
    # NaN set from Python passes Blender's clamping: refuse it rather than draw garbage.
    validate.finite_number("shadow strength", settings.shadow_strength, 0.0, 1.0)
    scale = validate.finite_number("sample scale", settings.camera_resolution_scale, 0.1, 1.0)
    size = (max(8, int(target_size[0] * scale)), max(8, int(target_size[1] * scale)))
    key = _view_key(view_matrix, projection, size)
    cached = _STATE.results.get(region_key)
    now = time.perf_counter() if now is None else now
    recomputed = False
    # A result made with the overlay off lacks its maps: turning the overlay on recomputes.
    lacks_overlay = cached is not None and settings.overlay_enabled and not cached.overlay
    pending = _STATE.pending
    if pending is not None and pending.region != region_key and now - pending.touched > ORPHAN_S:
        _drop_pending()  # its region no longer redraws (closed, hidden): the others may go on
        pending = None
    stale = cached is None or cached.key != key or cached.version != _STATE.version or lacks_overlay
    if pending is not None:
        # A recompute spread over redraws: this region's goes on; another region waits for it.
        if pending.region == region_key:
            viewport = gpu.state.viewport_get()
            try:
                done = _advance(pending, settings)
            finally:
                gpu.state.viewport_set(*viewport)
            if done is not None:
                cached = _STATE.results[region_key] = done
                _STATE.last_error = ""
                recomputed = True
    elif stale:
        last = max((r.computed_at for r in _STATE.results.values()), default=-1e9)
        if now - last >= settings.throttle_ms / 1000.0 or cached is None:
            viewport = gpu.state.viewport_get()
            try:
                _ensure_backend()
                CACHE.update(depsgraph)
                _schedule_grid_read(scene, depsgraph)
                lights = properties.enabled_lights(scene, depsgraph)
                # Only objects that changed since the last view are uploaded; removed ones are freed.
                _STATE.backend.sync_scene(CACHE.resident())
                seen, occluders = resident_inputs(CACHE, scene, [name for name, _, _ in lights])
                if cached is None or not _slow():  # at once (nothing to draw meanwhile)
                    steps = compute_view_steps(_STATE.backend, _STATE.pipeline, seen, view_matrix, projection, size,
                                               lights, occluders, settings.overlay_enabled)
                    start = time.perf_counter()
                    gbuffer, results = drive(steps)
                    done = _build_result(key, gbuffer, results, settings, seen, projection @ view_matrix, projection)
                    _STATE.compute_s = time.perf_counter() - start
                else:  # the last result stays drawn (reprojected) while this one is spread over redraws
                    pending = _STATE.pending = _Pending(None, region_key, key, _STATE.version, seen,
                                                        projection @ view_matrix, projection)
                    pending.steps = compute_view_steps(_STATE.backend, _STATE.pipeline, seen, view_matrix, projection,
                                                       size, lights, occluders, settings.overlay_enabled,
                                                       drawn=lambda gbuffer: setattr(pending, "gbuffer", gbuffer))
                    done = _advance(pending, settings)
                if done is not None:
                    cached = _STATE.results[region_key] = done
                    _STATE.last_error = ""
                    recomputed = True
            finally:
                gpu.state.viewport_set(*viewport)
        elif not _STATE.timer_pending and bpy.app.timers is not None:
            _STATE.timer_pending = True
            bpy.app.timers.register(_throttle_elapsed, first_interval=settings.throttle_ms / 1000.0)
    if cached is None:
        _STATE.last_drawn = "none"
        return False
    current = cached.key == key
    if current and cached.gbuffer is not None:
        _STATE.last_drawn = "computed" if recomputed else "cached"
        for (_, light, _, _, _, _), texture in zip(cached.lights, cached.visibility):
            draw_shadow_composite(_STATE.backend, cached.gbuffer, texture, light, settings.shadow_strength,
                                  target_size, draw_base=False)
    elif (cached.reprojection is not None and cached.seen is not None and cached.lights
          and (_STATE.pending is None or _STATE.pending.seen is cached.seen)):
        # (While a spread recompute runs on another scene, drawing the old one's G-buffer
        # would sync the backend back to it under the recompute's feet.)
        pending = _STATE.pending
        # This region's spread recompute's G-buffer, once drawn: the newest of this view.
        stand_in = pending.gbuffer if pending is not None and pending.region == region_key else None
        _draw_reprojected(cached, view_matrix, projection, size, target_size, settings.shadow_strength, key, stand_in)
        _STATE.last_drawn = "reprojected"
    else:
        _STATE.last_drawn = "none"
    if settings.overlay_enabled and cached.panels:
        shown = {"COUNT", "IMPORTANCE"} & set(settings.overlay_maps)
        draw_overlay(_STATE.backend, cached.panels, target_size, settings.overlay_size, settings.overlay_corner,
                     cached.lines if settings.overlay_stats else [], cached.top if shown else None)
    return current


def _draw_reprojected(cached: _ViewResult, view_matrix: np.ndarray, projection: np.ndarray,
                      size: tuple[int, int], target_size: tuple[int, int], strength: float, key: tuple,
                      stand_in: Any = None) -> None:
    """The cached result drawn over a view it was not computed for: a G-buffer of this view
    (drawn into the last one of its size, and only when the view moved since: a spread
    recompute redraws one view many times), each light's visibility looked up where this
    view's points land in the result's view. On a scene whose recomputes are spread the
    newest G-buffer at hand stands in for this view's: `stand_in` (the spread recompute's),
    else the last one drawn."""
    import gpu

    from ..render.backends.blender.draw import draw_shadow_composite, render_gbuffer

    gbuffer = cached.moved if cached.moved is not None and cached.moved_key == key else None
    if gbuffer is None and _slow():
        # A G-buffer of this view would hold the redraw as long as a slice of the recompute
        # (a million triangles: 0.25 s on llvmpipe): the newest one at hand is drawn instead,
        # the spread recompute's own once its first stage has drawn it. Its pixels trail
        # the view by the redraws since; the shadows it looks up are where they belong.
        gbuffer = next(g for g in (stand_in, cached.moved, cached.gbuffer) if g is not None)
    if gbuffer is None:
        camera = camera_from_matrices(view_matrix, projection, size)
        eye = np.linalg.inv(view_matrix)[:3, 3] if camera is None else camera.eye_homogeneous()
        viewport = gpu.state.viewport_get()
        try:
            gbuffer = cached.moved = render_gbuffer(_STATE.backend, cached.seen, projection @ view_matrix, eye,
                                                    size, reuse=cached.moved)
            cached.moved_key = key
        finally:
            gpu.state.viewport_set(*viewport)
    for (_, light, _, _, _, _), texture in zip(cached.lights, cached.visibility):
        draw_shadow_composite(_STATE.backend, gbuffer, texture, light, strength, target_size, draw_base=False,
                              reprojection=cached.reprojection)


def safe_draw_view(scene: bpy.types.Scene, depsgraph, view_matrix: np.ndarray, projection: np.ndarray,
                   target_size: tuple[int, int], region_key: Any) -> bool:
    """`draw_view` that never raises: a failure is logged once, shown in the view and
    the panel, and retried at most once per throttle interval or after a change."""
    try:
        return draw_view(scene, depsgraph, view_matrix, projection, target_size, region_key)
    except Exception as exc:  # noqa: BLE001 - a draw handler must not raise into Blender
        report_draw_error(exc)
        _STATE.results[region_key] = _ViewResult(("failed",), _STATE.version, computed_at=time.perf_counter())
        return False


def _draw() -> None:
    """POST_PIXEL callback of every 3D view. It must never take the viewport down."""
    context = bpy.context
    scene = context.scene
    settings = getattr(scene, "omniwarp", None)
    region, rv3d = context.region, context.region_data
    if settings is None or not settings.preview_enabled or region is None or rv3d is None:
        return
    safe_draw_view(scene, context.evaluated_depsgraph_get(), np.array(rv3d.view_matrix),
                   np.array(rv3d.window_matrix), (region.width, region.height), region.as_pointer())
    if _STATE.last_error:
        import blf

        blf.size(0, 12)
        blf.color(0, 1.0, 0.45, 0.35, 1.0)
        blf.position(0, 12, region.height - 48, 0)
        blf.draw(0, f"OmniWarp preview: {_STATE.last_error}")


def report_draw_error(exc: BaseException) -> None:
    """Log a draw failure once and keep it for the UI: a setting that cannot be drawn
    (InputError, e.g. a NaN bias) as a warning naming it, anything else with its traceback."""
    if isinstance(exc, InputError):
        message = str(exc)
        _STATE.last_error = message
        if message not in _STATE.reported:
            _STATE.reported.add(message)
            log.warning("OmniWarp preview paused until the setting is fixed: %s", message)
        return
    message = f"{type(exc).__name__}: {exc}"
    _STATE.last_error = message
    if message not in _STATE.reported:
        _STATE.reported.add(message)
        log.error("OmniWarp preview failed and is paused until something changes: %s", message, exc_info=exc)


def last_error() -> str:
    """The last preview failure, for panels to show ("" when none)."""
    return _STATE.last_error


# What this module answers through events (installed by register, dropped by unregister).
_EVENTS = (
    ("request_update", request_update),
    ("set_preview_enabled", set_preview_enabled),
    ("last_error", last_error),
)
