"""A user's .blend, checked before any long work: the header, then Blender's own load.

A .blend starts with "BLENDER"; Blender 3 and later may write it compressed, with
zstd (Blender 4.x and 5.x) or gzip (older files). A truncated file can still have a
good header: Blender's load then raises RuntimeError ("Missing DNA block"), which
becomes one line naming the file. bpy is imported only by `open_blend`.

A file with a fluid simulation crashes the PyPI bpy when Python exits (Mantaflow frees its
solver by running Python code after the interpreter is gone: exit status 139 after the
work is done). `free_fluids_at_exit` empties bpy's data while Python still runs.
"""
from __future__ import annotations

import atexit
import gzip
import logging
import os
import zlib
from pathlib import Path

from ..core.errors import InputError

log = logging.getLogger(__name__)

BLEND_MAGIC = b"BLENDER"
ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
GZIP_MAGIC = b"\x1f\x8b"


def check_blend_file(path: str | os.PathLike, option: str = "--blend") -> Path:
    """The absolute path of a readable file that starts like a .blend; InputError otherwise."""
    file = Path(path)
    if not file.exists():
        raise InputError(f"{option} file not found: {path}")
    if not file.is_file():
        raise InputError(f"{option} {path}: not a file")
    if file.suffix.lower() != ".blend":
        raise InputError(f"{option} expects a .blend file, got {file.name}")
    try:
        with open(file, "rb") as fh:
            head = fh.read(16)
    except OSError as exc:
        raise InputError(f"{option} {path}: cannot read it ({exc.strerror or exc})") from None
    if head.startswith(BLEND_MAGIC) or head.startswith(ZSTD_MAGIC):
        return file.resolve()
    if head.startswith(GZIP_MAGIC):
        try:
            with gzip.open(file, "rb") as fh:
                inner = fh.read(len(BLEND_MAGIC))
        except (OSError, EOFError, zlib.error) as exc:
            raise InputError(f"{option} {path}: a damaged compressed file ({exc})") from None
        if inner == BLEND_MAGIC:
            return file.resolve()
    raise InputError(f"{option} {path} is not a .blend file (it does not start with Blender's header); "
                     "save the scene from Blender and pass that file")


def open_blend(path: str | os.PathLike, option: str = "--blend") -> None:
    """Load a .blend into bpy (replacing its data; nothing is saved back).

    Blender reports a damaged or truncated file as RuntimeError: one InputError line.
    """
    import bpy

    file = check_blend_file(path, option)
    try:
        bpy.ops.wm.open_mainfile(filepath=str(file), load_ui=False)
    except RuntimeError as exc:
        # 'Error: Loading "F" failed: Failed to read blend file 'F': Missing DNA block':
        # the last clause is the reason; the file is named once, by us.
        reason = " ".join(str(exc).replace("Error:", " ").split()).split(": ")[-1]
        raise InputError(f"{option} {path}: Blender cannot load it ({reason}); "
                         "the file is damaged or truncated, save it again from Blender") from None
    free_fluids_at_exit()


_fluid_exit: list[bool] = []  # registered once per process


def free_fluids_at_exit() -> None:
    """In background bpy, once the data holds a fluid modifier: empty the data at exit, before
    Python's own shutdown (the module docstring). Blender's UI quits its own way."""
    import bpy

    if _fluid_exit or not bpy.app.background:
        return
    if not any(m.type == "FLUID" for obj in bpy.data.objects for m in obj.modifiers):
        return

    def free() -> None:
        try:
            bpy.ops.wm.read_factory_settings(use_empty=True)
        except RuntimeError as exc:  # nothing else to do at exit
            log.debug("emptying the data at exit: %s", exc)

    _fluid_exit.append(True)
    atexit.register(free)


def open_scene(path: Path, camera: str | None = None, light: str | None = None, frame: int | None = None):
    """Load a .blend (never saved back) and return its active scene: with `camera` as its
    camera, `light` checked to exist, at `frame` when given (set and evaluated as Blender
    renders it). The one way compare, the sweeps' jobs and the EEVEE child open a file."""
    import bpy

    open_blend(path)
    scene = bpy.context.scene
    if camera:
        cam = bpy.data.objects.get(camera)
        if cam is None or cam.type != "CAMERA":
            raise InputError(f"--camera {camera!r}: no camera object of that name in {path.name}")
        scene.camera = cam
    if light and bpy.data.objects.get(light) is None:
        raise InputError(f"--light {light!r}: no object of that name in {path.name}")
    if frame is not None:
        scene.frame_set(frame)
    return scene
