"""The shadow-map atlas: its layout, its clear, the depth pass and its read-back."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core.errors import BackendError
from ..device import Geometry, Rect, Target, UniformValues
from ..shaders import DEPTH_PROGRAM, program_variant


@dataclass(frozen=True)
class AtlasLayout:
    """Tiles of `resolution`^2 texels, `columns` x `rows`, tile i at (i % columns, i // columns)."""

    resolution: int
    tiles: int
    columns: int

    @property
    def rows(self) -> int:
        return max(1, -(-self.tiles // self.columns))

    @property
    def size(self) -> tuple[int, int]:
        return self.columns * self.resolution, self.rows * self.resolution

    def origin(self, tile: int) -> tuple[int, int]:
        return (tile % self.columns) * self.resolution, (tile // self.columns) * self.resolution

    def span_viewport(self, tile: int, span: int) -> tuple[int, int, int, int]:
        """Viewport (x, y, w, h) over `span` tiles side by side from `tile`, which must share a row."""
        if span < 1 or tile % self.columns + span > self.columns or tile + span > self.tiles:
            raise ValueError(f"tiles {tile}..{tile + span - 1} do not lie side by side in a "
                             f"{self.columns}-column atlas")
        x, y = self.origin(tile)
        return x, y, self.resolution * span, self.resolution

    def scissor_rect(self, tile: int, box: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
        """Atlas rectangle (x, y, w, h) of a tile-local texel box (x0, y0, x1, y1), clipped to the tile."""
        res = self.resolution
        x0, y0, x1, y1 = (min(max(int(v), 0), res) for v in box)
        x, y = self.origin(tile)
        return x + x0, y + y0, max(x1 - x0, 0), max(y1 - y0, 0)

    @staticmethod
    def for_tiles(resolution: int, tiles: int, max_texture: int) -> "AtlasLayout":
        """Widest layout (at most 3 columns) that fits the GPU's texture size limit."""
        tiles = max(1, tiles)
        for columns in (min(tiles, 3), 2, 1):
            layout = AtlasLayout(resolution, tiles, columns)
            if max(layout.size) <= max_texture:
                return layout
        raise ValueError(f"{tiles} tiles of {resolution}^2 exceed the GPU texture limit {max_texture}")


@dataclass
class Atlas:
    """The atlas of one layout: its R32F texture and a target with a depth buffer."""

    layout: AtlasLayout
    texture: Any
    target: Target


def layer_viewport(backend, tile: int, span: int = 1, caller: str = "draw_layer") -> Rect:
    """The atlas viewport of `span` tiles from `tile`; a BackendError before begin_atlas
    or for tiles that do not lie side by side."""
    if backend.atlas is None:
        raise BackendError(f"{caller} called before begin_atlas")
    try:
        return backend.atlas.layout.span_viewport(tile, span)
    except ValueError as exc:
        raise BackendError(str(exc)) from None


def clear_rects(layout: AtlasLayout, boxes: dict[int, tuple[int, int, int, int]] | None) -> list[Rect] | None:
    """What `begin_atlas` clears: None for the whole atlas, else each tile's readable box
    (the whole tile where it has none), empty boxes left out."""
    if not boxes:
        return None
    rects = []
    for tile in range(layout.tiles):
        box = boxes.get(tile)
        rect = layout.scissor_rect(tile, box) if box is not None else layout.span_viewport(tile, 1)
        if rect[2] > 0 and rect[3] > 0:
            rects.append(rect)
    return rects


def begin_atlas(backend, layout: AtlasLayout, boxes: dict[int, tuple[int, int, int, int]] | None = None) -> None:
    """Make the atlas exist at this layout and clear it to depth 1 (empty).

    `boxes` maps a tile to the texel box (x0, y0, x1, y1) the shadow test can read
    (plan.layer_scissor); such a tile is cleared only inside its box, the others
    whole. Outside a box the atlas keeps stale values: the shadow test never reads
    there (ow_layer_box), and the pipeline masks it in read-backs.
    """
    device = backend.device
    if backend.atlas is None or backend.atlas.layout != layout:
        free_atlas(backend)
        texture = device.texture(layout.size, "R32F")
        backend.atlas = Atlas(layout, texture, device.target((texture,), depth=True))
        backend.textures["ow_atlas"] = texture
    backend.veil.live = False  # cleared again at this atlas's first see-through draw
    backend.haze.live = False  # and the haze at its first medium draw
    device.clear(backend.atlas.target, (1.0, 1.0, 1.0, 1.0), depth=1.0, rects=clear_rects(layout, boxes))


def draw_layer(backend, tile: int, vertices: np.ndarray, uniforms: UniformValues, span: int = 1,
               scissor: tuple[int, int, int, int] | None = None) -> None:
    """Draw triangles into one tile (or `span` tiles side by side) with the depth program.

    `scissor` (x0, y0, x1, y1), in texels of the tile, limits the fragments drawn to the
    part of the map the shadow test can read (plan.layer_scissor). `vertices` is (n, 7)
    float32, three rows per triangle: light-centred position (3) and plane (4).
    """
    viewport = layer_viewport(backend, tile, span)
    if len(vertices) == 0:
        return
    data = np.ascontiguousarray(vertices, dtype=np.float32)
    layout = backend.atlas.layout
    # Fragments outside the readable box are never looked up (map-space culling).
    rect = viewport if scissor is None else layout.scissor_rect(tile, scissor)
    with backend.device.drawing(backend.atlas.target, viewport, rect, depth_test=True):
        backend.device.draw(program_variant(DEPTH_PROGRAM, uniforms), uniforms, backend.textures,
                            Geometry.vertices({"ow_position": data[:, 0:3], "ow_plane": data[:, 3:7]}))


def read_atlas(backend) -> np.ndarray:
    """The atlas as (rows*res, columns*res) float32, row 0 at the bottom."""
    if backend.atlas is None:
        raise BackendError("no atlas to read")
    return backend.device.read(backend.atlas.texture, "R32F")


def free_atlas(backend) -> None:
    """Free the atlas (a new layout, or the backend's release)."""
    if backend.atlas is not None:
        backend.device.free(backend.atlas.target, backend.atlas.texture)
        backend.textures.pop("ow_atlas", None)
        backend.atlas = None
