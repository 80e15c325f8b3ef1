"""The primitives a GPU backend provides: textures and images, targets, clears, draws,
dispatches, barriers, reads and timer queries.

Every pass (render/passes) is written once over this interface; a backend is a thin
adapter of it to one API (backends/moderngl, backends/blender). Programs are named
by their `shaders.ProgramInterface`, uniforms and textures by the names it declares, so
every adapter runs the same GLSL.

Texture formats are spelled as Blender spells them: R32F, RG32F, RGBA32F (float, nearest
filtering) and R32UI (the images the compute and exact passes write).
"""
from __future__ import annotations

import contextlib
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np

from .shaders import ComputeInterface, ProgramInterface

Rect = tuple[int, int, int, int]  # (x, y, width, height) in target pixels
UniformValues = dict[str, object]
Program = ProgramInterface | ComputeInterface

# The one triangle that covers a target (fullscreen.vert): every screen pass draws it.
FULLSCREEN_CORNERS: tuple[tuple[float, float], ...] = ((-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0))
# Components per texel of each float format.
COMPONENTS = {"R32F": 1, "RG32F": 2, "RGBA32F": 4, "R32UI": 1}


@dataclass
class Target:
    """A framebuffer over `colors` (and a depth buffer when `depth` holds one)."""

    handle: Any
    colors: tuple[Any, ...]
    size: tuple[int, int]
    depth: Any = None


@dataclass(frozen=True)
class Geometry:
    """What a draw rasterises.

    FULLSCREEN: the one covering triangle. CORNERS: triangles [first, first + count) of
    the footprint pass's corner buffer (footprints.corner_indices), as FOOTPRINT_VERTICES
    vertices each, or as one point each with `points`. VERTICES: per-vertex arrays by
    attribute name (the depth pass's triangles).
    """

    kind: str
    first: int = 0
    count: int = 0
    points: bool = False
    arrays: dict[str, np.ndarray] = field(default_factory=dict)

    @staticmethod
    def corners(first: int, count: int, points: bool = False) -> "Geometry":
        return Geometry("corners", first, count, points)

    @staticmethod
    def vertices(arrays: dict[str, np.ndarray]) -> "Geometry":
        return Geometry("vertices", arrays=arrays)


FULLSCREEN = Geometry("fullscreen")


class Device(ABC):
    """One GPU API, reduced to what the passes need."""

    name: str = "abstract"
    # Whether CORNERS draws may be point sprites (the shader sets the point size).
    point_sprites: bool = True
    # Whether `read` of a rect reads the whole texture back first (Blender's `gpu`).
    reads_whole: bool = False

    @contextlib.contextmanager
    def bound(self) -> Iterator[None]:
        """Make this device's context current for the calls inside (re-entrant)."""
        yield

    @abstractmethod
    def renderer(self) -> str:
        """Human-readable renderer string."""

    @abstractmethod
    def max_texture_size(self) -> int:
        """Largest 2D texture side the GPU accepts."""

    # resources ----------------------------------------------------------------
    @abstractmethod
    def texture(self, size: tuple[int, int], fmt: str, data: np.ndarray | None = None) -> Any:
        """A 2D texture of `size` (width, height) and `fmt`, from `data` (row 0 at the bottom) or undefined."""

    @abstractmethod
    def upload(self, texture: Any, size: tuple[int, int], fmt: str, data: np.ndarray) -> Any:
        """`data` in `texture` when it has this size and format (written in place where the
        API can), else in a new one (the old one freed); returns the texture that holds it."""

    @abstractmethod
    def free(self, *objects: Any) -> None:
        """Free textures and targets made here (None is skipped)."""

    @abstractmethod
    def texture_size(self, texture: Any) -> tuple[int, int]:
        """(width, height) of a texture."""

    @abstractmethod
    def target(self, colors: tuple[Any, ...], depth: bool = False) -> Target:
        """A framebuffer over the `colors` textures, with a 32-bit depth buffer of their size when `depth`."""

    @abstractmethod
    def clear(self, target: Target, color: tuple[float, float, float, float], depth: float | None = None,
              rects: list[Rect] | None = None) -> None:
        """Clear a target's colour (and depth); only inside `rects` when given (scissored clears)."""

    @abstractmethod
    def clear_image(self, image: Any) -> None:
        """Zero an R32UI image, on the GPU."""

    @abstractmethod
    def read(self, texture: Any, fmt: str, rect: Rect | None = None) -> np.ndarray:
        """A texture, or its `rect`, as (height, width[, components]) float32 (uint32 for
        R32UI), row 0 at the bottom. Where the API reads whole textures only (Blender's
        `gpu`), a rect is cut from the whole."""

    # work ---------------------------------------------------------------------
    @abstractmethod
    def drawing(self, target: Target, viewport: Rect, scissor: Rect | None = None,
                depth_test: bool = False) -> contextlib.AbstractContextManager:
        """Bind `target` for the draws inside: the viewport, a scissor rectangle, and a
        less-than depth test with writes (no face culling: both windings draw)."""

    @abstractmethod
    def draw(self, iface: ProgramInterface, uniforms: UniformValues, textures: dict[str, Any],
             geometry: Geometry = FULLSCREEN, images: dict[str, Any] | None = None) -> None:
        """Draw `geometry` with a program into the bound target; samplers and images by name."""

    @abstractmethod
    def dispatch(self, iface: ComputeInterface, uniforms: UniformValues, textures: dict[str, Any],
                 images: dict[str, Any], groups: int) -> None:
        """Run a compute program over `groups` work groups, then a barrier (its image stores
        are visible to every later fetch, image load and read)."""

    @abstractmethod
    def barrier(self) -> None:
        """Make image stores of earlier draws visible to later image loads and reads."""

    @abstractmethod
    def finish(self, target: Target | None = None) -> None:
        """Block until the GPU has finished every submitted command (`target`: one it may read to wait)."""

    def timer(self, key: str = "frame") -> "GPUTimer | None":
        """The GPU timer query named `key`, or None where the API has none (Blender's `gpu`).
        Each key has one query, made on first use and handed out again: read a key's
        `elapsed_ms` before timing with it again. Timers do not nest."""
        return None

    @abstractmethod
    def release(self) -> None:
        """Free what the device itself holds (programs, buffers, the context)."""


class GPUTimer(ABC):
    """Times the GPU work submitted inside `with timer:`; `elapsed_ms` waits for the result."""

    @abstractmethod
    def __enter__(self) -> "GPUTimer": ...

    @abstractmethod
    def __exit__(self, *exc) -> None: ...

    @property
    @abstractmethod
    def elapsed_ms(self) -> float: ...
