"""A Blender light's own size, read as a `core.light_shape` and set for a render.

One place for what Cycles and EEVEE take as the light's size: a point or spot light's
`shadow_soft_size` (a radius, not scaled by the object), a sun's `angle`, and an area
light's outline, `size` and `size_y` (scaled by the object's X and Y axes, as Cycles
scales them) and `spread`. Duck-typed on the bpy objects, so it imports without bpy.
"""
from __future__ import annotations

import logging
import math
from typing import Any, Callable

import numpy as np

from ..core.light_shape import POINT, Area, LightShape, Sphere, SunDisk

log = logging.getLogger(__name__)

# An area light cannot be of size zero (Cycles divides by its area): a hard area light is
# this small square, far below any texel of the maps and any pixel of the reference.
HARD_AREA_SIZE = 1e-5  # m
_OUTLINES = {"SQUARE": "rectangle", "RECTANGLE": "rectangle", "DISK": "ellipse", "ELLIPSE": "ellipse"}


def light_shape(light_obj: Any, matrix_world: Any | None = None) -> LightShape:
    """The shape of a light object as the file has it; `matrix_world` is the evaluated
    transform (for an area light's scale), the object's own when None."""
    light = light_obj.data
    if light.type in ("POINT", "SPOT"):
        radius = float(light.shadow_soft_size)
        return Sphere(radius) if radius > 0.0 else POINT
    if light.type == "SUN":
        angle = float(light.angle)
        return SunDisk(angle) if angle > 0.0 else POINT
    if light.type == "AREA":
        matrix = np.array(matrix_world if matrix_world is not None else light_obj.matrix_world, dtype=np.float64)
        scale_x = float(np.linalg.norm(matrix[:3, 0]))
        scale_y = float(np.linalg.norm(matrix[:3, 1]))
        square = light.shape in ("SQUARE", "DISK")
        size_x = float(light.size) * scale_x
        size_y = (float(light.size) if square else float(light.size_y)) * scale_y
        spread = float(getattr(light, "spread", math.pi))
        return Area(_OUTLINES[light.shape], size_x, size_y, spread)
    return POINT


def has_size(light: Any) -> bool:
    """True when a light datablock has a size (its object's scale aside), so its shadows
    have penumbrae."""
    if light.type in ("POINT", "SPOT"):
        return float(light.shadow_soft_size) > 0.0
    if light.type == "SUN":
        return float(light.angle) > 0.0
    return light.type == "AREA" and max(float(light.size), float(light.size_y)) > 0.0


def make_hard(light_obj: Any, set_attr: Callable[..., None]) -> None:
    """Give the light no size for a render (`--hard`): radius 0, a sun's angle 0, an area
    light HARD_AREA_SIZE across; `set_attr(owner, name, value, optional=...)` remembers the
    file's values (capture.Overrides.set)."""
    light = light_obj.data
    if light.type == "AREA":
        set_attr(light, "size", HARD_AREA_SIZE)
        set_attr(light, "size_y", HARD_AREA_SIZE)
        return
    set_attr(light, "shadow_soft_size", 0.0)
    if light.type == "SUN":
        set_attr(light, "angle", 0.0)  # a sun's softness is its angle, not its radius
