"""The NoTW and RTW warps built on the GPU (warp_build.comp) from the count strip the
scatter left: the DV crop (stored in the rows table, where every warped pass reads it),
then each family's lines and smoothing (NoTW) or its one function (RTW), and its packed
table. Nothing is read back: `GpuMapping` and `GpuWarp` read a layer's crop and tables on
request, after the frame."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core.errors import BackendError
from ...core.warping import (ALONG_BLUR_SHARE, FLOOR_SHARE, MAX_SLOPE, LayerMapping, Warp, WarpParams, box_stretch,
                             rtw_blur)
from ..shaders import NO_TILE, SLOTS, WARP_BUILD_PROGRAM, WARP_FAMILIES, warp_step_variant
from ..shaders.constants import WARP_INFO, WARP_INFO_WIDTH, WARP_WINDOWS

# The largest count-map side the GPU builds a warp for (the analysis' largest, 256): its
# smoothing tries WARP_WINDOWS windows.
MAX_GPU_WARP_SIZE = 256
# Relative room on the numbers the GPU reduced in float32, for the host's bound.
ROUNDING_ROOM = 1e-3
# The table each family writes (the samplers every warped pass reads).
TABLE_OF_FAMILY = {"rows": "ow_warp_rows", "cols": "ow_warp_cols"}


@dataclass
class WarpBuild:
    """The images of the GPU's warp construction, kept between frames."""

    bounds: Any = None  # R32UI (4 * SLOTS, 1): each tile's occupied columns and rows
    # R32UI (2 A + 5 + WARP_WINDOWS, SLOTS * A): a family's lines as float bits (offsets,
    # total, weight, the smoothed offsets, then the smoothing's denominator at each
    # candidate window: warp_build.comp)
    work: Any = None
    # R32UI (WARP_INFO_WIDTH, SLOTS), a row a tile: the columns of shaders.constants.WARP_INFO
    info: Any = None
    size: int = 0
    generation: int = 0  # bumped by every build: a GpuWarp of an earlier one is stale
    info_read: tuple[int, np.ndarray] | None = None  # (generation, info) once read this build

    def held(self) -> list[Any]:
        return [self.bounds, self.work, self.info]


def _images(backend, size: int) -> WarpBuild:
    held = backend.warp_build
    device = backend.device
    if held.size != size:
        device.free(*held.held())
        held.bounds = device.texture((4 * SLOTS, 1), "R32UI")
        held.work = device.texture((2 * size + 5 + WARP_WINDOWS, SLOTS * size), "R32UI")
        held.info = device.texture((WARP_INFO_WIDTH, SLOTS), "R32UI")
        held.size = size
    for name in TABLE_OF_FAMILY.values():
        table = backend.warp_tables.get(name)
        if table is None or device.texture_size(table) != (size + 1, SLOTS * size):
            device.free(table)
            table = backend.warp_tables[name] = device.texture((size + 1, SLOTS * size), "RGBA32F")
        backend.textures[name] = table
    return held


def _uniforms(family: str, size: int, tiles: int, tile_slots: list[int], kind: str) -> dict:
    slots = np.full(SLOTS, NO_TILE, dtype=np.int64)
    slots[:len(tile_slots)] = tile_slots
    # The blur's half-width: NoTW's along each line (warping._one_family), RTW's over its
    # one function (warping.rtw_from_counts).
    along = rtw_blur(size) if kind == "rtw" else int(round(size * ALONG_BLUR_SHARE))
    return {"ow_family": WARP_FAMILIES[family], "ow_count_size": size,
            "ow_tiles": tiles, "ow_along": along, "ow_tile_slot": slots}


def _steps(backend, family: str, size: int, tile_slots: list[int], kind: str = "notw"):
    """A function that dispatches a step of the build of one family (warp_step_variant) over
    a number of invocations: the family's uniforms and images are made once for its steps."""
    held = backend.warp_build
    counts = backend.samples.counts.get(size)
    if counts is None:
        raise BackendError("the GPU warp needs the count strip of a scatter at its size first")
    images = {"ow_counts": counts, "ow_bounds": held.bounds, "ow_work": held.work, "ow_info": held.info,
              "ow_table": backend.warp_tables[TABLE_OF_FAMILY[family]]}
    uniforms = _uniforms(family, size, len(tile_slots), tile_slots, kind)

    def run(step: str, invocations: int) -> None:
        backend.device.dispatch(warp_step_variant(step), uniforms, {}, images, WARP_BUILD_PROGRAM.groups(invocations))

    return run


def build_crop(backend, size: int, tile_slots: list[int]) -> None:
    """Each drawn layer's DV crop from the count strip of `size` (the occupied cells of the
    uncropped counts, warping.dv_crop_from_bounds), stored in the rows table."""
    if size > MAX_GPU_WARP_SIZE or size < 2:
        raise BackendError(f"the GPU warp takes count maps of 2 to {MAX_GPU_WARP_SIZE} cells, not {size}")
    held = _images(backend, size)
    tiles = len(tile_slots)
    backend.device.clear_image(held.bounds)
    run = _steps(backend, "rows", size, tile_slots)
    run("crop", size * size * tiles)
    run("crop_store", tiles)


def read_crop_bounds(backend, tiles: int) -> list[tuple[int, int, int, int] | None]:
    """The last `build_crop`'s first and last occupied column and row of each tile (None:
    empty), read back: for tests and diagnostics, never in a frame."""
    raw = backend.device.read(backend.warp_build.bounds, "R32UI", (0, 0, 4 * tiles, 1)).ravel().astype(np.int64)
    out = []
    for tile in range(tiles):
        lo_col, hi_col, lo_row, hi_row = raw[4 * tile:4 * tile + 4]
        empty = lo_col == 0  # the complement of a column index is never 0 once a cell counted
        out.append(None if empty else (int(~lo_col & 0xFFFFFFFF), int(hi_col), int(~lo_row & 0xFFFFFFFF), int(hi_row)))
    return out


def build_family(backend, size: int, tile_slots: list[int], family: str, kind: str = "notw") -> None:
    """One family of every drawn layer's warp from the count strip of `size`, into its
    table. NoTW (`kind`) takes the rows from the cropped counts and the columns from the
    counts through the row warps: lines, smoothing, packing. RTW takes both from the
    cropped counts: one function a family, packing. Nothing is read back."""
    held = _images(backend, size)
    tiles = len(tile_slots)
    if family == "rows":
        held.generation += 1  # the tables change from here: a warp of the previous build is stale
    # Each step is wide (an invocation a line, a position, a candidate window, a node): a GPU
    # runs an invocation's serial loop at its memory latency.
    if kind == "rtw":
        steps = (("rtw_top", size * tiles), ("rtw", tiles), ("rtw_spread", (size + 1) * size * tiles))
    else:
        steps = (("line_blur", size * size * tiles), ("lines", size * tiles), ("smooth_weights", tiles),
                 ("smooth_den", WARP_WINDOWS * tiles), ("smooth_shear", (size + 1) * WARP_WINDOWS * tiles),
                 ("smooth_store", (size + 1) * tiles))
    run = _steps(backend, family, size, tile_slots, kind)
    for step, invocations in (*steps, ("pack", (size + 1) * size * tiles)):
        run(step, invocations)


class GpuWarp:
    """A layer's NoTW or RTW warp as the GPU built it. Its tables stay on the GPU; `rows`,
    `cols` and `params` read them on first use, which must come before the next warped
    frame overwrites them (BackendError otherwise)."""

    def __init__(self, backend, slot: int, size: int, tile: int = 0, kind: str = "notw") -> None:
        self.kind = kind
        self._backend = backend
        self._slot = slot
        self._tile = tile
        self._generation = backend.warp_build.generation
        self.size = size
        self._warp: Warp | None = None
        self._crop: tuple[np.ndarray, np.ndarray] | None = None

    def _check_current(self) -> None:
        backend = self._backend
        if backend.released or backend.warp_build.generation != self._generation:
            raise BackendError("a GPU-built warp was read after a later frame replaced its tables")

    def _read(self) -> Warp:
        if self._warp is None:
            self._check_current()
            backend = self._backend
            tables, windows = [], []
            for name in TABLE_OF_FAMILY.values():
                packed = backend.device.read(backend.warp_tables[name], "RGBA32F")
                block = packed[self._slot * self.size:(self._slot + 1) * self.size].astype(np.float64)
                table = np.concatenate([block[:, :self.size, 0], block[:, self.size - 1:self.size, 1]], axis=1)
                tables.append(table)
                windows.append(int(round(block[0, self.size, 1])))
                if name == TABLE_OF_FAMILY["rows"]:
                    lo, scale = block[1, self.size, :2], block[1, self.size, 2:]
                    self._crop = (lo, lo + 1.0 / scale)
            self._warp = Warp(tables[0], tables[1], WarpParams(FLOOR_SHARE, MAX_SLOPE, *windows), self.kind)
        return self._warp

    def stretch(self) -> float:
        """How much the crop and warp widen a box of the plain map (core.warping.box_stretch),
        from the slopes, shears and crop scale the build left: one read of its info (a few
        hundred bytes) shared by every layer of the frame, made only for a draw that may
        use point sprites (footprint_runs.sprites_pay)."""
        self._check_current()
        held = self._backend.warp_build
        if held.info_read is None or held.info_read[0] != held.generation:
            raw = self._backend.device.read(held.info, "R32UI")
            held.info_read = (held.generation, raw.astype(np.uint32).view(np.float32))
        info = held.info_read[1][self._tile]
        crop = WARP_INFO["crop_scale"]
        slope = {family: float(info[WARP_INFO["slope"] + code]) for family, code in WARP_FAMILIES.items()}
        shear = {family: float(info[WARP_INFO["shear"] + 2 * code]) for family, code in WARP_FAMILIES.items()}
        return box_stretch(float(max(info[crop], info[crop + 1])), slope["rows"], shear["rows"], slope["cols"],
                           shear["cols"]) * (1.0 + ROUNDING_ROOM)

    def crop(self) -> tuple[np.ndarray, np.ndarray]:
        """The layer's DV crop (lo, hi) as the GPU stored it beside the tables."""
        self._read()
        return self._crop

    def __getattr__(self, name: str):
        # rows, cols, params, forward, inverse, jacobian, slopes: the Warp read back.
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._read(), name)


class GpuMapping:
    """A layer's mapping whose DV crop and warp the GPU built (LayerMapping's interface).

    The passes read the crop from the rows table, so its uniform crop (`crop_vec4`) is the
    whole map; `lo` and `hi` read the crop the GPU stored, with the tables (GpuWarp)."""

    is_identity = False

    def __init__(self, warp: GpuWarp) -> None:
        self.warp = warp

    @property
    def lo(self) -> np.ndarray:
        return self.warp.crop()[0]

    @property
    def hi(self) -> np.ndarray:
        return self.warp.crop()[1]

    @property
    def scale(self) -> np.ndarray:
        return 1.0 / (self.hi - self.lo)

    @staticmethod
    def crop_vec4() -> tuple[float, float, float, float]:
        return 0.0, 0.0, 1.0, 1.0  # the passes take a warped layer's crop from its rows table

    def __getattr__(self, name: str):
        # forward, inverse, jacobian, magnification, reach: the LayerMapping read back.
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(LayerMapping(self.lo, self.hi, self.warp._read()), name)
