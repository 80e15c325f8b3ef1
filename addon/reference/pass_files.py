"""A render's passes as files: the Render Result written to a multilayer EXR while Python's
lock is held, and its channels read back by name.

Why not `render.render(write_still=True)`: the operator releases Python's lock for the
whole render and its file write, so an interrupt's immediate exit (core.interrupt) could
remove the temporary folder while Blender was still writing into it, and Blender then
made the folder again for its file (a CI run's Ctrl-C left an `omniwarp_ref_*` folder
behind). `Image.save_render` keeps the lock for the write (measured on bpy 5.2.3: a
2048x2048 multilayer EXR, 0.26 s, no tick of another Python thread inside), and writes
the same file through the same image writer. The files are read with the project's own
numpy reader (core/exr.py): a stock Blender's Python has no OpenEXR.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..compat import blender as blender_compat
from ..core import exr
from ..core.errors import ReferenceCaptureError
from ..core.metrics import reference_ratio
from .reference_materials import AOV_NORMAL


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


def read_exr_channels(path: Path) -> dict[str, np.ndarray]:
    """Every channel of a (multi-part) EXR by its full name, as (H, W) float32 arrays; row 0
    is the top of the image (Blender writes the data window top-down)."""
    try:
        return exr.read_channels(path)
    except exr.ExrError as exc:
        raise ReferenceCaptureError(f"cannot read Cycles output {path}: {exc}") from exc


def pass_channel(channels: dict[str, np.ndarray], layer: str, name: str) -> np.ndarray:
    """One channel of a view layer's pass ("Combined.A"), or an error naming what there is."""
    key = f"{layer}.{name}"
    if key not in channels:
        raise ReferenceCaptureError(
            f"Cycles output lacks channel {key!r}; found: {', '.join(sorted(channels))}"
        )
    return channels[key]


def stack_pass(channels: dict[str, np.ndarray], layer: str, name: str, comps: str) -> np.ndarray:
    """A pass's components ("XYZ", "RGB") stacked on the last axis."""
    return np.stack([pass_channel(channels, layer, f"{name}.{c}") for c in comps], axis=-1)


@dataclass
class PassReading:
    """What the passes say, pixel by pixel (row 0 at the top)."""

    position: np.ndarray
    normal: np.ndarray
    hit: np.ndarray
    shadowed: np.ndarray
    unshadowed: np.ndarray
    noise: np.ndarray | None
    mixed: int  # pixels whose samples disagree on hitting geometry (samples > 1 only)
    lost: int  # hit pixels no render gave a position for (media)


def read_passes(lits: list[dict[str, np.ndarray]], frees: list[dict[str, np.ndarray]], name: str, media: bool,
                noisy: bool) -> PassReading:
    """Positions, normals, the hit mask and the shadowed and unshadowed diffuse light (the
    halves' mean) of a capture's renders (`lits` with the light's shadows, `frees` without,
    one a seed), and the halves' noise where there are two."""
    lit = lits[0]
    alpha = pass_channel(lit, name, "Combined.A")
    hit = alpha > 0.5
    mixed = int(np.count_nonzero((alpha > 1e-6) & (alpha < 1.0 - 1e-6)))
    # Cycles writes Position at sample 0 only; in a heterogeneous volume (seen by camera rays,
    # its closure empty for them) that sample's camera path may end before the surface: with
    # media, take another render's (seed), and leave a pixel none gives out of `hit` (meta
    # positions_lost). Without media a surface may well pass through the origin.
    found = [stack_pass(c, name, "Position", "XYZ")
             for c in ((*lits, *frees) if media else (lit,))]
    position = found[0]
    for other in found[1:]:
        position = np.where(np.all(position == 0.0, axis=-1, keepdims=True), other, position)
    lost = hit & np.all(position == 0.0, axis=-1) if media else np.zeros_like(hit)
    hit &= ~lost
    position = np.where(hit[..., None], position, 0.0)
    normal = stack_pass(lit, name, AOV_NORMAL, "RGB")
    length = np.linalg.norm(normal, axis=-1, keepdims=True)
    # Several samples average the AOV; re-normalize (only silhouettes can shrink it).
    normal = np.where(hit[..., None] & (length > 1e-12), normal / np.maximum(length, 1e-12), 0.0)
    diffuse = blender_compat.exr_pass_name("Diffuse Direct")
    shadowed_halves = [np.where(hit, stack_pass(c, name, diffuse, "RGB").mean(axis=-1), 0.0) for c in lits]
    unshadowed_halves = [np.where(hit, stack_pass(c, name, diffuse, "RGB").mean(axis=-1), 0.0) for c in frees]
    noise = None
    if noisy:
        # Half the halves' difference: for independent halves, its mean is the mean
        # distance of their average (the reference) from the converged visibility.
        a, b = (reference_ratio(sh, un) for sh, un in zip(shadowed_halves, unshadowed_halves))
        noise = (0.5 * np.abs(a - b)).astype(np.float32)
    return PassReading(position, normal, hit, np.mean(shadowed_halves, axis=0).astype(np.float32),
                 np.mean(unshadowed_halves, axis=0).astype(np.float32), noise, mixed, int(lost.sum()))
