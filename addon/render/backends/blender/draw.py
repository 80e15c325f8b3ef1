"""Drawing with Blender's `gpu` module around the pipeline: the G-buffer of a view,
the shadow composite over it, and the map overlay.

Every function takes explicit matrices, sizes and the target it draws into (the
currently bound framebuffer), so the viewport handler, the headless `preview`
command and the tests share them. `gpu`, `blf` and `gpu_extras` are imported
lazily so that this module imports without Blender.
"""
from __future__ import annotations

import contextlib
import functools
import logging
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ....core.scene import CameraSpec, LightSpec

from ...backend import FULLSCREEN_CORNERS
from .backend import BlenderGPUBackend
from .gpu_objects import empty_texture, float_texture, framebuffer, read_texture
from ...pacing import Steps, drive
from ...frame import GBufferSamples, ViewSamples
from ...resident import ResidentScene
from ...shaders import OVERLAY_MODES, OVERLAY_PROGRAM, PREVIEW_PROGRAM

log = logging.getLogger(__name__)

_QUAD = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 0.0), (1.0, 1.0), (0.0, 1.0)]


@dataclass
class GBuffer:
    """World position (w = 1 on geometry) and camera-facing geometric normal per pixel,
    as RGBA32F textures; read back as arrays (row 0 at the TOP) only when asked."""

    textures: dict[str, Any]  # "ow_gb_position", "ow_gb_normal"
    size: tuple[int, int]  # (W, H)
    target: Any = None  # its framebuffer (with a depth texture): a later view of this size draws into it
    # The framebuffer holds no reference to its textures: the depth is kept here, or a later
    # view drawn into `target` would be drawn without a depth test.
    depth: Any = None

    @functools.cached_property
    def positions(self) -> np.ndarray:
        """(H, W, 4) float32, row 0 at the TOP (a read-back)."""
        return read_texture(self.textures["ow_gb_position"], "RGBA32F")[::-1].copy()

    @functools.cached_property
    def normals(self) -> np.ndarray:
        """(H, W, 4) float32, row 0 at the TOP (a read-back)."""
        return read_texture(self.textures["ow_gb_normal"], "RGBA32F")[::-1].copy()

    @property
    def hit(self) -> np.ndarray:
        return self.positions[..., 3] > 0.5

    def view_samples(self, camera: CameraSpec | None) -> ViewSamples:
        """The samples as host arrays (a read-back)."""
        return ViewSamples(self.positions[..., :3].astype(np.float64), self.normals[..., :3].astype(np.float64),
                           self.hit, camera)

    def samples(self, camera: CameraSpec | None) -> GBufferSamples:
        """The samples as they stay on the GPU, for `ShadowPipeline.render`."""
        return GBufferSamples(self.textures, self.size, camera, lambda: self.view_samples(camera))


def _homogeneous_eye(camera_position: np.ndarray) -> np.ndarray:
    """(4,) float64: a 3-vector eye gets w = 1; a 4-vector is kept."""
    eye = np.asarray(camera_position, dtype=np.float64).ravel()
    return np.append(eye, 1.0) if eye.size == 3 else eye


def render_gbuffer(backend: BlenderGPUBackend, scene: ResidentScene, view_proj: np.ndarray,
                   camera_position: np.ndarray, size: tuple[int, int], reuse: GBuffer | None = None) -> GBuffer:
    """Rasterise a resident scene's objects into a G-buffer of `size` (W, H).

    The objects' vertex textures are the depth pass's (`BlenderGPUBackend.draw_gbuffer_steps`):
    an unchanged scene sends no geometry. `camera_position` turns the normals towards
    the camera: the eye (3,), or homogeneous (4,), w = 0 giving the direction towards
    an orthographic camera (`CameraSpec.eye_homogeneous`). `reuse`, a G-buffer of the
    same size no longer needed, is drawn into instead of allocating.
    """
    return drive(render_gbuffer_steps(backend, scene, view_proj, camera_position, size, reuse))


def render_gbuffer_steps(backend: BlenderGPUBackend, scene: ResidentScene, view_proj: np.ndarray,
                         camera_position: np.ndarray, size: tuple[int, int],
                         reuse: GBuffer | None = None) -> Steps[GBuffer]:
    """`render_gbuffer` as a stepped pass (render/pacing.py): each batch of draws binds the
    target and sets the state itself, so the viewport may draw other things in between."""
    import gpu

    width, height = size
    if reuse is not None and reuse.size == (width, height) and reuse.target is not None:
        pos_tex, nrm_tex, target = reuse.textures["ow_gb_position"], reuse.textures["ow_gb_normal"], reuse.target
        depth = reuse.depth
        vars(reuse).pop("positions", None)  # its read-backs are of the earlier view
        vars(reuse).pop("normals", None)
    else:
        pos_tex = float_texture((width, height), "RGBA32F")
        nrm_tex = float_texture((width, height), "RGBA32F")
        depth = empty_texture((width, height), "DEPTH_COMPONENT32F")
        target = framebuffer(color_slots=(pos_tex, nrm_tex), depth_slot=depth)

    @contextlib.contextmanager
    def bound() -> Iterator[None]:
        with target.bind():
            gpu.state.viewport_set(0, 0, width, height)
            gpu.state.depth_test_set("LESS")
            gpu.state.depth_mask_set(True)
            gpu.state.face_culling_set("NONE")
            try:
                yield
            finally:
                gpu.state.depth_test_set("NONE")
                gpu.state.depth_mask_set(False)

    with target.bind():
        target.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
    yield from backend.draw_gbuffer_steps(scene, {"ow_view_proj": np.asarray(view_proj, dtype=np.float64),
                                                  "ow_camera_pos": _homogeneous_eye(camera_position)}, bound)
    return GBuffer({"ow_gb_position": pos_tex, "ow_gb_normal": nrm_tex}, (width, height), target, depth)


def _static_batch(backend: BlenderGPUBackend, key: str, shader, corners: list[tuple[float, float]]):
    """A screen-corner batch built once per backend: redraws must not allocate."""
    batch = backend.cached_batch(key)
    if batch is None:
        from gpu_extras.batch import batch_for_shader

        batch = batch_for_shader(shader, "TRIS", {"ow_corner": corners})
        backend.store_batch(key, batch)
    return batch


def visibility_texture(test_result: np.ndarray):
    """The pipeline's (H, W, 2) visibility and flag (row 0 at the TOP) as an RG32F texture."""
    result = np.asarray(test_result, np.float32)
    return float_texture((result.shape[1], result.shape[0]), "RG32F", result[::-1])


@dataclass(frozen=True)
class Reprojection:
    """Where a visibility computed for an earlier view is looked up from a later one: that
    view's matrix, its G-buffer's positions, and the world size of one of its pixels at
    unit view depth (the tolerance for a surface to count as the same)."""

    view_proj: np.ndarray
    positions: Any
    pixel: float

    @staticmethod
    def of(view_proj: np.ndarray, projection: np.ndarray, gbuffer: GBuffer) -> "Reprojection":
        # Projection row 1 scales view y to clip y: 2 / (P[1][1] H) is a pixel's height
        # at depth 1 (perspective), or everywhere (orthographic, where clip w = 1).
        scale = abs(float(np.asarray(projection, dtype=np.float64)[1, 1])) or 1.0
        return Reprojection(np.asarray(view_proj, dtype=np.float64), gbuffer.textures["ow_gb_position"],
                            2.0 / (scale * gbuffer.size[1]))


# Pixels of the earlier view a surface may lie from where the later view's point lands.
REPROJECT_PIXELS = 4.0


def draw_shadow_composite(backend: BlenderGPUBackend, gbuffer: GBuffer, visibility, light: LightSpec,
                          strength: float, target_size: tuple[int, int], draw_base: bool,
                          reprojection: Reprojection | None = None) -> None:
    """Draw one light's shadow into the bound framebuffer, stretched over `target_size`.

    `visibility` is an RG32F texture of the G-buffer's size, row 0 at the bottom (the
    viewport's own, `ShadowPipeline.visibility_into`, or `visibility_texture`), made once
    per result so that a redraw allocates nothing. Without `draw_base`, shadowed pixels are darkened by
    alpha blending (viewport). A sun shades by its direction, not its lamp position.
    With a `reprojection`, the visibility belongs to that earlier view: each pixel of
    `gbuffer` (this view's) takes the earlier pixel its point lands on, where that pixel
    saw the same surface; a pixel the earlier view did not see is drawn lit.
    """
    import gpu

    earlier = reprojection.positions if reprojection is not None else gbuffer.textures["ow_gb_position"]
    textures = dict(gbuffer.textures, ow_visibility=visibility, ow_old_position=earlier)
    shader = backend.bind_program(PREVIEW_PROGRAM, {
        "ow_reproject": 0 if reprojection is None else 1,
        "ow_old_view_proj": np.eye(4) if reprojection is None else reprojection.view_proj,
        "ow_old_tolerance": 0.0 if reprojection is None else REPROJECT_PIXELS * reprojection.pixel,
        "ow_light_pos": np.asarray(light.position, dtype=np.float64),
        "ow_sun": 1 if light.emission == "sun" else 0,
        "ow_light_dir": -light.axis,
        "ow_strength": float(strength),
        "ow_draw_base": 1 if draw_base else 0,
        "ow_target_size": (float(target_size[0]), float(target_size[1]))}, textures)
    batch = _static_batch(backend, "preview_fullscreen", shader, FULLSCREEN_CORNERS)
    previous = gpu.state.blend_get()
    gpu.state.blend_set("NONE" if draw_base else "ALPHA")
    try:
        batch.draw(shader)
    finally:
        gpu.state.blend_set(previous)


def pool_image(image: np.ndarray, max_side: int, reduce=np.max) -> np.ndarray:
    """Shrink an image by an integer factor until it fits `max_side`, keeping peaks
    (np.max, for counts) or nearest surfaces (np.min, for depth)."""
    image = np.asarray(image)
    factor = max(1, -(-max(image.shape[:2]) // max_side))
    if factor == 1:
        return image
    h, w = (image.shape[0] // factor) * factor, (image.shape[1] // factor) * factor
    return reduce(reduce(image[:h, :w].reshape(h // factor, factor, w // factor, factor), axis=3), axis=1)


@dataclass
class OverlayPanel:
    """One thumbnail: an image (row 0 at the bottom) and how to colour it."""

    label: str
    image: np.ndarray  # (h, w) float32
    mode: int  # shaders.OVERLAY_MODES: depth, or count heat (log)
    maximum: float = 1.0
    texture: Any = None  # made on first draw, then reused

    def gpu_texture(self):
        if self.texture is None:
            image = np.asarray(self.image, dtype=np.float32)
            self.texture = float_texture((image.shape[1], image.shape[0]), "R32F", image)
        return self.texture


CORNERS = ("BOTTOM_LEFT", "BOTTOM_RIGHT", "TOP_LEFT", "TOP_RIGHT")


def overlay_layout(count: int, thumb: int, target_size: tuple[int, int], corner: str,
                   margin: int = 12, text_rows: int = 0) -> list[tuple[int, int]]:
    """Lower-left pixel of each thumbnail, in a row from the chosen corner."""
    width, height = target_size
    gap = 6
    line = 16
    total = count * thumb + max(0, count - 1) * gap
    x0 = margin if corner.endswith("LEFT") else max(margin, width - margin - total)
    label_room = 18 + line * text_rows
    y0 = margin + label_room if corner.startswith("BOTTOM") else max(margin, height - margin - thumb - 14)
    return [(x0 + i * (thumb + gap), y0) for i in range(count)]


def draw_overlay(backend: BlenderGPUBackend, panels: list[OverlayPanel], target_size: tuple[int, int],
                 thumb: int, corner: str, stats_lines: list[str], legend_max: float | None) -> None:
    """Thumbnails with labels, a heat legend for count maps, and stats lines, in pixels."""
    import blf
    import gpu

    if corner not in CORNERS:
        raise ValueError(f"overlay corner must be one of {CORNERS}, got {corner!r}")
    origins = overlay_layout(len(panels), thumb, target_size, corner, text_rows=len(stats_lines))
    previous = gpu.state.blend_get()
    gpu.state.blend_set("NONE")
    try:
        for panel, (x, y) in zip(panels, origins):
            texture = panel.gpu_texture()
            shader = backend.bind_program(OVERLAY_PROGRAM, {
                "ow_rect": (float(x), float(y), float(thumb), float(thumb)),
                "ow_target_size": (float(target_size[0]), float(target_size[1])),
                "ow_mode": panel.mode, "ow_max": float(panel.maximum)}, {"ow_image": texture})
            _static_batch(backend, "overlay_quad", shader, _QUAD).draw(shader)
        if legend_max is not None and origins:
            x, y = origins[0]
            shader = backend.bind_program(OVERLAY_PROGRAM, {
                "ow_rect": (float(x), float(y - 14), float(thumb), 6.0),
                "ow_target_size": (float(target_size[0]), float(target_size[1])),
                "ow_mode": OVERLAY_MODES["legend"], "ow_max": float(legend_max)}, {"ow_image": backend_dummy(backend)})
            _static_batch(backend, "overlay_quad", shader, _QUAD).draw(shader)
    finally:
        gpu.state.blend_set(previous)
    font = 0
    blf.size(font, 11)
    blf.color(font, 1.0, 1.0, 1.0, 0.95)
    for panel, (x, y) in zip(panels, origins):
        blf.position(font, x + 3, y + thumb + 3, 0)
        blf.draw(font, panel.label)
    if legend_max is not None and origins:
        x, y = origins[0]
        blf.position(font, x + thumb + 6, y - 15, 0)
        blf.draw(font, f"count 0 .. {legend_max:.0f} (log)")
    if origins:
        x, y = origins[0]
        for row, text in enumerate(stats_lines):
            blf.position(font, x, y - 32 - 16 * row, 0)
            blf.draw(font, text)


def backend_dummy(backend: BlenderGPUBackend):
    """A 1x1 texture for a sampler a draw mode does not read."""
    if backend._overlay_dummy is None:
        backend._overlay_dummy = float_texture((1, 1), "R32F", np.zeros((1, 1), np.float32))
    return backend._overlay_dummy
