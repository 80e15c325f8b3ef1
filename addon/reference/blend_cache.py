"""Cache of the Cycles references of a user's .blend, beside the presets' (cache.py).

The key is what changes the render: the bytes of the file and of the files outside it that
can change the geometry (linked libraries, unpacked images, Alembic/USD caches), the scene,
the requested light (or none: the scene's only one), the camera, the frame, the output size, the samples
(and a sized light's: `hard`, `soft_samples`), the Blender version and `capture.CAPTURE_VERSION`. Files are
`<stem>_<W>x<H>_<key>.npz` under the same folder as the presets' references, with the
same fields. bpy is imported only inside functions; the file must already be open.
"""
from __future__ import annotations

import hashlib
import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from .cache import blender_version, cache_dir_path, cache_key, cache_path, check_cache_dir, load_cached, store
from .capture import CAPTURE_VERSION, DEFAULT_SAMPLES, SOFT_SAMPLES, capture, output_size
from .data import ReferenceData

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

# The notes of what no method draws (left_out.py) and the points and strands came with
# version 2 of a file's reference: one cached before has neither, so it is captured again.
# Version 3: hair and points are drawn, so no longer among the notes. Version 4: the
# strands know whether the scene draws them as ribbons (Strands.flat). Version 5: the
# reference renders volume shaders (reference_materials), with their noise. Version 6:
# media stay seen by camera rays but act on shadow rays alone (a receiver inside one is
# shadowed by it), and the triangles carry their homogeneous media (Surface.medium).
# Version 7: Volume geometry's density grids are read (ReferenceData.grids), Volume
# objects are seen by camera rays with their volume for shadow rays alone. Version 8: a
# smoke domain is Volume geometry (smoke_domains.py), not a mesh medium. Version 9: hair
# radii follow the object's or emitter's scale as Cycles' do (hair.strand_radius_scale).
NOTES_VERSION = 9

log = logging.getLogger(__name__)

Progress = Callable[[str], None]
_CHUNK = 1 << 20
_FILE_SOURCES = frozenset({"FILE", "SEQUENCE", "MOVIE", "TILED"})


def file_digest(path: Path) -> str:
    """sha256 of a file's bytes ("missing" for a library that is not there)."""
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(_CHUNK), b""):
                digest.update(block)
    except OSError:
        return "missing"
    return digest.hexdigest()


def _external_files() -> list[str]:
    """Files outside the .blend that can change the render's geometry: linked libraries,
    images that are not packed (a displacement or a modifier's texture) and Alembic/USD caches."""
    import bpy

    names = [lib.filepath for lib in bpy.data.libraries]
    names += [image.filepath for image in bpy.data.images
              if image.source in _FILE_SOURCES and image.packed_file is None and image.filepath]
    names += [cache.filepath for cache in bpy.data.cache_files]
    return names


def blend_key_fields(path: Path, scene: "bpy.types.Scene", light: str | None, samples: int,
                     hard: bool = False, soft_samples: int = SOFT_SAMPLES) -> dict[str, Any]:
    """What a cached reference of the open file depends on."""
    import bpy

    return {
        "blend_sha256": file_digest(path),
        "external_files": sorted(file_digest(Path(bpy.path.abspath(name))) for name in _external_files()),
        "scene": scene.name,
        "light": light or "",
        "camera": scene.camera.name if scene.camera is not None else "",
        "frame": int(scene.frame_current),
        "resolution": list(output_size(scene)),
        "samples": int(samples),
        # A sized light's reference (capture.py): its samples, or its size taken away.
        "hard": bool(hard),
        "soft_samples": int(soft_samples),
        "blender": blender_version(),
        "capture_version": CAPTURE_VERSION,
        "notes_version": NOTES_VERSION,
    }


def load_or_capture_blend(path: Path, scene: "bpy.types.Scene", light: str | None = None, *,
                          samples: int = DEFAULT_SAMPLES, refresh: bool = False, cache_dir: Path | None = None,
                          progress: Progress | None = None,
                          check: Callable[[str], None] | None = None, hard: bool = False,
                          soft_samples: int = SOFT_SAMPLES) -> ReferenceData:
    """The reference of the open .blend `path` (its `scene`): cached, or rendered and cached.

    `check(emission)` runs before a render, and on a cached reference too, so a misfit is
    refused the same way either way."""
    say = progress or (lambda message: None)
    folder = cache_dir_path(cache_dir)
    fields = blend_key_fields(path, scene, light, samples, hard, soft_samples)
    key = cache_key(fields)
    target = cache_path(path.stem, output_size(scene), key, folder)
    cached = load_cached(target) if not refresh and target.exists() else None
    if cached is not None:
        if check is not None:
            check(cached.emission)
        say(f"using the cached Cycles reference of {path.name}: {target}")
        return cached

    def checked(emission: str) -> None:
        if check is not None:
            check(emission)
        # Said only once the file, its light and camera passed: bad input stays one line.
        say(f"rendering Cycles reference of {path.name}")

    check_cache_dir(folder)  # before the render, not after it
    start = time.perf_counter()
    ref = capture(scene, samples=samples, light=light, progress=progress, check=checked, hard=hard,
                  soft_samples=soft_samples)
    ref.meta.update(blend=str(path), cache_key=key, key_fields=fields)
    store(ref, target)
    say(f"reference of {path.name} cached in {time.perf_counter() - start:.1f} s: {target}")
    return ref
