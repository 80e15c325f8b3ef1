"""Cache of Cycles references per preset, resolution and sample count.

A cached reference loads without `bpy`; Blender is imported only to render a new one.
The cache key hashes the preset's builder source (with scene.py and camera.py), the Blender
version, the resolution, the sample count and `capture.CAPTURE_VERSION`.

Where: `cache_dir` if given, else the folder named by $OMNIWARP_CACHE, else
`<repo>/.cache/reference/`. Files are `<preset>_<W>x<H>_<key>.npz`.

The sample count stays in the key (later samples move off the pixel centre on 5.2, so
they change the reference); every command defaults to `capture.DEFAULT_SAMPLES`, so
`omniwarp reference` fills the file `compare` and `preview` read. Files are written
under a temporary name and renamed (`ReferenceData.save`); a file that cannot be read
is named in one warning and rendered again, which replaces it.
"""
from __future__ import annotations

import hashlib
import importlib.metadata
import importlib.util
import json
import logging
import os
import re
import sys
import time
from pathlib import Path
from typing import Any, Callable

from ..core.errors import ReferenceCaptureError
from ..core.presets import DEFAULT_RESOLUTION, build_preset, preset_source_hash
# capture.py imports bpy only inside functions, so this import is bpy-free.
from .capture import CAPTURE_VERSION, DEFAULT_SAMPLES, SOFT_SAMPLES
from .data import ReferenceData, read_meta

log = logging.getLogger(__name__)

CACHE_ENV = "OMNIWARP_CACHE"
DEFAULT_CACHE_DIR = Path(__file__).resolve().parents[2] / ".cache" / "reference"

Progress = Callable[[str], None]


def cache_dir_path(cache_dir: str | os.PathLike | None = None) -> Path:
    """The folder holding cached references."""
    if cache_dir is not None:
        return Path(cache_dir)
    env = os.environ.get(CACHE_ENV)
    return Path(env) if env else DEFAULT_CACHE_DIR


def blender_version() -> str | None:
    """'X.Y.Z' of the bpy that would render, or None if bpy is not installed.

    Avoids importing bpy when it can: a loaded module, else the PyPI package metadata.
    """
    bpy = sys.modules.get("bpy")
    if bpy is not None:
        return "%d.%d.%d" % tuple(bpy.app.version[:3])
    try:
        match = re.match(r"^(\d+)\.(\d+)\.(\d+)", importlib.metadata.version("bpy"))
        if match:
            return ".".join(match.groups())
    except importlib.metadata.PackageNotFoundError:
        log.debug("no bpy package metadata")
    if importlib.util.find_spec("bpy") is None:
        return None
    import bpy  # a bpy without metadata (e.g. a custom build): ask it directly

    return "%d.%d.%d" % tuple(bpy.app.version[:3])


def key_fields(preset: str, resolution: tuple[int, int], samples: int, version: str | None,
               hard: bool = False, soft_samples: int = SOFT_SAMPLES) -> dict[str, Any]:
    """What a cached reference depends on. A sized light's settings join the key only
    when they differ from the defaults, so the hard presets' keys stay as they were."""
    fields: dict[str, Any] = {
        "preset_hash": preset_source_hash(preset),
        "blender": version,
        "resolution": [int(resolution[0]), int(resolution[1])],
        "samples": int(samples),
        "capture_version": CAPTURE_VERSION,
    }
    if hard:
        fields["hard"] = True
    if soft_samples != SOFT_SAMPLES:
        fields["soft_samples"] = int(soft_samples)
    return fields


def cache_key(fields: dict[str, Any]) -> str:
    """Short stable hash of the key fields."""
    return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:16]


def cache_path(preset: str, resolution: tuple[int, int], key: str, cache_dir: Path) -> Path:
    width, height = resolution
    return cache_dir / f"{preset}_{int(width)}x{int(height)}_{key}.npz"


def _find_without_blender(preset: str, resolution: tuple[int, int], fields: dict[str, Any],
                          folder: Path) -> Path | None:
    """Newest cached file matching everything but the Blender version (bpy is absent)."""
    width, height = resolution
    wanted = {k: v for k, v in fields.items() if k != "blender"}
    candidates = sorted(folder.glob(f"{preset}_{int(width)}x{int(height)}_*.npz"),
                        key=lambda p: p.stat().st_mtime, reverse=True)
    for path in candidates:
        try:
            stored = read_meta(path).get("key_fields", {})
        except ReferenceCaptureError as exc:
            log.warning("skipping unreadable cache file: %s", exc)
            continue
        if {k: v for k, v in stored.items() if k != "blender"} == wanted:
            log.info("bpy is not installed: using %s (rendered with Blender %s)", path.name, stored.get("blender"))
            return path
    return None


def _capture_preset(preset: str, resolution: tuple[int, int], samples: int,
                    progress: Progress | None, hard: bool, soft_samples: int) -> ReferenceData:
    """Build the preset in a new Blender scene, capture it and delete everything created."""
    try:
        import bpy  # noqa: F401  (only to fail early with a clear message)
    except ImportError as exc:
        raise ReferenceCaptureError(
            f"the Cycles reference of preset {preset!r} at {resolution[0]}x{resolution[1]} is not cached, "
            "and rendering it needs the bpy module (pip install bpy, or run inside Blender)"
        ) from exc
    from .blender_scene import build_blender_scene, remove_blender_scene
    from .capture import capture

    spec = build_preset(preset, tuple(resolution))
    scene = build_blender_scene(spec)
    try:
        return capture(scene, samples=samples, progress=progress, hard=hard, soft_samples=soft_samples)
    finally:
        remove_blender_scene(scene)


def load_or_capture(preset: str, resolution: tuple[int, int] = DEFAULT_RESOLUTION, refresh: bool = False,
                    samples: int = DEFAULT_SAMPLES, cache_dir: str | os.PathLike | None = None,
                    log_progress: Progress | None = None, hard: bool = False,
                    soft_samples: int = SOFT_SAMPLES) -> ReferenceData:
    """The reference of `preset`: from the cache, or rendered with Cycles and cached.

    `refresh` renders anew even when a cached file exists. `log_progress` receives
    one-line progress messages during a render. `hard` and `soft_samples` are for a
    sized light (capture.capture).
    """
    resolution = (int(resolution[0]), int(resolution[1]))
    folder = cache_dir_path(cache_dir)
    version = blender_version()
    fields = key_fields(preset, resolution, samples, version, hard, soft_samples)

    if not refresh:
        path: Path | None
        if version is None:
            path = _find_without_blender(preset, resolution, fields, folder)
        else:
            path = cache_path(preset, resolution, cache_key(fields), folder)
            path = path if path.exists() else None
        if path is not None:
            if version is None:
                return ReferenceData.load(path)  # nothing could render it again
            ref = load_cached(path)
            if ref is not None:
                return ref

    if version is None:
        raise ReferenceCaptureError(
            f"the Cycles reference of preset {preset!r} at {resolution[0]}x{resolution[1]} "
            f"({samples} samples) is not cached in {folder}, and rendering it needs the bpy module "
            "(pip install bpy, or run inside Blender)"
        )
    key = cache_key(fields)
    path = cache_path(preset, resolution, key, folder)
    check_cache_dir(folder)  # before the render, not after it
    say = log_progress or (lambda message: None)
    say(f"rendering Cycles reference of {preset} at {resolution[0]}x{resolution[1]}")
    start = time.perf_counter()
    ref = _capture_preset(preset, resolution, samples, log_progress, hard, soft_samples)
    ref.meta.update(preset=preset, cache_key=key, key_fields=fields)
    store(ref, path)
    say(f"reference of {preset} cached in {time.perf_counter() - start:.1f} s: {path}")
    return ref


def load_cached(path: Path) -> ReferenceData | None:
    """A cached reference, or None when the file is damaged (a run killed mid-write before
    writes were atomic, a full disk, a copy cut short): it heals, one line, then rendered
    and replaced by the caller."""
    try:
        ref = ReferenceData.load(path)
    except ReferenceCaptureError as exc:
        log.warning("%s; rendering it again", exc)
        return None
    log.debug("reference cache hit: %s", path)
    return ref


def store(ref: ReferenceData, path: Path) -> None:
    """Write a reference into the cache (a temporary name, renamed into place: ReferenceData.save)."""
    try:
        ref.save(path)
    except OSError as exc:
        raise ReferenceCaptureError(f"cannot write the reference cache file {path}: {exc.strerror or exc}; "
                                    f"set {CACHE_ENV} to a writable folder") from exc


def check_cache_dir(folder: Path) -> None:
    """The cache folder exists (created if need be) and is writable; a one-line
    ReferenceCaptureError naming $OMNIWARP_CACHE otherwise."""
    if folder.exists() and not folder.is_dir():
        raise ReferenceCaptureError(f"the reference cache folder {folder} is a file; set {CACHE_ENV} to a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ReferenceCaptureError(f"cannot create the reference cache folder {folder}: "
                                    f"{exc.strerror or exc}; set {CACHE_ENV} to a writable folder") from exc
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ReferenceCaptureError(f"the reference cache folder {folder} is not writable; "
                                    f"set {CACHE_ENV} to a writable folder")
