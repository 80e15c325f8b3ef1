"""The footprint pass: resident objects drawn into one tile of the atlas (the maps), or
marking the linked view samples (the exact pass), and the ray table of warped layers."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...core.errors import BackendError
from ..device import Geometry, UniformValues
from ..shaders import FOOTPRINT_PROGRAM, FOOTPRINT_VERTICES, RAY_TABLE_PROGRAM, ProgramInterface, program_variant
from ..shaders import alpha_of, exact_variant, medium_of, pieces_of
from ..pacing import Steps, drive
from .atlas import layer_viewport

RAY_BAND = 64  # rows of the ray table a stepped build measures apart


@dataclass(frozen=True)
class FootprintDraw:
    """One object's triangles [first, first + count) drawn by the footprint pass, with the
    object's own uniforms (ow_object_linear, ow_light_hi, ow_light_lo); as point sprites when
    `points` (each triangle's box is known to fit MAX_POINT_SIZE), else as quads. A part
    of `pieces` (hair, points) draws its pieces where a mesh draws triangles."""

    key: str
    first: int
    count: int
    uniforms: UniformValues
    points: bool = False
    pieces: bool = False
    medium: bool = False  # a part of a homogeneous medium (shaders.medium_of)


def corner_indices(triangles: int) -> np.ndarray:
    """The footprint pass's corner buffer for `triangles` triangles: vertex i holds i % 6.

    Devices keep one, grown by doubling, and draw a range of it per object.
    """
    return np.tile(np.arange(FOOTPRINT_VERTICES, dtype=np.float32), max(int(triangles), 1))


def corner_capacity(triangles: int, held: int) -> int:
    """Triangles a corner buffer must hold for a draw of `triangles`: `held` while it is
    enough, else the next power of two (so a growing scene reallocates rarely)."""
    if triangles <= held:
        return held
    return 1 << max(int(triangles) - 1, 1).bit_length()


def build_ray_table(backend, tile: int, uniforms: UniformValues) -> None:
    """Fill one tile of the ray table (RAY_TABLE_PROGRAM, RG32F, the atlas's size), bound as
    `ow_ray_table` for the footprint pass: the projection point of every texel of a warped
    layer. Call after begin_atlas and set_warp_tables."""
    drive(build_ray_table_steps(backend, tile, uniforms))


def build_ray_table_steps(backend, tile: int, uniforms: UniformValues) -> Steps[None]:
    """`build_ray_table` as a stepped pass: while the pacer steps (the viewport) the tile is
    drawn in bands of rows, each its own slice (at 1024 texels one draw is longer than a
    redraw may take on a software rasteriser). Each texel is computed alone, so the bands
    write what one draw writes."""
    if backend.atlas is None:
        raise BackendError("build_ray_table called before begin_atlas")
    device = backend.device
    layout = backend.atlas.layout
    table = backend.textures["ow_ray_table"]
    if device.texture_size(table) != layout.size or backend.ray_target is None:
        device.free(backend.ray_target, table)
        table = backend.textures["ow_ray_table"] = device.texture(layout.size, "RG32F")
        backend.ray_target = device.target((table,))
    x, y, width, rows = viewport = layout.span_viewport(tile, 1)

    def draw_rows(top: int) -> Callable[[int, int], None]:
        def draw(first: int, count: int) -> None:
            with device.drawing(backend.ray_target, viewport, (x, y + top + first, width, count)):
                device.draw(RAY_TABLE_PROGRAM, uniforms, backend.textures)
        return draw

    if not backend.pacer.stepping:  # one draw (in slices only while a signal is watched)
        yield from backend.pacer.steps("wait:ray_table", rows, draw_rows(0), backend.finish)
        return
    # A row's cost depends on where it crosses the layer (its middle rows cost most), so
    # each band of RAY_BAND rows keeps its own rate.
    for top in range(0, rows, RAY_BAND):
        yield from backend.pacer.steps(f"step:ray_table:{tile}:{top}", min(RAY_BAND, rows - top), draw_rows(top),
                                       backend.finish, fallback="step:ray_table")
    yield from backend.pacer.settle(backend.finish)


def footprint_program(backend, draw: FootprintDraw, uniforms: UniformValues, exact: bool,
                      points: bool) -> tuple[ProgramInterface, dict[str, object], dict[str, object]]:
    """The program one footprint draw runs (the exact pass's variant with `exact`, after
    `link_samples`; the alpha variant for a see-through part), the textures it reads from
    the object (its vertex texture and alpha map) and the images it writes, by name: the
    exact pass's lists and marks, or the atlas's veil. A BackendError for an object not resident."""
    if exact and backend.exact is None:
        raise BackendError("the exact footprint pass needs link_samples first")
    held = backend.vertices.get(draw.key)
    if held is None:
        raise BackendError(f"object {draw.key!r} is not resident; call sync_scene first")
    see_through = backend.alpha.see_through(draw.key)
    if exact:
        iface = exact_variant(uniforms, points, see_through=see_through, pieces=draw.pieces, medium=draw.medium)
        images = backend.exact.images(iface)
        if draw.medium:
            if not backend.sample_media.live:
                raise BackendError("a medium's exact pass needs link_samples with media")
            images["ow_media"] = backend.sample_media.image
    elif draw.medium:
        iface = medium_of(program_variant(FOOTPRINT_PROGRAM, uniforms, points))
        images = backend.haze.ready(backend.device, backend.atlas.layout.size)
    else:
        iface = program_variant(FOOTPRINT_PROGRAM, uniforms, points)
        iface = pieces_of(iface) if draw.pieces else (alpha_of(iface) if see_through else iface)
        images = backend.veil.ready(backend.device, backend.atlas.layout.size) if see_through else {}
    return iface, {"ow_vertices": held[1], **backend.alpha.textures_of(draw.key)}, images


def draw_footprints(backend, tile: int, draws: list[FootprintDraw], uniforms: UniformValues,
                    scissor: tuple[int, int, int, int] | None = None, exact: bool = False) -> None:
    """Draw resident objects into one tile with the footprint program (FOOTPRINT_PROGRAM).

    FOOTPRINT_VERTICES vertices per triangle (corner_indices); `uniforms` are the layer's,
    each draw adds its object's. `scissor` is as for `draw_layer`. With `exact` the
    irregular z-buffer's variant (shaders.exact_variant) marks the linked samples instead
    (uniforms ow_exact_tile, ow_exact_eps; after `link_samples`).
    """
    drive(draw_footprints_steps(backend, tile, draws, uniforms, scissor, exact))


def draw_footprints_steps(backend, tile: int, draws: list[FootprintDraw], uniforms: UniformValues,
                          scissor: tuple[int, int, int, int] | None = None, exact: bool = False) -> Steps[None]:
    """`draw_footprints` as a stepped pass (render/pacing.py): it yields between slices
    while the backend's pacer is stepping."""
    viewport = layer_viewport(backend, tile, caller="draw_footprints")
    device = backend.device
    layout = backend.atlas.layout
    if not exact and any(backend.alpha.see_through(draw.key) for draw in draws):
        # Cleared before the atlas is bound: a device may clear through a target of its own.
        backend.veil.ready(device, layout.size)
    if not exact and any(draw.medium for draw in draws):
        backend.haze.ready(device, layout.size)
    # Always scissored: point sprites may reach past the tile's edge.
    rect = viewport if scissor is None else layout.scissor_rect(tile, scissor)
    live = [draw for draw in draws if draw.count > 0]  # a count of 0 would mean "all" to some APIs
    programs = [footprint_program(backend, draw, uniforms, exact, draw.points and device.point_sprites)
                for draw in live]
    queued: list[tuple[int, int, int]] = []  # (draw, first, count) not drawn yet
    pacer = backend.pacer

    def flush() -> None:
        if queued:
            with device.drawing(backend.atlas.target, viewport, rect, depth_test=True):
                for index, first, count in queued:
                    draw, (iface, textures, images) = live[index], programs[index]
                    device.draw(iface, {**uniforms, **draw.uniforms}, {**backend.textures, **textures},
                                Geometry.corners(first, count, draw.points and device.point_sprites), images)
            queued.clear()

    def wait() -> None:
        flush()
        backend.finish()  # stepping too: a slice's time holds its GPU work (llvmpipe's threads)

    # A long draw (the exact pass over hair under a soft sun, a million triangles in the
    # viewport) in slices; each object's rate is its own (a hair piece's walk may cost a
    # thousand triangles of the ground's), and waiting and stepping rates are kept apart.
    # A run of an object costs what its triangles cover in the map, which differs from run to
    # run: each run keeps its own rate (its tile and first item), from the object's until known.
    kind = ("step:" if pacer.stepping else "wait:") + ("exact" if exact else "maps")
    for index, draw in enumerate(live):
        yield from pacer.steps(f"{kind}:{draw.key}:{tile}:{draw.first}", draw.count,
                               lambda first, count, index=index, base=draw.first: queued.append(
                                   (index, base + first, count)), wait, fallback=f"{kind}:{draw.key}")
    flush()
    yield from pacer.settle(wait)
