"""The view samples on the GPU and the passes that read them before the maps: the warp
tables, the count scatters of the analysis and the planning reductions."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...core.errors import BackendError
from ...core.samples import STAT_COUNT, STAT_SPAN, STAT_TEXELS
from ...core.warping import max_shear
from ..device import Target, UniformValues
from ..shaders import SAMPLE_STATS_PROGRAM, STATS_PASSES, scatter_variant


@dataclass
class SampleTargets:
    """What the passes over the samples write: the shadow test's target of the samples'
    size, one R32UI count strip per count-map size, and the statistics' row."""

    size: tuple[int, int] | None = None  # (width, height) of the sample textures
    test: tuple[Any, Target] | None = None  # (RG32F texture, its target)
    counts: dict[int, Any] = field(default_factory=dict)  # count-map size -> strip of its tiles
    stats: Any = None  # R32UI row of the planning statistics
    stats_out: Any = None  # R32UI row of their STAT_COUNT fields alone, the one the host reads
    # What the sample textures hold, as the uploader named it (ShadowPipeline's key of a
    # read-only ViewSamples and its light); None after any other upload or a G-buffer.
    source: Any = None

    def held(self) -> list[Any]:
        """Every GPU object held here, targets before their textures."""
        return [*(reversed(self.test) if self.test else ()), *self.counts.values(), self.stats, self.stats_out]


def set_size(backend, size: tuple[int, int]) -> None:
    """New samples of `size` from now on (their source unnamed): the shadow test's target
    follows them."""
    held = backend.samples
    held.source = None
    if held.size != size:
        device = backend.device
        if held.test is not None:
            device.free(held.test[1], held.test[0])
        out = device.texture(size, "RG32F")
        held.test = (out, device.target((out,)))
        held.size = size


def upload_samples(backend, positions: np.ndarray, normals: np.ndarray) -> None:
    """View samples for the scatter and test passes: (H, W, 4) float32, row 0 at the bottom.

    positions: light-centred xyz; w = the sample's importance weight (an integer >= 1, 1
    unless ViewSamples.importance is given) where the pixel hit geometry, 0 where it missed.
    """
    height, width = positions.shape[:2]
    for name, data in (("ow_positions", positions), ("ow_normals", normals)):
        backend.textures[name] = backend.device.upload(backend.textures.get(name), (width, height), "RGBA32F", data)
    set_size(backend, (width, height))


def pack_warp_table(table: np.ndarray | None, window: int = 0, crops: np.ndarray | None = None) -> np.ndarray:
    """The GPU layout of a (6 * A, A + 1) warp table: (6 * A, A + 1, 4) float32.

    Texel (k, row), k < A, holds the four offsets one evaluation needs: nodes k and k + 1
    of function i = row and of its neighbour i + 1 (the same function at the last one of a
    slot's A). One fetch instead of four: on a software rasteriser the fetches of the
    warp dominate the warped depth pass, which evaluates it twice per texel (see
    lib/warp.glsl). Texel (A, s * A) holds slot s's family's shear (warping.max_shear) and
    smoothing `window`, which the footprint pass's boxes read; texel (A, s * A + 1) of the
    rows table holds slot s's DV crop, `crops[s]` (LayerMapping.crop_vec4), which every
    warped pass reads (lib/mapping.glsl). None packs to one zero texel. The GPU builds the
    same layout itself (warp_build.comp).
    """
    if table is None:
        return np.zeros((1, 1, 4), dtype=np.float32)
    t = np.asarray(table, dtype=np.float32)
    size = t.shape[1] - 1
    if size < 1 or t.shape[0] % size:
        raise BackendError(f"warp table of shape {t.shape} is not (6 * A, A + 1)")
    following = np.arange(t.shape[0]) + 1
    following[size - 1::size] -= 1  # the last function of each slot has no next one: itself
    nxt = t[following]
    packed = np.zeros((t.shape[0], size + 1, 4), dtype=np.float32)
    packed[:, :size] = np.stack([t[:, :-1], t[:, 1:], nxt[:, :-1], nxt[:, 1:]], axis=-1)
    for slot in range(t.shape[0] // size):
        packed[slot * size, size, :2] = (max_shear(t[slot * size:(slot + 1) * size].astype(np.float64)), window)
        if crops is not None and size > 1:
            packed[slot * size + 1, size] = crops[slot]
    return packed


def set_warp_tables(backend, rows: np.ndarray | None, cols: np.ndarray | None,
                    crops: np.ndarray | None = None) -> None:
    """Warp offset tables, (6 * A, A + 1) float32 each (slot-major), or None for no warp,
    uploaded as `pack_warp_table` lays them out (RGBA32F, (A + 1) x 6A), the rows table with
    each slot's crop vec4 (`crops`, (6, 4); a warped layer's passes read it there). "No
    warp" is one zero texel, made once and bound as both; each table's own texture is kept
    for the next warped frame to write in place (where the device can)."""
    device = backend.device
    if backend.no_warp is None:
        backend.no_warp = device.texture((1, 1), "RGBA32F", pack_warp_table(None))
    for name, table, crop in (("ow_warp_rows", rows, crops), ("ow_warp_cols", cols, None)):
        if table is None:
            backend.textures[name] = backend.no_warp
            continue
        data = pack_warp_table(table, crops=crop)
        backend.warp_build.generation += 1  # a GPU-built warp's tables are overwritten
        held = device.upload(backend.warp_tables.get(name), (data.shape[1], data.shape[0]), "RGBA32F", data)
        backend.textures[name] = backend.warp_tables[name] = held


def scatter_counts(backend, size: int, tiles: int, uniforms: UniformValues, read: bool = True) -> np.ndarray | None:
    """Count maps of the uploaded samples, all layers in one dispatch (SCATTER_PROGRAM),
    into the strip of `size` (SampleTargets.counts), where the GPU's warp reads them.

    With `read`, returns the strip as (size, size * tiles) float32, row 0 at the bottom
    (v = 0); the layer in slot s fills the columns of tile `uniforms["ow_slot_tile"][s]`.
    """
    held = backend.samples
    if held.size is None:
        raise BackendError("scatter_counts called before upload_samples")
    device = backend.device
    target = held.counts.get(size)
    if target is None or device.texture_size(target)[0] != size * tiles:
        # One strip per count-map size, reallocated when the layer count changes.
        device.free(target)
        target = held.counts[size] = device.texture((size * tiles, size), "R32UI")
    device.clear_image(target)
    iface = scatter_variant(uniforms)
    width, height = held.size
    device.dispatch(iface, uniforms, backend.textures, {"ow_counts": target}, iface.groups(width * height))
    return device.read(target, "R32UI").astype(np.float32) if read else None


def reduce_samples(backend, uniforms: UniformValues, histogram: bool) -> np.ndarray:
    """The planning statistics of the uploaded samples (SAMPLE_STATS_PROGRAM), in one read.

    Zeroes the reduction image (core.samples.STAT_TEXELS R32UI texels) and runs pass 0
    (the fields); with `histogram`, pass 1 (the depth histogram over pass 0's range) and
    pass 2 (the percentile cut's bins) too. The last pass copies the STAT_COUNT fields
    into a texture of their own, read as uint32: the only read of the planning
    statistics, 76 bytes on every device (Blender's `gpu` reads whole textures).
    """
    held = backend.samples
    if held.size is None:
        raise BackendError("reduce_samples called before upload_samples")
    device = backend.device
    if held.stats is None:
        held.stats = device.texture((STAT_TEXELS, 1), "R32UI")
        held.stats_out = device.texture((STAT_COUNT, 1), "R32UI")
    device.clear_image(held.stats)
    width, height = held.size
    groups = SAMPLE_STATS_PROGRAM.groups(-(-width * height // STAT_SPAN))
    passes = ("fields", "histogram", "cut") if histogram else ("fields", "copy")
    images = {"ow_stats": held.stats, "ow_stats_out": held.stats_out}
    for name in passes:
        device.dispatch(SAMPLE_STATS_PROGRAM, {**uniforms, "ow_stats_pass": STATS_PASSES[name]}, backend.textures,
                        images, groups if name in ("fields", "histogram") else 1)
    return device.read(held.stats_out, "R32UI").ravel()
