"""The shadow pipeline of one frame, over any `ShadowBackend` (docs/design.md section 3).

  plan -> analysis (DV crop and warp, on the GPU's count maps) -> shadow maps (one atlas
  tile per drawn layer, drawn by the frame's `parameterizations.Parameterization`)
  -> shadow test per sample.

The scene stays on the GPU (`resident.ResidentScene`): a frame's host work is the
plan, the warp tables and the uniforms, whatever the scene's size. The frame does not
wait for the GPU: its visibility stays there until the result is read
(`frame.FrameResult`). `time_ms` holds wall ms per stage (stage_clock.py), in a
measuring frame (`Measure.sync_stages`) each with its GPU work; `FrameResult.gpu_ms` holds the
GPU's own ms per stage where the backend has timer queries. The stages:

- `prepare`: host work of the frame: planning from the samples' statistics (a few
  numbers, core.samples), the resident scene's residency check (and the upload of
  changed objects, when there are any), the depth range from the objects' boxes, and
  the draw's uniforms. For unfold it also builds the host stream (unfold.py).
- `analysis`: the GPU's reductions over the view samples: the planning statistics
  (three dispatches, read back once as STAT_COUNT integers), and for a warp the count-map
  scatters and the tables built from them.
- `shadow_maps`: the depth pass (ray tables, footprints or the unfold stream, and the
  edge-distance map); for `exact`, the list pass over the samples and the footprint
  pass that walks the lists (no depth is stored).
- `shadow_test`: uploading the view samples (when they changed) and the shadow test over them.
- `total`: all of it.

Everything is light-centred before it is turned into float32: the object's offset
from the light is formed in float64 on the host.
"""
from __future__ import annotations

import dataclasses
import logging
import math
import time
import weakref
from collections.abc import Callable
from collections import OrderedDict

import numpy as np

from ..core import projection
from ..core.alpha import hits_visibility
from ..core.errors import BackendError
from ..core.plan import Plan
from ..core.samples import Reduction, depth_axis
from ..core.scene import LightSpec
from ..core.warping import LayerMapping
from . import analysis
from .backend import AtlasLayout, ShadowBackend
from .count_stats import CountStatistics, count_statistics, projective_counts
from .frame import (
    MAX_IMPORTANCE,
    MAX_IMPORTANCE_TOTAL,
    MAX_RESOLUTION,
    MIN_RESOLUTION,
    BiasSettings,
    FrameReader,
    FrameResult,
    GBufferSamples,
    Measure,
    PLAIN,
    PreparedGeometry,
    ShadowSettings,
    ViewSamples,
    analysis_size_for,
    check_light_fits,
    resident_samples_key,
    settings_for,
)
from .footprint_runs import RunMemo, footprint_draws, region_uniforms
from .pacing import Steps, drive
from .passes import segments
from .passes.media import NO_MEDIA, MediaFrame, MediaMemo, media_points, read_haze
from .parameterizations import DrawInputs, parameterization, slot_rotations_and_crops
from .plan_memo import PlanMemo
from .resident import ResidentScene
from .shaders import GRID_SAMPLERS_KEY, PARAM_CODES, SLOTS
from .soft import (SizedMode, exact_soft_uniforms, hit_words, list_resolution, sample_far, share_points, sized_mode,
                   soft_uniforms)
from .stage_clock import StageClock
from .unfold import edge_aa_parameters

log = logging.getLogger(__name__)

# The frame's data types and helpers, importable from here as before.
__all__ = ["MAX_IMPORTANCE", "MAX_IMPORTANCE_TOTAL", "MAX_RESOLUTION", "MIN_RESOLUTION", "BiasSettings",
           "CountStatistics", "FrameResult", "Measure", "PreparedGeometry", "ShadowPipeline", "ShadowSettings", "ViewSamples",
           "count_statistics", "edge_aa_parameters", "projective_counts", "settings_for"]


# Read-only triangle arrays a pipeline keeps resident at once (ShadowPipeline._scene_of):
# a few lights, each with its own selection of blockers.
MAX_HELD_SOUPS = 8

class ShadowPipeline:
    """Runs frames on one backend."""

    def __init__(self, backend: ShadowBackend) -> None:
        self.backend = backend
        # Read-only triangle arrays seen lately (the viewport's per-light selections, which
        # stay the same object while the scene is unchanged) -> their resident scenes.
        self._soups: OrderedDict[int, tuple[weakref.ref, ResidentScene]] = OrderedDict()
        self._latest: weakref.ref | None = None  # the last frame rendered (visibility_into)
        self._plans = PlanMemo()  # a steady frame's plan is the last one
        self._runs = RunMemo()  # and its chunk runs, the last ones
        self._media = MediaMemo()  # and its media's units, while the light and media stay

    def _scene_of(self, triangles: np.ndarray) -> tuple[ResidentScene, bool]:
        """A resident scene for a triangle array, and whether it is for this frame only.

        A read-only array cannot change in place, so the same array object gets the same
        scene (nothing uploaded again); any other array is uploaded for one frame.
        """
        array = np.asarray(triangles)
        if array is not triangles or array.flags.writeable:
            return ResidentScene.of_triangles(array), True
        held = self._soups.get(id(array))
        if held is not None and held[0]() is array:
            self._soups.move_to_end(id(array))
            return held[1], False
        scene = ResidentScene.of_triangles(array)
        self._soups[id(array)] = (weakref.ref(array), scene)
        while len(self._soups) > MAX_HELD_SOUPS:
            _, (_, old) = self._soups.popitem(last=False)
            self.backend.release_scene(old)
        return scene, False

    def release(self) -> None:
        """Read the frames still unread, and free the resident scenes this pipeline made for
        read-only arrays."""
        if not self.backend.released:
            self.backend.settle()
        for _, scene in self._soups.values():
            self.backend.release_scene(scene)
        self._soups.clear()

    def count_maps(self, light: LightSpec, plan: Plan, mappings: dict[int, LayerMapping], size: int,
                   mode: int, weighted: bool = False) -> dict[int, np.ndarray]:
        """GPU count maps (row 0 = v = 0) of the uploaded samples, one per drawn layer of `plan`
        (analysis.count_maps)."""
        return analysis.count_maps(self.backend, light, plan, mappings, size, mode, weighted)

    def link_lists(self, light: LightSpec, plan: Plan, mappings: dict[int, LayerMapping], size: int,
                   words: int = 1, media: MediaFrame | None = None) -> None:
        """Link the uploaded samples into per-texel lists through the full mapping of each
        drawn layer, at `size` texels a side (the irregular z-buffer's lists; the backend
        keeps them, `read_links` reads them back), with `words` words of marks a sample
        (soft.hit_words), and the samples' optical depths of `media`'s light points each
        cleared (None: no media). The warp tables must be bound."""
        uniforms = analysis.scatter_uniforms(light, plan, mappings, size, 2, False)
        points, across = (media.points, media.across) if media is not None else (0, 1)
        self.backend.link_samples(size, max(len(plan.drawn), 1), uniforms, hit_words=words, media=points,
                                  media_across=across)

    def render(self, light: LightSpec, scene: ResidentScene | np.ndarray, samples: ViewSamples | GBufferSamples,
               settings: ShadowSettings, measure: Measure = PLAIN) -> FrameResult:
        """One frame: plan, analysis, maps, test.

        The frame does not wait for the GPU: its visibility (and, where the backend has
        timer queries, each stage's GPU ms) stays there until the result is first read,
        at the latest when the next frame starts. `measure` (frame.Measure) reads the maps
        back, waits at the end of each stage or counts the exact pass's work. `scene` is a `ResidentScene`, whose unchanged objects
        stay on the GPU between frames (keep it there until the result is read: the exact
        pass's later rounds draw it then), or a (T, 3, 3) world triangle array: a read-only
        one stays resident for as long as the same array comes back (the viewport's
        per-light selections), any other is uploaded for this frame only. `samples` are
        arrays, uploaded, or a Blender G-buffer's textures, used where they are.
        """
        return drive(self.render_steps(light, scene, samples, settings, measure))

    def render_steps(self, light: LightSpec, scene: ResidentScene | np.ndarray,
                     samples: ViewSamples | GBufferSamples, settings: ShadowSettings,
                     measure: Measure = PLAIN) -> Steps[FrameResult]:
        """`render` as a stepped pass (render/pacing.py): while the backend's pacer is
        stepping it yields between slices of its long draws (the viewport spreads a frame
        over redraws); nothing else may use the backend until it has returned."""
        self.backend.settle()  # this frame overwrites what an unread earlier one reads
        one_frame = False
        start = time.perf_counter()
        if not isinstance(scene, ResidentScene):
            scene, one_frame = self._scene_of(scene)
        # Making a scene of an array (sanitising, sorting into chunks) is host work of this
        # frame: it counts in `prepare`.
        scene_ms = (time.perf_counter() - start) * 1e3
        # The context is made current once for the frame: every pass inside finds it bound.
        with self.backend.device.bound():
            try:
                result = yield from self._render_steps(light, scene, samples, settings, measure, scene_ms)
                if one_frame:
                    result.complete()  # its later exact rounds draw this scene, freed below
            finally:
                if one_frame:
                    self.backend.release_scene(scene)
        self.backend.hold_unread(result)
        self._latest = weakref.ref(result)
        return result

    def visibility_into(self, result: FrameResult, target) -> None:
        """Draw `result`'s visibility and flags (row 0 at the bottom) into `target` (a
        device target of an RG32F texture of the samples' size) on the GPU, the exact pass's
        marks applied: a compositor samples it there. `result` must be this pipeline's
        latest frame, its targets not yet overwritten."""
        latest = self._latest() if self._latest is not None else None
        if latest is not result or not result.pending:
            raise BackendError("visibility_into needs the pipeline's latest frame, before it is read")
        result.complete()  # the exact pass's later rounds, where its lists need them
        self.backend.resolve_visibility(target, result.exact_marks)

    def _render_steps(self, light: LightSpec, scene: ResidentScene, samples: ViewSamples | GBufferSamples,
                      settings: ShadowSettings, measure: Measure, scene_ms: float = 0.0) -> Steps[FrameResult]:
        backend = self.backend
        # A sized light's exact pass lists its samples coarser (soft.list_resolution).
        settings = dataclasses.replace(settings, resolution=list_resolution(light, settings))
        clock = StageClock(backend.device, backend.finish if measure.sync_stages else None)
        clock.add("prepare", scene_ms)
        with clock.part("upload", "shadow_test"):
            self._upload_samples(light, samples)

        with clock.part("sync", "prepare", gpu=False):
            backend.sample_media.live = False  # until this frame's exact pass sums its media
            check_light_fits(light, settings.parameterization)
            backend.sync_scene(scene)  # uploads only objects whose geometry changed
            bounds = scene.bounds()  # per object, from its box and matrix
            near_far = (projection.depth_range(None, light.position, bounds=bounds) if bounds is not None
                        else (0.0, 1.0))
        yield from backend.pacer.pause()
        with clock.part("stats", "analysis"):
            raw_stats = self._reduce_samples(light, samples)  # a GPU reduction: a few numbers read back
        with clock.part("plan", "prepare", gpu=False):
            camera = samples.camera

            def make_plan() -> Plan:
                stats = Reduction.decode(raw_stats, camera, light, samples.shape).stats(camera, samples.shape)
                return parameterization(settings.parameterization).plan(light, settings, camera, stats,
                                                                        near_far, bounds)

            plan = self._plans.plan(raw_stats, (light, camera, settings, samples.shape, near_far, bounds),
                                    make_plan)
            # The plan may fall back to another parameterization (ipsm to dpsm, psm to sm).
            scheme = parameterization(plan.parameterization)

        mappings: dict[int, LayerMapping] = {}
        counts: dict[int, np.ndarray] = {}
        yield from backend.pacer.pause()
        with clock.part("analysis", "analysis"):
            if settings.warp != "none" and plan.drawn:
                mappings, counts = analysis.analyse(backend, light, settings, plan)
            else:
                backend.set_warp_tables(None, None)
                mappings = scheme.base_mappings(plan, light, settings)

        with clock.part("prepare", "prepare", gpu=False):
            geometry = scheme.prepare(light, scene, plan, settings, near_far)
            res = settings.resolution
            size = settings.analysis_size or analysis_size_for(res)
            tile_of_slot = {layer.slot: i for i, layer in enumerate(plan.drawn)}
            layout = AtlasLayout.for_tiles(res, len(plan.drawn), backend.max_texture_size())
            boxes = scheme.scissor(plan, light, settings, mappings)
            media = self._media.frame(scene, light)
            if media.on and not media_drawn(light, settings):
                log.debug("media not drawn by this frame (%s): left out", settings.parameterization)
                media = NO_MEDIA
            elif media.on and sized_mode(light, settings) is SizedMode.EXACT_SOFT:
                # A sized light's exact pass follows a share of its points through the media.
                points, across = media_points(settings.exact_samples, samples.shape, backend.max_texture_size())
                media = dataclasses.replace(media, points=points, across=across,
                                            indices=share_points(int(settings.exact_samples), points))
            backend.media = media
            inputs = DrawInputs(plan, settings, geometry, layout, tile_of_slot, mappings, size, boxes,
                                footprint_draws(scene, light, media), region_uniforms(plan, light, settings.cull),
                                scene, light, measure.count_work, self._runs)

        yield from backend.pacer.pause()
        with clock.part("shadow_maps", "shadow_maps"):
            # Texels outside a layer's box are neither cleared nor drawn (map-space culling).
            backend.begin_atlas(layout, {tile_of_slot[slot]: box for slot, box in boxes.items()})
            segments_walk = by_segments(light, settings, scene, media)
            if segments_walk:
                # The segments mark the lists' words; no sample is linked into a list.
                backend.hold_lists(res, max(len(plan.drawn), 1), hit_words(light, settings))
            elif settings.exact:
                # The irregular z-buffer's lists.
                self.link_lists(light, plan, mappings, res, hit_words(light, settings),
                                media=media if media.on else None)
            if segments_walk:
                yield from backend.mark_segments_steps(scene, light.position, exact_soft_uniforms(light, settings),
                                                       sample_far(plan, light))
                edge_radius = 0
            else:
                edge_radius = yield from scheme.draw_steps(backend, inputs)
            if settings.exact and (measure.sync_stages or measure.count_work):
                # A measuring frame draws the exact pass's later rounds in its own time; any
                # other leaves the check of their need (a read) to its first read.
                backend.finish_lists()

        yield from backend.pacer.pause()
        with clock.part("test", "shadow_test"):
            test = self._shadow_test(light, scene, settings, plan, geometry, layout, tile_of_slot, mappings, size,
                                     edge_radius, boxes)
        timings = clock.wall_ms()

        atlas = _mask_unread_texels(backend.read_atlas(), layout, tile_of_slot, boxes) if measure.keep_atlas else None
        haze = read_haze(backend) if measure.keep_atlas else None
        if haze is not None:
            haze = _mask_unread_texels(haze, layout, tile_of_slot, boxes)
        # The atlas of `exact` holds no depth (every texel empty), so the test lit every
        # tested sample; the exact pass's marks shadow the ones a triangle crosses, unless
        # the test weighed a sized light's marks itself.
        marks = settings.exact and sized_mode(light, settings) is not SizedMode.EXACT_SOFT
        return FrameResult(timings, plan, geometry, layout, texels=len(plan.drawn) * res * res, atlas=atlas, haze=haze,
                           tile_of_slot=tile_of_slot, mappings=mappings, count_maps=counts, boxes=boxes,
                           exact_counts=backend.exact_work() if settings.exact else None,
                           reader=_reader(backend, marks, media if backend.sample_media.unweighed else None,
                                          clock.gpu_reader()), exact_marks=marks,
                           completer=_completer(backend, None if marks else test) if settings.exact else None)

    def _reduce_samples(self, light: LightSpec, samples: ViewSamples | GBufferSamples) -> np.ndarray:
        """The planning statistics of the uploaded samples, reduced on the GPU and read once:
        the raw integers `core.samples.Reduction` decodes."""
        camera = samples.camera
        axis, offset = depth_axis(camera, light) if camera is not None else (np.zeros(3), 0.0)
        uniforms = {"ow_light_rot": light.rotation.T, "ow_view_axis": axis, "ow_view_offset": offset,
                    "ow_hemi": 1 if light.emission == "hemi" else 0,
                    "ow_ortho": int(camera is not None and camera.ortho)}
        return self.backend.reduce_samples(uniforms, histogram=camera is not None)

    def _upload_samples(self, light: LightSpec, samples: ViewSamples | GBufferSamples) -> None:
        """Put the frame's samples on the GPU, light-centred. A G-buffer is used where it is;
        arrays are uploaded, unless the backend already holds these very samples for this
        light (`resident_samples_key`): then nothing travels."""
        if isinstance(samples, GBufferSamples):
            self.backend.samples_from_gbuffer(samples.textures, light.position)
            return
        key = resident_samples_key(samples, light)
        if key is not None and key.matches(self.backend.samples.source):
            return
        height, width = samples.hit.shape
        # GL textures start at the bottom row and the samples at the top, so the arrays
        # are filled upside down, in place: a third of the time of building them with
        # np.where and flipping a copy (every frame, every method).
        hit = (samples.hit & projection.finite_points(samples.positions))[::-1]
        pos = np.empty((height, width, 4), dtype=np.float32)
        nrm = np.empty((height, width, 4), dtype=np.float32)
        with np.errstate(over="ignore", invalid="ignore"):  # misses are zeroed below
            np.subtract(samples.positions[::-1], light.position, out=pos[..., :3], casting="same_kind")
            nrm[..., :3] = samples.normals[::-1]
        weights = samples.importance_weights()
        pos[..., 3] = hit if weights is None else weights[::-1]
        pos[~hit] = 0.0
        nrm[~hit] = 0.0
        self.backend.upload_samples(pos, nrm)
        self.backend.samples.source = key

    def _shadow_test(self, light: LightSpec, scene: ResidentScene, settings: ShadowSettings, plan: Plan,
                     geometry: PreparedGeometry,
                     layout: AtlasLayout, tile_of_slot: dict[int, int], mappings: dict[int, LayerMapping],
                     warp_size: int, edge_radius: int = 0,
                     boxes: dict[int, tuple[int, int, int, int]] | None = None) -> dict:
        """Run the shadow test; returns its uniforms (a test that weighs the exact pass's
        marks runs again after later rounds)."""
        rotations, crops = slot_rotations_and_crops(plan, mappings)
        tiles = np.zeros((SLOTS, 4))
        res = float(settings.resolution)
        readable = np.tile([0.0, 0.0, res, res], (SLOTS, 1))
        for slot, box in (boxes or {}).items():
            readable[slot] = box
        for slot, tile in tile_of_slot.items():
            x, y = layout.origin(tile)
            tiles[slot] = (x, y, 1.0, 0.0)
        uniforms = {
            "ow_light_rot": light.rotation.T,
            "ow_layer_rot": rotations,
            "ow_layer_tile": tiles,
            "ow_layer_crop": crops,
            "ow_layer_box": readable,
            "ow_param": PARAM_CODES[plan.parameterization],
            "ow_layer_kind": plan.layer_kind,
            "ow_hemi": 1 if light.emission == "hemi" else 0,
            "ow_warp_size": warp_size if any(m.warp is not None for m in mappings.values()) else 0,
            "ow_resolution": float(settings.resolution),
            "ow_near": geometry.near,
            "ow_far": geometry.far,
            "ow_bias_const": settings.bias.constant,
            "ow_bias_slope": settings.bias.slope,
            "ow_bias_normal": settings.bias.normal,
            "ow_projective": 0,
            "ow_map_inverted": 0,
            "ow_map_matrix": np.eye(4),
            "ow_depth_offset": 0.0,
            "ow_sun": 1 if light.emission == "sun" else 0,
            "ow_light_axis": light.axis,
            "ow_spot_cos": math.cos(light.spot_size / 2.0) if light.emission == "spot" else -2.0,
            "ow_edge_radius": int(edge_radius),
        }
        uniforms.update(parameterization(plan.parameterization).test_uniforms(plan))
        uniforms.update(soft_uniforms(light, settings))
        if scene.grids:  # density grids, marched along each sample's segment (lib/grids.glsl)
            grid_uniforms, samplers = self.backend.grids.bind(self.backend.device, scene.grids.values(), light)
            uniforms.update(grid_uniforms, **{GRID_SAMPLERS_KEY: samplers})
        self.backend.run_shadow_test(uniforms)
        return uniforms


def by_segments(light: LightSpec, settings: ShadowSettings, scene: ResidentScene, media: MediaFrame) -> bool:
    """Whether a frame's exact pass walks segments through a tree (passes/segments.py)
    rather than its lists: a sized light's, over opaque triangles without media."""
    return (settings.exact and settings.exact_segments and sized_mode(light, settings) is SizedMode.EXACT_SOFT
            and not media.on and segments.fits(scene))


def _completer(backend: ShadowBackend, test: dict | None) -> Callable[[], None]:
    """What an exact frame leaves to its first read: the check of the exact pass's counters
    and its later rounds (passes.exact.finish_lists), then, where the shadow test weighed
    the marks itself (`test`, its uniforms), the test again over the finished marks."""

    def complete() -> None:
        if backend.released:
            raise BackendError("a frame's result was read after its backend was released")
        if backend.finish_lists() and test is not None:
            backend.run_shadow_test(test)

    return complete

def media_drawn(light: LightSpec, settings: ShadowSettings) -> bool:
    """Whether a frame draws its media: the exact pass and the maps (their haze,
    lib/media.glsl) do, for every light (a sized light's exact pass along a share of its
    points' segments, its maps along the ray to its centre), the light the media keep times
    the share that surfaces let through. Unfold does not: its media cast no shadow
    (docs/volumes.md)."""
    return settings.parameterization != "unfold"


def _reader(backend: ShadowBackend, marks: bool, media: MediaFrame | None, gpu_ms) -> FrameReader:
    """Reads a frame's visibility and flags (top row first) and its GPU ms; `marks`: shadow
    the samples the exact pass marked; `media`: weigh in the optical depths the exact pass
    summed (None: it summed none)."""

    def read() -> tuple[np.ndarray, np.ndarray, dict[str, float] | None]:
        if backend.released:
            raise BackendError("a frame's result was read after its backend was released")
        with backend.device.bound():  # one binding for every read and timer below
            result = backend.read_shadow_test()
            if marks:
                hits, _ = backend.read_hits()
                result[..., 0] *= hits_visibility(hits)  # opaque crossings and see-through ones
            if media is not None:  # the exact pass's optical depths (passes/media.py)
                words = backend.read_media()
                distance = (np.linalg.norm(backend.read_positions()[..., :3], axis=-1) if media.light.any()
                            else np.zeros(result.shape[:2]))
                result[..., 0] *= media.kept(words, distance)
            return result[..., 0][::-1].copy(), result[..., 1][::-1].astype(np.int8), gpu_ms()

    return read


def _mask_unread_texels(atlas: np.ndarray, layout: AtlasLayout, tile_of_slot: dict[int, int],
                        boxes: dict[int, tuple[int, int, int, int]]) -> np.ndarray:
    """The atlas with every texel outside its layer's readable box set to 1 (empty).

    Those texels were neither cleared nor drawn this frame, so they hold stale values;
    images and checks of the read-back see them as the empty texels they stand for.
    """
    for slot, box in boxes.items():
        x, y = layout.origin(tile_of_slot[slot])
        res = layout.resolution
        keep = np.zeros((res, res), dtype=bool)
        x0, y0, x1, y1 = (min(max(int(v), 0), res) for v in box)
        keep[y0:y1, x0:x1] = True  # rows are y (row 0 at the bottom, as GL stores it)
        tile = atlas[y:y + res, x:x + res]
        tile[~keep] = 1.0
    return atlas
