"""The jobs of `omniwarp compare`: one per (scene, frame, light, camera), docs/sweeps.md.

A job is small and picklable: it names its scene (a preset, or a .blend with the frame,
light and camera), never holds data. `run_job` is the one job function: it loads the
job's Cycles reference (from the cache, else rendered and cached) and measures its
method rows. `run_jobs` runs the jobs in this process, one after another; `cluster.py`
runs the same `run_job` on Dask workers. Neither this module nor the serial path imports
Dask. bpy is imported only inside functions.
"""
from __future__ import annotations

import logging
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .compare import CompareOptions, Progress, check_some_fit, measure_reference, rows_per_reference
from .core.errors import InputError, OmniWarpError
from .reference.capture import DEFAULT_SAMPLES, SOFT_SAMPLES
from .reference.data import ReferenceData
from .render.pipeline import ShadowPipeline
from .core.rows import Row, with_shot

log = logging.getLogger(__name__)

MAX_JOBS = 100_000  # a typo like 1-1000000 is refused before any work
_RANGE = re.compile(r"^\s*(-?\d+)\s*-\s*(-?\d+)\s*(?::\s*(\d+)\s*)?$")
_CAMERA_TYPES = ("PERSP", "ORTHO")  # what the reference renders (capture.capture)
Say = Callable[[str], None]


@dataclass(frozen=True)
class Job:
    """One (scene, frame, light, camera): a preset (`preset`, `size`) or a .blend (`blend`).

    `frame`, `light` and `camera` are None for the file's own (its current frame, its only
    light, its scene camera). `tag` tells one job's images from another's ("" for a run of
    one job per scene, whose image names stay as they were)."""

    label: str  # the rows' `preset`: a preset's name or the .blend's stem
    preset: str | None = None
    size: tuple[int, int] | None = None
    blend: str | None = None
    frame: int | None = None
    light: str | None = None
    camera: str | None = None
    tag: str = ""
    hard: bool = False  # the light without its size (capture.capture, --hard)
    soft_samples: int = SOFT_SAMPLES  # a sized light's reference samples (--soft-samples)

    def source(self) -> list[str]:
        """The arguments a child process rebuilds this scene from (the eevee rows)."""
        if self.preset is not None:
            return ["--preset", self.preset, "--size", f"{self.size[0]}x{self.size[1]}"]
        return (["--blend", str(self.blend)] + (["--light", self.light] if self.light else [])
                + (["--camera", self.camera] if self.camera else [])
                + (["--frame", str(self.frame)] if self.frame is not None else []))

    def describe(self) -> str:
        """The job in a progress or error line: `room_omni`, `shot frame 9 light key`."""
        parts = [self.label] + ([f"frame {self.frame}"] if self.frame is not None else [])
        parts += [f"light {self.light}"] if self.light else []
        parts += [f"camera {self.camera}"] if self.camera else []
        return " ".join(parts)


@dataclass
class JobResult:
    """What a job gives back: its rows, the skipped `preset method` entries, and the cache
    file of a reference it rendered (None when it was cached already)."""

    rows: list[Row]
    skipped: list[str] = field(default_factory=list)
    rendered: Path | None = None


def parse_frame_range(text: str | None) -> list[int] | None:
    """`A-B[:STEP]` -> the frames A, A+STEP, ... up to B (None when not given)."""
    if text is None:
        return None
    match = _RANGE.match(text)
    if match is None:
        raise InputError(f"bad --frame-range {text!r}: use A-B or A-B:STEP, e.g. 1-250:10")
    first, last, step = int(match[1]), int(match[2]), int(match[3] or 1)
    if step < 1 or last < first:
        raise InputError(f"bad --frame-range {text!r}: the last frame must not come before the first, "
                         f"and STEP must be 1 or more")
    return list(range(first, last + 1, step))


def parse_names(text: str | None, option: str) -> list[str] | None:
    """`all` -> ["all"], `a,b` -> ["a", "b"], None -> None (the single-name option decides)."""
    if text is None:
        return None
    names = [part.strip() for part in text.split(",") if part.strip()]
    if not names:
        raise InputError(f"{option} is empty: give 'all' or a comma list of names")
    if "all" in names and len(names) > 1:
        raise InputError(f"{option} {text!r}: 'all' stands alone")
    return names


def preset_jobs(names: Sequence[str], size: tuple[int, int]) -> list[Job]:
    """One job per preset (a preset has one light, one camera and no animation)."""
    return [Job(label=name, preset=name, size=(int(size[0]), int(size[1]))) for name in names]


def blend_jobs(path: Path, frames: list[int] | None, lights: list[str] | None, cameras: list[str] | None,
               check: Callable[[dict[str, str]], None]) -> list[Job]:
    """The jobs of a .blend, its names checked in the open file before any render.

    `lights` and `cameras` are lists of names, ["all"] or None (the file's own: one name
    from --light/--camera, or None). `check(emissions)` gets `{"stem/light": emission}`
    and refuses the run when no requested method fits any of the lights."""
    import bpy

    from .reference.blend_file import open_blend
    from .reference.capture import (LIGHT_TYPES, emission_of, render_visible_objects, evaluated_depsgraph,
                                    pick_view_layer)

    open_blend(path)  # replaces bpy's in-memory data only; nothing is ever saved back
    scene = bpy.context.scene
    layer = pick_view_layer(scene)
    evaluated_depsgraph(scene, layer)  # syncs the view layer before its collections are read
    visible = render_visible_objects(layer)
    usable = {o.name: o for o in scene.objects if o.type == "LIGHT" and o.data.type in LIGHT_TYPES
              and o.name_full in visible}
    if lights == ["all"]:
        if not usable:
            raise InputError(f"--lights all: {path.name} has no rendered point, spot, sun or area light")
        lights = sorted(usable)
    for name in lights or []:
        if name not in usable:
            raise InputError(f"--lights {name!r}: no rendered point, spot, sun or area light of that name in {path.name}"
                             + (f" (it has {', '.join(sorted(usable))})" if usable else ""))
    cams = {o.name: o for o in scene.objects if o.type == "CAMERA"}
    if cameras == ["all"]:
        cameras = sorted(name for name, o in cams.items() if o.data.type in _CAMERA_TYPES)
        if not cameras:
            raise InputError(f"--cameras all: {path.name} has no perspective or orthographic camera")
    for name in cameras or []:
        if name not in cams or cams[name].data.type not in _CAMERA_TYPES:
            raise InputError(f"--cameras {name!r}: no perspective or orthographic camera of that name in {path.name}")
    if lights is None and len(usable) > 1:
        raise InputError(f"{path.name} has several point, spot, sun or area lights ({', '.join(sorted(usable))}); "
                         "name one with --light, or several with --lights")
    # The file's only light (None: capture names what is missing) or the named ones.
    checked = lights if lights is not None else sorted(usable)
    if checked:
        check({f"{path.stem}/{name}": emission_of(usable[name].data) for name in checked})
    # The image names carry what varies: the frame of a range, the light and camera of several.
    plural = (frames is not None, len(lights or []) > 1, len(cameras or []) > 1)
    jobs = []
    for frame in frames if frames is not None else [None]:
        for camera in cameras if cameras is not None else [None]:
            for light in lights if lights is not None else [None]:
                jobs.append(Job(label=path.stem, blend=str(path), frame=frame, light=light, camera=camera,
                                tag=_tag(frame, light, camera, plural)))
    if len(jobs) > MAX_JOBS:
        raise InputError(f"{len(jobs)} jobs (frames x lights x cameras) is more than {MAX_JOBS}; "
                         "use a STEP in --frame-range")
    return jobs


def _tag(frame: int | None, light: str | None, camera: str | None, plural: tuple[bool, bool, bool]) -> str:
    """The job's part of its image names: what the plural options chose."""
    parts = [f"f{frame:04d}" if plural[0] else "", light if plural[1] else "", camera if plural[2] else ""]
    return "_".join(re.sub(r"[^A-Za-z0-9.-]+", "-", p) for p in parts if p)


def load_reference(job: Job, cache_dir: str | None, say: Say,
                   check: Callable[[str], None] | None = None) -> tuple[ReferenceData, bool]:
    """The job's Cycles reference, and whether it was rendered now (False: from the cache).

    A .blend is opened afresh for every job (its frame is set and evaluated as Blender
    renders it: `frame_set`, the depsgraph at that frame), so no job sees another's state."""
    rendered: list[str] = []

    def noting(message: str) -> None:
        if message.startswith("rendering Cycles reference"):
            rendered.append(message)
        say(message)

    if job.preset is not None:
        from .reference.cache import load_or_capture

        ref = load_or_capture(job.preset, job.size, cache_dir=cache_dir, log_progress=noting, hard=job.hard,
                              soft_samples=job.soft_samples)
        return ref, bool(rendered)
    from .reference.blend_cache import load_or_capture_blend
    from .reference.blend_file import check_blend_file, open_scene

    path = check_blend_file(job.blend)  # on a worker: the file must be readable at the same path
    scene = open_scene(path, job.camera, job.light, job.frame)
    ref = load_or_capture_blend(path, scene, job.light, samples=DEFAULT_SAMPLES, cache_dir=cache_dir,
                                progress=noting, check=check, hard=job.hard, soft_samples=job.soft_samples)
    return ref, bool(rendered)


def run_job(job: Job, options: CompareOptions, pipeline: ShadowPipeline, image_dir: Path | None,
            progress: Progress, cache_dir: str | None = None, say: Say | None = None,
            check: Callable[[str], None] | None = None) -> JobResult:
    """The one job function: the reference of (scene, frame, light, camera), then its rows.

    The serial path and the Dask workers (`cluster.py`) both call it. A .blend job's rows
    carry `frame`, `light` and `camera` (the values rendered, also where the file chose them)."""
    say = say or _say
    try:
        ref, rendered = load_reference(job, cache_dir, say, check)
    except OmniWarpError as exc:
        if not job.tag:
            raise
        # One of many jobs: the line names the frame, light and camera at fault.
        raise type(exc)(f"{job.describe()}: {exc}") from None
    rows, skipped = measure_reference(pipeline, ref, job.label, options, job.source(), image_dir, progress, job.tag)
    if job.blend is not None:
        frame = job.frame if job.frame is not None else ref.meta.get("key_fields", {}).get("frame")
        for row in rows:
            with_shot(row, frame=frame, light=ref.meta.get("light"), camera=ref.meta.get("camera"))
    return JobResult(rows, skipped, _cache_file(job, ref, cache_dir) if rendered else None)


def _cache_file(job: Job, ref: ReferenceData, cache_dir: str | None) -> Path | None:
    """Where the job's reference was cached (blend_cache and cache name files alike)."""
    from .reference.cache import cache_dir_path, cache_path

    key = ref.meta.get("cache_key")
    return None if key is None else cache_path(job.label, tuple(ref.resolution), key, cache_dir_path(cache_dir))


def run_jobs(jobs: Sequence[Job], options: CompareOptions, pipeline_factory: Callable[[], ShadowPipeline],
             image_dir: Path | None, cache_dir: str | None = None,
             check: Callable[[str], None] | None = None) -> list[Row]:
    """Every job in this process, one after another (no Dask): the rows in job order."""
    progress = Progress(len(jobs) * rows_per_reference(options))
    rows: list[Row] = []
    skipped: list[str] = []
    pipeline = pipeline_factory()
    try:
        for job in jobs:
            result = run_job(job, options, pipeline, image_dir, progress, cache_dir, check=check)
            rows += result.rows
            skipped += result.skipped
    finally:
        pipeline.backend.release()
    check_some_fit(rows, skipped)
    return rows


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)
