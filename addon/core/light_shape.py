"""The light's own size: what makes its shadows soft.

One object per shape, each in the light's local frame (the light looks along local -Z):

- `Point`: no size, the hard light the shadow maps assume;
- `Sphere`: a point or spot light of radius `radius` (Blender's `shadow_soft_size`);
- `SunDisk`: a sun whose disk spans the full angle `angle` (radians, Blender's `angle`);
- `Area`: a one-sided emitter in the local XY plane, facing -Z: a rectangle `size_x` by
  `size_y` or an ellipse with those diameters (Blender's SQUARE, RECTANGLE, DISK and
  ELLIPSE, `size`, `size_y`), whose light leaves within `spread` of the normal.

`shape_from_dict(shape.as_dict())` gives the shape back (a reference's metadata keeps it).
`stratified_points` gives the fixed pattern of points on an emitter that sampling methods
share. numpy only.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import validate
from .errors import InputError

AREA_OUTLINES = ("rectangle", "ellipse")


@dataclass(frozen=True)
class Point:
    """No size: hard shadows."""

    kind = "point"

    @property
    def sized(self) -> bool:
        return False

    def describe(self) -> str:
        return "hard"

    def as_dict(self) -> dict:
        return {"kind": self.kind}


@dataclass(frozen=True)
class Sphere:
    """A point or spot light's sphere of `radius` metres."""

    radius: float
    kind = "sphere"

    def __post_init__(self) -> None:
        validate.finite_number("the light's radius", self.radius, low=0.0)

    @property
    def sized(self) -> bool:
        return self.radius > 0.0

    def describe(self) -> str:
        return f"sphere r={self.radius:g} m"

    def as_dict(self) -> dict:
        return {"kind": self.kind, "radius": float(self.radius)}


@dataclass(frozen=True)
class SunDisk:
    """A sun's disk, `angle` radians across as seen from anywhere."""

    angle: float
    kind = "sun_disk"

    def __post_init__(self) -> None:
        validate.finite_number("the sun's angle", self.angle, low=0.0)
        if self.angle >= math.pi:
            raise InputError(f"sun angle {math.degrees(self.angle):g} degrees: it must be below 180")

    @property
    def sized(self) -> bool:
        return self.angle > 0.0

    def describe(self) -> str:
        return f"sun disk {math.degrees(self.angle):g} deg"

    def as_dict(self) -> dict:
        return {"kind": self.kind, "angle": float(self.angle)}


@dataclass(frozen=True)
class Area:
    """A one-sided area light in local XY facing -Z: a rectangle or an ellipse."""

    outline: str
    size_x: float
    size_y: float
    spread: float = math.pi
    kind = "area"

    def __post_init__(self) -> None:
        if self.outline not in AREA_OUTLINES:
            raise InputError(f"unknown area light outline {self.outline!r}; use rectangle or ellipse")
        validate.finite_number("the area light's size", self.size_x, low=0.0)
        validate.finite_number("the area light's size_y", self.size_y, low=0.0)
        validate.finite_number("the area light's spread", self.spread, low=0.0)

    @property
    def sized(self) -> bool:
        return self.size_x > 0.0 or self.size_y > 0.0

    @property
    def area(self) -> float:
        """The emitting area in square metres."""
        full = self.size_x * self.size_y
        return full if self.outline == "rectangle" else 0.25 * math.pi * full

    def describe(self) -> str:
        spread = "" if self.spread >= math.pi else f", spread {math.degrees(self.spread):g} deg"
        return f"area {self.outline} {self.size_x:g}x{self.size_y:g} m{spread}"

    def as_dict(self) -> dict:
        return {"kind": self.kind, "outline": self.outline, "size_x": float(self.size_x),
                "size_y": float(self.size_y), "spread": float(self.spread)}


LightShape = Point | Sphere | SunDisk | Area
POINT = Point()
_KINDS = {"point": Point, "sphere": Sphere, "sun_disk": SunDisk, "area": Area}


def shape_from_dict(data: dict | None) -> LightShape:
    """The shape `as_dict` wrote; None or a missing dict (an older reference) is a hard point."""
    if not data:
        return POINT
    cls = _KINDS.get(data.get("kind"))
    if cls is None:
        raise InputError(f"unknown light shape {data.get('kind')!r}")
    fields = {k: v for k, v in data.items() if k != "kind"}
    try:
        return cls(**fields)
    except TypeError as exc:
        raise InputError(f"light shape {data!r}: {exc}") from None


def stratified_unit_square(n: int) -> np.ndarray:
    """n points in [0, 1)^2, one in each cell of a near-square grid, jittered by a fixed
    low-discrepancy offset (no randomness: the same n gives the same points)."""
    if n < 1:
        raise InputError(f"the number of light samples must be at least 1, got {n}")
    cols = int(math.ceil(math.sqrt(n)))
    rows = int(math.ceil(n / cols))
    index = np.arange(n)
    # R2 sequence offsets (Roberts 2018) inside each cell keep the pattern fixed and even.
    g = 1.32471795724474602596
    jitter = np.stack([(0.5 + index / g) % 1.0, (0.5 + index / (g * g)) % 1.0], axis=1)
    cell = np.stack([index % cols, index // cols], axis=1).astype(np.float64)
    return (cell + jitter) / np.array([cols, rows], dtype=np.float64)


def unit_disk(uv: np.ndarray) -> np.ndarray:
    """Shirley and Chiu's concentric map of [0, 1)^2 onto the unit disk: equal areas stay
    equal, so a stratified square gives a stratified disk."""
    a = 2.0 * np.asarray(uv, dtype=np.float64) - 1.0
    x, y = a[:, 0], a[:, 1]
    use_x = np.abs(x) > np.abs(y)
    r = np.where(use_x, x, y)
    safe_x = np.where(x == 0.0, 1.0, x)
    safe_y = np.where(y == 0.0, 1.0, y)
    phi = np.where(use_x, (math.pi / 4.0) * (y / safe_x), (math.pi / 2.0) - (math.pi / 4.0) * (x / safe_y))
    phi = np.where((x == 0.0) & (y == 0.0), 0.0, phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


def stratified_points(shape: LightShape, n: int) -> np.ndarray:
    """The fixed pattern of n points on the emitter, in the light's local frame (n, 3).

    An area light's points lie on its outline's surface (z = 0); a sphere's on the disk of
    its radius facing the receiver, given here in the disk's own plane (z = 0), which the
    caller turns towards each receiver; a sun's are unit directions towards the light
    (local +Z) within half its angle. A point light's n points are its centre.
    """
    uv = stratified_unit_square(n)
    if isinstance(shape, Area):
        if shape.outline == "rectangle":
            xy = (uv - 0.5) * np.array([shape.size_x, shape.size_y])
        else:
            xy = 0.5 * unit_disk(uv) * np.array([shape.size_x, shape.size_y])
        return np.column_stack([xy, np.zeros(n)])
    if isinstance(shape, Sphere):
        return np.column_stack([shape.radius * unit_disk(uv), np.zeros(n)])
    if isinstance(shape, SunDisk):
        # Uniform in solid angle over the cap of half angle angle / 2.
        cos_max = math.cos(0.5 * shape.angle)
        cos_t = 1.0 - uv[:, 0] * (1.0 - cos_max)
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
        phi = 2.0 * math.pi * uv[:, 1]
        return np.column_stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t])
    return np.zeros((n, 3))
