"""Cameras as Blender has them: perspective or orthographic, any sensor fit, lens shift,
pixel aspect and resolution percentage, all described by one view-space image window.

A camera looks along its local -Z with +Y up. Its image window (left, right, bottom,
top) is the rectangle the image covers in view space: tangents at unit depth for a
perspective camera, scene units for an orthographic one. A pixel (col, row), row 0 at
the top, has normalised device coordinates x = 2 (col + 0.5) / W - 1 and
y = 1 - 2 (row + 0.5) / H, and the window maps them linearly (x_view = cx + x * hx,
cx and hx its centre and half width). Sensor fit, shift and non-square pixels only
move and stretch the window against the W x H pixels, so one window describes every
Blender camera; `blender_camera_window` computes it with Blender's own rule
(BKE_camera_params_compute_viewplane, which Cycles follows).

The older centred form (`fov_deg` spanning the larger image side, square pixels)
stays the default constructor: `CameraSpec(matrix, fov_deg, (W, H))` gives the same
numbers, bit for bit, as before windows existed.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .errors import InputError

log = logging.getLogger(__name__)

# (left, right, bottom, top) of the image in view space (see the module docstring).
Window = tuple[float, float, float, float]
SensorFit = Literal["AUTO", "HORIZONTAL", "VERTICAL"]
# Projection matrices entries this close to their ideal value count as exact.
_MATRIX_TOL = 1e-6


@dataclass
class CameraSpec:
    """One camera: world matrix, image size, clip range and its image window.

    `window` None is the centred perspective camera whose `fov_deg` spans the larger
    image side (Blender's AUTO fit, square pixels, no shift). With a window, `fov_deg`
    only describes it (the angle the window spans along the larger side; 0 for an
    orthographic camera): use `frame_extents()` and the ray helpers, never fov_deg.
    """

    matrix_world: np.ndarray
    fov_deg: float
    resolution: tuple[int, int]  # (width, height) in pixels
    clip_start: float = 0.05
    clip_end: float = 200.0
    window: Window | None = None
    ortho: bool = False

    def __post_init__(self) -> None:
        if self.window is not None:
            left, right, bottom, top = (float(v) for v in self.window)
            if not all(math.isfinite(v) for v in (left, right, bottom, top)) or not (left < right and bottom < top):
                raise InputError(f"camera window {self.window!r} must be finite with left < right, bottom < top")
            self.window = (left, right, bottom, top)
        elif self.ortho:
            raise InputError("an orthographic camera needs its window (the image extents in scene units)")
        self.ortho = bool(self.ortho)

    @classmethod
    def from_window(cls, matrix_world: np.ndarray, window: Window, resolution: tuple[int, int],
                    clip_start: float = 0.05, clip_end: float = 200.0, ortho: bool = False) -> "CameraSpec":
        """A camera with an explicit image window; `fov_deg` is filled in for display only."""
        width, height = resolution
        return cls(np.asarray(matrix_world, dtype=np.float64), window_fov_deg(window, resolution, ortho),
                   (int(width), int(height)), float(clip_start), float(clip_end), tuple(window), ortho)

    # the window --------------------------------------------------------------
    def _centre_half(self) -> tuple[float, float, float, float]:
        """(cx, cy, hx, hy): the window's centre and half extents."""
        if self.window is None:
            # The formula of the centred form, unchanged, so old results stay bit-identical.
            width, height = self.resolution
            half = math.tan(math.radians(self.fov_deg) / 2.0)
            if width >= height:
                return 0.0, 0.0, half, half * height / width
            return 0.0, 0.0, half * width / height, half
        left, right, bottom, top = self.window
        return (left + right) / 2.0, (bottom + top) / 2.0, (right - left) / 2.0, (top - bottom) / 2.0

    def frame_extents(self) -> Window:
        """(left, right, bottom, top): tangents at unit depth, or scene units if orthographic."""
        if self.window is not None:
            return self.window
        _, _, hx, hy = self._centre_half()
        return (-hx, hx, -hy, hy)

    @property
    def is_centred(self) -> bool:
        """True when the view axis passes through the image centre."""
        cx, cy, _, _ = self._centre_half()
        return cx == 0.0 and cy == 0.0

    # view space --------------------------------------------------------------
    def view_points(self, ndc: np.ndarray, depth: np.ndarray | float) -> np.ndarray:
        """Camera-local points (..., 3) at NDC (..., 2) and view depth (along -Z)."""
        ndc = np.asarray(ndc, dtype=np.float64)
        depth = np.asarray(depth, dtype=np.float64)
        cx, cy, hx, hy = self._centre_half()
        x, y = cx + ndc[..., 0] * hx, cy + ndc[..., 1] * hy
        if not self.ortho:
            # Same order of operations as the centred form's (sx * hx) * depth.
            x, y = x * depth, y * depth
        x, y = np.broadcast_arrays(x, y)
        return np.stack([x, y, np.broadcast_to(-depth, x.shape)], axis=-1)

    def world_points(self, ndc: np.ndarray, depth: np.ndarray | float) -> np.ndarray:
        """World points (..., 3) at NDC (..., 2) and view depth."""
        m = np.asarray(self.matrix_world, dtype=np.float64)
        return self.view_points(ndc, depth) @ m[:3, :3].T + m[:3, 3]

    def rays_through_ndc(self, ndc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World ray origins and unit directions (..., 3) through NDC points (..., 2).

        A perspective ray starts at the eye; an orthographic one on the camera plane,
        and all of them run along the view axis.
        """
        m = np.asarray(self.matrix_world, dtype=np.float64)
        ndc = np.asarray(ndc, dtype=np.float64)
        if self.ortho:
            origins = self.world_points(ndc, 0.0)
            forward = -m[:3, 2] / np.linalg.norm(m[:3, 2])
            return origins, np.broadcast_to(forward, origins.shape).copy()
        dirs = self.view_points(ndc, 1.0) @ m[:3, :3].T
        dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
        return np.broadcast_to(m[:3, 3], dirs.shape).copy(), dirs

    def pixel_ndc(self) -> np.ndarray:
        """NDC (H, W, 2) of every pixel centre, row 0 at the top."""
        width, height = self.resolution
        xs = (np.arange(width) + 0.5) / width * 2.0 - 1.0
        ys = 1.0 - (np.arange(height) + 0.5) / height * 2.0
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx, gy], axis=-1)

    def pixel_rays(self) -> tuple[np.ndarray, np.ndarray]:
        """World ray origins and unit directions (H, W, 3) through every pixel centre."""
        return self.rays_through_ndc(self.pixel_ndc())

    def view_depths(self, points: np.ndarray) -> np.ndarray:
        """Depth along the view axis (-Z) of world points (..., 3)."""
        m = np.asarray(self.matrix_world, dtype=np.float64)
        return -((np.asarray(points, dtype=np.float64) - m[:3, 3]) @ m[:3, 2])

    def ndc_of(self, points: np.ndarray) -> np.ndarray:
        """NDC (..., 2) of world points (..., 3), the inverse of `world_points` (rigid matrix)."""
        m = np.asarray(self.matrix_world, dtype=np.float64)
        local = (np.asarray(points, dtype=np.float64) - m[:3, 3]) @ m[:3, :3]
        cx, cy, hx, hy = self._centre_half()
        x, y = local[..., 0], local[..., 1]
        if not self.ortho:
            depth = -local[..., 2]
            x, y = x / depth, y / depth
        return np.stack([(x - cx) / hx, (y - cy) / hy], axis=-1)

    def pixel_of(self, points: np.ndarray) -> np.ndarray:
        """Continuous pixel coordinates (..., 2) = (col, row) of world points; a pixel
        centre is at (col + 0.5, row + 0.5), row 0 at the top."""
        ndc = self.ndc_of(points)
        width, height = self.resolution
        return np.stack([(ndc[..., 0] + 1.0) * 0.5 * width, (1.0 - ndc[..., 1]) * 0.5 * height], axis=-1)

    def eye_homogeneous(self) -> np.ndarray:
        """Where the camera looks from, homogeneous (4,): the eye (w = 1), or for an
        orthographic camera the direction towards it (w = 0)."""
        m = np.asarray(self.matrix_world, dtype=np.float64)
        if self.ortho:
            back = m[:3, 2] / np.linalg.norm(m[:3, 2])
            return np.append(back, 0.0)
        return np.append(m[:3, 3], 1.0)

    # clip space --------------------------------------------------------------
    def projection(self) -> np.ndarray:
        """OpenGL 4x4 projection (view -> clip) of the camera's window and clip range."""
        n, f = self.clip_start, self.clip_end
        if self.window is None:
            # The centred form's matrix, unchanged (bit-identical results).
            width, height = self.resolution
            half = math.tan(math.radians(self.fov_deg) / 2.0)
            if width >= height:
                sx, sy = 1.0 / half, (width / height) / half
            else:
                sx, sy = (height / width) / half, 1.0 / half
            return np.array([[sx, 0, 0, 0], [0, sy, 0, 0],
                             [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)], [0, 0, -1, 0]], dtype=np.float64)
        left, right, bottom, top = self.window
        if self.ortho:
            return np.array([
                [2.0 / (right - left), 0, 0, -(right + left) / (right - left)],
                [0, 2.0 / (top - bottom), 0, -(top + bottom) / (top - bottom)],
                [0, 0, -2.0 / (f - n), -(f + n) / (f - n)],
                [0, 0, 0, 1.0],
            ], dtype=np.float64)
        # glFrustum with the window at unit depth (the near factor cancels).
        return np.array([
            [2.0 / (right - left), 0, (right + left) / (right - left), 0],
            [0, 2.0 / (top - bottom), (top + bottom) / (top - bottom), 0],
            [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)],
            [0, 0, -1.0, 0],
        ], dtype=np.float64)


def window_fov_deg(window: Window, resolution: tuple[int, int], ortho: bool = False) -> float:
    """The angle a window spans along the larger image side (0 for an orthographic one):
    the `fov_deg` that describes a windowed camera, for display."""
    left, right, bottom, top = window
    width, height = resolution
    half = (right - left) / 2.0 if width >= height else (top - bottom) / 2.0
    return 0.0 if ortho else math.degrees(2.0 * math.atan(half))


def blender_camera_window(resolution: tuple[int, int], *, ortho: bool = False, lens: float = 50.0,
                          ortho_scale: float = 6.0, sensor_fit: SensorFit = "AUTO", sensor_width: float = 36.0,
                          sensor_height: float = 24.0, shift: tuple[float, float] = (0.0, 0.0),
                          pixel_aspect: tuple[float, float] = (1.0, 1.0)) -> Window:
    """The image window of a Blender camera rendered at `resolution` (W, H) pixels.

    Blender's rule (BKE_camera_params_compute_viewplane; Cycles' blender_camera_viewplane
    agrees): the fitted side spans s = sensor / lens (perspective, tangents at unit
    depth) or s = ortho_scale (scene units); the other side follows the image's aspect
    in pixels times the pixel aspect; the shift moves the window by shift * s. The
    sensor is sensor_height for VERTICAL fit, else sensor_width; AUTO fits the wider
    side (horizontal when W * aspect_x >= H * aspect_y).
    """
    width, height = resolution
    aspect_x, aspect_y = pixel_aspect
    if not (width > 0 and height > 0 and aspect_x > 0 and aspect_y > 0):
        raise InputError(f"camera size {width}x{height} and pixel aspect {aspect_x}:{aspect_y} must be positive")
    x_ratio, y_ratio = width * aspect_x, height * aspect_y
    if sensor_fit not in ("AUTO", "HORIZONTAL", "VERTICAL"):
        raise InputError(f"unknown sensor fit {sensor_fit!r}; use AUTO, HORIZONTAL or VERTICAL")
    horizontal = sensor_fit == "HORIZONTAL" or (sensor_fit == "AUTO" and x_ratio >= y_ratio)
    if ortho:
        if not ortho_scale > 0:
            raise InputError(f"orthographic scale {ortho_scale!r} must be positive")
        size = float(ortho_scale)
    else:
        sensor = sensor_height if sensor_fit == "VERTICAL" else sensor_width
        if not (lens > 0 and sensor > 0):
            raise InputError(f"camera lens {lens!r} mm and sensor {sensor!r} mm must be positive")
        size = float(sensor) / float(lens)
    if horizontal:
        hx, hy = size / 2.0, size / 2.0 * y_ratio / x_ratio
    else:
        hx, hy = size / 2.0 * x_ratio / y_ratio, size / 2.0
    dx, dy = shift[0] * size, shift[1] * size
    return (dx - hx, dx + hx, dy - hy, dy + hy)


def blender_camera_settings(camera: CameraSpec, sensor_width: float = 36.0) -> dict[str, float | str]:
    """Blender camera and render settings that give `camera`'s window (the inverse of
    `blender_camera_window`), for a windowed camera: HORIZONTAL fit on a `sensor_width`
    sensor, the lens (or orthographic scale) for the window's width, the shift for its
    centre and the pixel aspect for its shape (the smaller side of the aspect is 1, as
    Blender allows 1 to 200)."""
    if camera.window is None:
        raise InputError("a centred camera is set by its angle (sensor fit AUTO), not by a window")
    left, right, bottom, top = camera.window
    width, height = camera.resolution
    wx, wy = right - left, top - bottom
    # W * aspect_x / (H * aspect_y) = wx / wy fixes the pixel aspect's ratio.
    ratio = (width * wy) / (height * wx)  # aspect_y / aspect_x
    aspect = (1.0, ratio) if ratio >= 1.0 else (1.0 / ratio, 1.0)
    settings: dict[str, float | str] = {
        "type": "ORTHO" if camera.ortho else "PERSP", "sensor_fit": "HORIZONTAL", "sensor_width": float(sensor_width),
        "shift_x": (left + right) / 2.0 / wx, "shift_y": (bottom + top) / 2.0 / wx,
        "pixel_aspect_x": aspect[0], "pixel_aspect_y": aspect[1],
    }
    if camera.ortho:
        settings["ortho_scale"] = wx
    else:
        settings["lens"] = sensor_width / wx
    return settings


def camera_from_matrices(view_matrix: np.ndarray, projection: np.ndarray,
                         resolution: tuple[int, int]) -> CameraSpec | None:
    """The camera behind an OpenGL view and projection matrix (perspective, off-centre or
    orthographic, as Blender's viewport makes them), or None for a projection that is
    neither (skewed, or not invertible)."""
    p = np.asarray(projection, dtype=np.float64)
    width, height = int(resolution[0]), int(resolution[1])
    if abs(p[0, 1]) > _MATRIX_TOL or abs(p[1, 0]) > _MATRIX_TOL or abs(p[2, 0]) > _MATRIX_TOL \
            or abs(p[2, 1]) > _MATRIX_TOL or abs(p[3, 0]) > _MATRIX_TOL or abs(p[3, 1]) > _MATRIX_TOL \
            or p[0, 0] <= 0.0 or p[1, 1] <= 0.0:
        log.debug("projection is neither perspective nor orthographic: %s", p.tolist())
        return None
    world = np.linalg.inv(np.asarray(view_matrix, dtype=np.float64))
    if abs(p[3, 2] + 1.0) <= _MATRIX_TOL and abs(p[3, 3]) <= _MATRIX_TOL \
            and abs(p[0, 3]) <= _MATRIX_TOL and abs(p[1, 3]) <= _MATRIX_TOL:
        # glFrustum: P[0,0] = 2 / (r - l), P[0,2] = (r + l) / (r - l), at unit depth.
        window = ((p[0, 2] - 1.0) / p[0, 0], (p[0, 2] + 1.0) / p[0, 0],
                  (p[1, 2] - 1.0) / p[1, 1], (p[1, 2] + 1.0) / p[1, 1])
        near, far = p[2, 3] / (p[2, 2] - 1.0), p[2, 3] / (p[2, 2] + 1.0)
        ortho = False
    elif abs(p[3, 2]) <= _MATRIX_TOL and abs(p[3, 3] - 1.0) <= _MATRIX_TOL \
            and abs(p[0, 2]) <= _MATRIX_TOL and abs(p[1, 2]) <= _MATRIX_TOL and p[2, 2] != 0.0:
        # glOrtho: P[0,0] = 2 / (r - l), P[0,3] = -(r + l) / (r - l).
        window = ((-p[0, 3] - 1.0) / p[0, 0], (1.0 - p[0, 3]) / p[0, 0],
                  (-p[1, 3] - 1.0) / p[1, 1], (1.0 - p[1, 3]) / p[1, 1])
        near, far = (p[2, 3] + 1.0) / p[2, 2], (p[2, 3] - 1.0) / p[2, 2]
        ortho = True
    else:
        log.debug("projection is neither perspective nor orthographic: %s", p.tolist())
        return None
    return CameraSpec.from_window(world, tuple(float(v) for v in window), (width, height),
                                  float(near), float(far), ortho)
