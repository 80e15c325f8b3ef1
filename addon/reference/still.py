"""A finished render's Render Result, written to a file while Python's lock is held.

Why not `render.render(write_still=True)`: the operator releases Python's lock for the
whole render and its file write, so an interrupt's immediate exit (core.interrupt) could
remove the temporary folder while Blender was still writing into it, and Blender then
recreated the folder for its file (`compare` left an `omniwarp_ref_*` folder behind, about
one Ctrl-C in a few hundred). `Image.save_render` keeps the lock for the write (measured on
bpy 5.2.3: a 2048x2048 multilayer EXR, 0.26 s, no tick of another Python thread inside),
and writes the same file through the same image writer.
"""
from __future__ import annotations

from pathlib import Path

from ..core.errors import ReferenceCaptureError


def render_result_image():
    """The file's Render Result image (found by type: a user image may share its name)."""
    import bpy

    for image in bpy.data.images:
        if image.type == "RENDER_RESULT":
            return image
    raise ReferenceCaptureError("the render left no Render Result image")


def save_render_result(scene, path: Path, what: str) -> None:
    """Write the last render of `scene` to `path` with the scene's output settings."""
    render_result_image().save_render(str(path), scene=scene)
    if not Path(path).exists():
        raise ReferenceCaptureError(f"{what} of scene {scene.name!r} wrote no {Path(path).name}")
