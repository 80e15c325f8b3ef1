"""`omniwarp compare`: every method against the Cycles reference, timed per stage.

Writes DIR/results.json (a list of rows, docs/design.md section 6), DIR/report.md,
DIR/error_vs_time.png and one mismatch image per row under DIR/images/.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import json
import logging
import math
import statistics
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .core import blockers, metrics
from .core import methods as method_registry
from .core.errors import InputError
from .core.methods import DEFAULT_METHODS
from .core.outputs import FinishedRows, StagedOutput
from .core.png import colormap, write_png
from .core.scene import POINT_EMISSIONS, PROJECTIVE_EMISSIONS, CameraSpec, LightSpec
from .reference.data import ReferenceData
from .render.backends.blender.draw import pool_image
from .render.frame import EXACT_SAMPLES, Measure
from .render.pipeline import (
    MAX_RESOLUTION,
    MIN_RESOLUTION,
    FrameResult,
    ShadowPipeline,
    ShadowSettings,
    ViewSamples,
    count_statistics,
    media_drawn,
    settings_for,
)
from .render import soft
from .render.resident import ResidentScene
from .core.rows import Row, make_row, row_key

log = logging.getLogger(__name__)

MAP_IMAGE_MAX = 512  # map images are pooled down to at most this many pixels a side
DEFAULT_RESOLUTIONS = (512, 1024, 2048)


@dataclass(frozen=True)
class CompareOptions:
    methods: tuple[str, ...] = DEFAULT_METHODS
    resolutions: tuple[int, ...] = DEFAULT_RESOLUTIONS
    cull: bool = True
    cull_both: bool = False  # measure every pipeline row with and without culling, in one run
    frames: int = 3  # timed frames per row, after one warm-up frame
    exact_samples: int = EXACT_SAMPLES  # a sized light's points per view sample in `exact` (--exact-samples)
    out_dir: Path = Path("out/compare")
    write_images: bool = True
    command: str = ""  # the command line, recorded in report.md for provenance


def parse_resolutions(text: str) -> tuple[int, ...]:
    """Comma list of shadow-map resolutions, each an integer in the supported range."""
    values = []
    for part in (s.strip() for s in text.split(",")):
        if not part:
            continue
        try:
            value = int(part)
        except ValueError:
            raise InputError(f"bad resolution {part!r}: expected an integer such as 1024") from None
        if not MIN_RESOLUTION <= value <= MAX_RESOLUTION:
            raise InputError(f"bad resolution {value}: must lie in [{MIN_RESOLUTION}, {MAX_RESOLUTION}]")
        values.append(value)
    if not values:
        raise InputError("no resolutions given")
    return tuple(values)


def light_from_reference(ref: ReferenceData) -> LightSpec:
    if ref.emission not in POINT_EMISSIONS + PROJECTIVE_EMISSIONS:
        raise InputError(f"the reference light is {ref.emission!r}; expected omni, hemi, spot or sun")
    return ref.light_spec()


def camera_from_reference(ref: ReferenceData) -> CameraSpec:
    """The reference's camera as the file had it (ReferenceData.camera)."""
    return ref.camera()


def samples_from_reference(ref: ReferenceData) -> ViewSamples:
    """The reference's view samples as read-only copies: the pipeline keeps read-only
    samples on the GPU between frames (frame.resident_samples_key), so a row's frames
    upload them once."""
    arrays = [ref.position.astype(np.float64), ref.normal.astype(np.float64), np.array(ref.hit, dtype=bool)]
    for array in arrays:
        array.flags.writeable = False
    return ViewSamples(*arrays, camera_from_reference(ref))


class Progress:
    """One status line on stderr with an estimate of the time left."""

    def __init__(self, total: int, stream=None) -> None:
        self.total = max(total, 1)
        self.done = 0
        self.start = time.perf_counter()
        self.stream = stream if stream is not None else sys.stderr  # resolved late: tests swap it

    def step(self, label: str) -> None:
        elapsed = time.perf_counter() - self.start
        if self.done:
            eta = elapsed / self.done * (self.total - self.done)
            eta_text = f"~{eta:.0f}s left"
        else:
            eta_text = "estimating"
        print(f"[{self.done + 1}/{self.total}] {label} ({elapsed:.0f}s elapsed, {eta_text})",
              file=self.stream, flush=True)

    def advance(self) -> None:
        self.done += 1


def _median_times(frames: Sequence[dict[str, float]]) -> dict[str, float]:
    keys = ("total", "prepare", "analysis", "shadow_maps", "shadow_test")
    return {k: float(statistics.median(f.get(k, 0.0) for f in frames)) for k in keys}


def _median_gpu_times(frames: Sequence[dict[str, float] | None]) -> dict[str, float] | None:
    """Median GPU ms per stage (and total) of the frames timed by GPU queries (a frame whose
    queries gave no true time has none: stage_clock); None when no frame was."""
    timed = [f for f in frames if f is not None]
    if not timed:
        return None
    return {k: float(statistics.median(f[k] for f in timed)) for k in timed[0]}


# The one method that does not follow see-through materials: its host-built stream has no UVs.
UNFOLD_ALPHA_NOTE = "unfold draws see-through materials opaque (its tessellated stream carries no UVs)"
UNFOLD_PIECES_NOTE = "unfold draws no hair or points (its tessellated stream holds triangles only)"
MEDIA_NOTE = ("this method draws no media: the scene's homogeneous volumes (fog, smoke) cast no shadow here "
              "(every other method draws them, render/passes/media.py), though it marches density grids as they do")
HARD_SIZED_NOTE = ("the light has a size, but this method's shadows are hard (render/soft.py softens "
                   "the sphere, area and sun shapes on their lights' maps)")


def scene_has_alpha(scene: ResidentScene) -> bool:
    """Whether any resident part has a see-through material."""
    return any(obj.alpha is not None for obj in scene.objects.values())


def scene_has_media(scene: ResidentScene) -> bool:
    """Whether any resident part bounds a homogeneous medium."""
    return any(obj.medium is not None for obj in scene.objects.values())


def resident_scene(ref: ReferenceData) -> ResidentScene:
    """The reference's triangles as one resident object, its hair and points as one object
    of pieces, and its density grids: build it once per reference and pass it to every
    row, so the GPU holds the scene across rows and frames."""
    scene = ResidentScene.of_triangles(ref.triangles.astype(np.float64), key=f"reference:{id(ref)}",
                                       surface=ref.surface)
    pieces = blockers.pieces(ref.spheres, ref.strands)
    if len(pieces):
        scene.set_pieces(f"reference:{id(ref)}:pieces", pieces)
    for index, grid in enumerate(ref.grids):  # Volume objects' density, marched by the shadow test
        scene.set_grid(f"reference:{id(ref)}:grid{index}", grid)
    return scene


def run_row(pipeline: ShadowPipeline, ref: ReferenceData, preset: str, method: str, resolution: int,
            options: CompareOptions, image_dir: Path | None, scene: ResidentScene | None = None,
            tag: str = "") -> Row:
    """Measure one (preset, method, resolution) row; `scene` is `resident_scene(ref)`, made here when not given.
    `tag` (a job's frame, light and camera) goes into the image names."""
    light = light_from_reference(ref)
    samples = samples_from_reference(ref)
    settings = settings_for(method, resolution, light.emission, cull=options.cull, exact_samples=options.exact_samples)
    scene = scene if scene is not None else resident_scene(ref)
    pipeline.render(light, scene, samples, settings)  # warm-up: shader compile, allocation, upload
    count = max(1, options.frames)
    # Measuring frames: each stage waits for its GPU work, so its wall time holds it. A
    # frame's visibility is read after it (at the latest when the next frame starts).
    frames = [pipeline.render(light, scene, samples, settings, Measure(keep_atlas=i == count - 1, sync_stages=True))
              for i in range(count)]
    last = frames[-1]
    counts = count_statistics(pipeline, light, settings, last, samples)  # measurement, not timed
    ref_lit = metrics.reference_visibility(ref.shadowed, ref.unshadowed)
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
    est_lit = last.visibility > 0.5
    judged = metrics.judge(last.visibility, ref.shadowed, ref.unshadowed, evaluable, sized=light.sized,
                           noise=ref.visibility_noise)
    times = _median_times([f.time_ms for f in frames])
    # Read before any later frame: a GPU-built warp's tables stay on the GPU until then.
    warp, nonfinite = _warp_summary(last), nonfinite_texels(last, counts)
    row = make_row(
        preset, method, light.emission, judged.figure, times, pipeline.backend.renderer(), pipeline.backend.name,
        len(frames), ref.resolution,
        **(_list_columns(pipeline, light, scene, samples, settings, counts) if settings.exact else {}),
        resolution=resolution,
        gpu_ms=_median_gpu_times([f.gpu_ms for f in frames]),
        # Mean |visibility - reference| in %: equal to error_pct for binary methods without
        # fractional pixels; the antialiased rows' and see-through shadows' fractions show here.
        **judged.columns(),
        passes=last.passes,
        triangles_drawn=last.geometry.triangles_drawn,
        scene_triangles=scene.triangles,  # resident, after dropping non-finite and zero-area ones
        scene_pieces=scene.pieces or None,  # hair and points, as pieces (resident.set_pieces)
        texels=last.texels,
        max_count_before=counts.max_count_before,
        max_count_after=counts.max_count_after,
        texel_utilization=counts.texel_utilization,
        tessellated_triangles=last.geometry.tessellated_triangles,
        skipped_triangles=last.geometry.skipped_triangles,
        nonfinite_texels=nonfinite,
        layers=[layer.name for layer in last.plan.drawn],
        warp=warp,
        cull=options.cull,
        light_shape=light.shape.describe() if light.sized else None,
        light_points=soft.light_points(light, settings),
        note=_row_note(light, settings, scene, ref),
    )
    if image_dir is not None:
        stem = f"{preset}{'_' + tag if tag else ''}_{method}_{resolution}{'' if options.cull else '_nocull'}"
        row["mismatch_image"] = metrics.write_mismatch_image(image_dir, stem, ref.shadowed, est_lit, ref_lit, evaluable)
        row["map_images"] = _write_map_images(image_dir, stem, last, counts)
    return row


def _row_note(light: LightSpec, settings: ShadowSettings, scene: ResidentScene,
              ref: ReferenceData | None = None) -> str | None:
    """What a row leaves out of the scene as the reference renders it, or None: the
    geometry no method draws that blocks the reference's light (its `left_out` notes,
    readers/left_out.py), and this method's own limits."""
    notes = list(ref.meta.get("left_out", ())) if ref is not None else []
    if settings.parameterization == "unfold" and scene_has_alpha(scene):
        notes.append(UNFOLD_ALPHA_NOTE)
    if settings.parameterization == "unfold" and scene.pieces:
        notes.append(UNFOLD_PIECES_NOTE)
    if light.sized and soft.sized_mode(light, settings) is soft.SizedMode.HARD:
        notes.append(HARD_SIZED_NOTE)
    if scene_has_media(scene) and not media_drawn(light, settings):
        notes.append(MEDIA_NOTE)
    return "; ".join(notes) or None


def _list_columns(pipeline: ShadowPipeline, light: LightSpec, scene: ResidentScene, samples: ViewSamples,
                  settings: ShadowSettings, counts) -> dict:
    """The exact method's list statistics: the lists are the mapped count maps at the map
    resolution (`counts.after`), and one more frame, untimed, counts the triangle pass's work."""
    lengths = np.concatenate([m.ravel() for m in counts.after.values()]) if counts.after else np.zeros(1)
    occupied = lengths[lengths > 0]
    work = pipeline.render(light, scene, samples, settings, Measure(count_work=True)).exact_work
    return {"list_longest": int(lengths.max()), "list_mean": float(occupied.mean()) if occupied.size else 0.0,
            "list_fragments": work["fragments"], "list_entries": work["entries"], "list_cut": work["cut"],
            "list_moved_entries": work["moved"], "list_rounds": work["rounds"]}


def nonfinite_texels(result: FrameResult, counts) -> int:
    """NaN or inf values in the frame's maps: the depth atlas, the count maps and the warps.

    Checked in code for every row; a healthy pipeline always reports 0.
    """
    bad = 0 if result.atlas is None else int(np.count_nonzero(~np.isfinite(result.atlas)))
    for maps in (counts.before, counts.after, result.count_maps):
        bad += sum(int(np.count_nonzero(~np.isfinite(m))) for m in maps.values())
    for mapping in result.mappings.values():
        if mapping.warp is not None:
            bad += int(np.count_nonzero(~np.isfinite(mapping.warp.rows)))
            bad += int(np.count_nonzero(~np.isfinite(mapping.warp.cols)))
    return bad


def _warp_summary(result: FrameResult) -> dict:
    """Per layer: the DV crop and the smoothing windows the automatic rule chose."""
    summary = {}
    for layer in result.plan.drawn:
        mapping = result.mappings.get(layer.slot)
        if mapping is None:
            continue
        entry = {"crop_lo": [round(float(v), 5) for v in mapping.lo],
                 "crop_hi": [round(float(v), 5) for v in mapping.hi]}
        if mapping.warp is not None and mapping.warp.params is not None:
            entry.update(kind=mapping.warp.kind, analysis_size=mapping.warp.size,
                         row_window=mapping.warp.params.row_window, col_window=mapping.warp.params.col_window)
        summary[layer.name] = entry
    return summary


def _pool(image: np.ndarray, reduce) -> np.ndarray:
    return pool_image(image, MAP_IMAGE_MAX, reduce)


def _write_map_images(image_dir: Path, stem: str, result: FrameResult, counts) -> list[str]:
    """Per layer: count map (log), importance map (counts after crop and warp), depth map,
    and where the layer drew media their transmittance map; row 0 of a map at the bottom
    of its image."""
    names = []
    res = result.layout.resolution if result.layout else 0
    top = max(counts.max_count_before, counts.max_count_after, 1.0)
    for layer in result.plan.drawn:
        tag = layer.name.replace("(", "_").replace(")", "").replace("+", "p").replace("-", "m")
        x, y = result.layout.origin(result.tile_of_slot[layer.slot])
        depth = result.atlas[y:y + res, x:x + res] if result.atlas is not None else None
        kept = result.haze[y:y + res, x:x + res] if result.haze is not None else None
        panels = {"count": counts.before[layer.slot], "importance": counts.after[layer.slot], "depth": depth,
                  "transmittance": kept}
        for kind, data in panels.items():
            if data is None:
                continue
            path = image_dir / f"{stem}_{tag}_{kind}.png"
            if kind == "depth":
                rgb = colormap(_pool(data, np.min), "viridis", 0.0, 1.0)
            elif kind == "transmittance":
                rgb = colormap(_pool(data, np.min), "gray", 0.0, 1.0)
            else:
                rgb = colormap(np.log1p(_pool(data, np.max)), "inferno", 0.0, float(np.log1p(top)))
            write_png(path, rgb[::-1])  # the map's row 0 at the bottom
            names.append(f"images/{path.name}")
    return names


def _cull_variants(options: CompareOptions) -> list[CompareOptions]:
    """The options each pipeline row is measured with: as given, or culled and unculled."""
    if not options.cull_both:
        return [options]
    return [replace(options, cull=True, cull_both=False), replace(options, cull=False, cull_both=False)]


def _eevee_rows(source: list[str], ref: ReferenceData, preset: str, image_dir: Path | None,
                options: CompareOptions, tag: str = "") -> list[Row]:
    import tempfile

    from .reference.eevee_rows import eevee_rows

    with tempfile.TemporaryDirectory(prefix="omniwarp_eevee_") as tmp:
        return eevee_rows(source, ref, preset, Path(tmp), image_dir, frames=max(1, options.frames),
                          image_stem=f"{preset}_{tag}" if tag else None)


def check_rows(rows: Sequence[Row]) -> None:
    """Every number finite; raise if not (a NaN must never reach results.json silently)."""
    for row in rows:
        values = [v for k, v in row.items() if isinstance(v, float)] + list(row["time_ms"].values())
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"non-finite value in row {'/'.join(str(part) for part in row_key(row))}")


def check_methods_fit(methods: Sequence[str], emissions: dict[str, str]) -> None:
    """InputError, before any render, when no requested method fits any of the lights
    (`emissions`: preset or file -> the emission of its light). A method that fits only
    some lights is not an error: the others skip it with a note."""
    if any(method_registry.method(m).fits(emission) for m in methods for emission in emissions.values()):
        return
    raise InputError(f"no requested method fits the light of {', '.join(sorted(emissions))}; "
                     f"{method_registry.fits_text('omni')}; {method_registry.fits_text('sun')}")


# Where a run's rows go as each finishes (run_compare's FinishedRows), in this process: a
# Dask worker's list is empty, and its rows reach the run when its job returns.
_FINISHED: list[Callable[[Row], None]] = []


@contextlib.contextmanager
def _collecting(sink: Callable[[Row], None]) -> Iterator[None]:
    _FINISHED.append(sink)
    try:
        yield
    finally:
        _FINISHED.remove(sink)


def row_finished(row: Row) -> Row:
    """Hand a finished row to the run's FinishedRows (none outside run_compare); return it."""
    for sink in _FINISHED:
        sink(row)
    return row


def run_compare(measure: Callable[[Path | None], list[Row]], options: CompareOptions) -> list[dict]:
    """Measure the rows with `measure(image_dir)` and write the outputs.

    `measure` runs every job (`shots.run_jobs`, or `cluster.run_jobs` on Dask) and returns
    the rows in job order, with the mismatch images written under `image_dir` (None with
    --no-images). Everything is written into a staging folder beside `options.out_dir` and
    moved into place at the end (`core/outputs.py`): a failed or interrupted run leaves the
    earlier results as they were, and a finished one leaves no image of an earlier run.
    Meanwhile each finished row is kept in `results.partial.json` (core/outputs.FinishedRows),
    which an interrupted or failed run leaves behind and a finished one removes.
    """
    finished = FinishedRows(options.out_dir)
    # A run of one frame draws no frame plot: an earlier run's must not stay beside it.
    with StagedOutput(options.out_dir, replaces=("images", "error_vs_time.png", "error_vs_frame.png")) as stage, \
            _collecting(finished.add):
        rows = measure(stage.path / "images" if options.write_images else None)
        check_rows(rows)
        stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        (stage.path / "results.json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
        from .report import write_frame_plot, write_markdown, write_plot

        write_markdown(rows, stage.path / "report.md", stamp, options.command)
        plotted = [name for name, write in (("error_vs_time.png", write_plot), ("error_vs_frame.png", write_frame_plot))
                   if write(rows, stage.path / name)]
        stage.commit()
    finished.discard()
    out = stage.target
    written = [out / "results.json", out / "report.md"] + [out / name for name in plotted]
    print(f"wrote {len(rows)} rows to {', '.join(str(p) for p in written)}", file=sys.stderr)
    return rows


def rows_per_reference(options: CompareOptions) -> int:
    """How many rows one reference gives at most (every method fitting): for the progress count."""
    variants = len(_cull_variants(options))
    return sum(1 if method_registry.method(m).external else len(options.resolutions) * variants
               for m in options.methods)


def measure_reference(pipeline: ShadowPipeline, ref: ReferenceData, preset: str, options: CompareOptions,
                      source: list[str] | None, image_dir: Path | None, progress: Progress,
                      tag: str = "") -> tuple[list[Row], list[str]]:
    """The rows of one reference (every requested method that fits its light, at every
    resolution) and the skipped `preset method` entries. `source` gives the child-process
    arguments (`--preset NAME --size WxH` or `--blend FILE ...`) that the external `eevee`
    rows rebuild the scene from; `tag` tells the images of one job from another's."""
    external = [m for m in options.methods if method_registry.method(m).external]
    if external and not source:
        raise InputError("the eevee rows need to know how to rebuild the scene (no source given)")
    rows: list[Row] = []
    skipped: list[str] = []
    variants = _cull_variants(options)
    scene = resident_scene(ref)  # uploaded by the first row, kept by the rest
    try:
        for method in options.methods:
            entry = method_registry.method(method)
            if not entry.fits(ref.emission):
                # e.g. `--preset all --methods dpsm,psm`: each light gets the methods it fits.
                skipped.append(f"{preset} {method}")
                print(f"skipped {preset} {method}: it does not fit {method_registry.light_phrase(ref.emission)} "
                      f"({method_registry.fits_text(ref.emission)})", file=sys.stderr)
                progress.done += 1 if entry.external else len(options.resolutions) * len(variants)
                continue
            if entry.external:
                progress.step(f"{preset} {method} (EEVEE renders in a child process)")
                rows += [row_finished(row) for row in _eevee_rows(source, ref, preset, image_dir, options, tag)]
                progress.advance()
                continue
            for resolution in options.resolutions:
                for variant in variants:
                    progress.step(f"{preset} {method} @ {resolution}{'' if variant.cull else ' (no cull)'}")
                    rows.append(row_finished(run_row(pipeline, ref, preset, method, resolution, variant, image_dir,
                                                     scene, tag)))
                    progress.advance()
    finally:
        pipeline.backend.release_scene(scene)
    # What the comparison cannot follow in this scene (shadow_rule.unfollowed), on every row.
    for row in rows:
        if ref.meta.get("notes"):
            row["scene_notes"] = list(ref.meta["notes"])
    return rows, skipped


def check_some_fit(rows: Sequence[Row], skipped: Sequence[str]) -> None:
    """InputError when a run measured nothing because no requested method fits any light."""
    if rows or not skipped:
        return
    presets = ", ".join(sorted({entry.split()[0] for entry in skipped}))
    raise InputError(f"no requested method fits the light of {presets}; {method_registry.fits_text('omni')}; "
                     f"{method_registry.fits_text('sun')}")
