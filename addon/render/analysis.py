"""The analysis of a warped frame (thesis Algorithm 3, steps 2-7): the DV crop and the warp
of every drawn layer, from count maps of the view samples (docs/design.md section 4).

NoTW and RTW are built on the GPU (passes/warp.py): the scatters fill a count strip
there, the crop and the tables are built from it and stay there, and nothing is read back.
Count maps finer than the GPU build takes go through numpy (core/warping.py, the oracle of
both): their count maps are read back and their tables uploaded.
"""
from __future__ import annotations

import numpy as np

from ..core.plan import Plan
from ..core.scene import LightSpec
from ..core.warping import (
    FLOOR_SHARE,
    MAX_SLOPE,
    LayerMapping,
    Warp,
    WarpParams,
    dv_crop_from_counts,
    notw_cols,
    notw_rows,
    rtw_from_counts,
)
from .backend import ShadowBackend
from .frame import ShadowSettings, analysis_size_for
from .parameterizations import slot_rotations_and_crops
from .passes.warp import MAX_GPU_WARP_SIZE, GpuMapping, GpuWarp
from .shaders import NO_TILE, PARAM_CODES, SCATTER_MODE_CODES, SLOTS


def scatter_uniforms(light: LightSpec, plan: Plan, mappings: dict[int, LayerMapping], size: int, mode: int,
                     weighted: bool) -> dict:
    """The uniforms of the scatter (and its list-linking variant) over the drawn layers."""
    slots = plan.drawn_slots
    rotations, crops = slot_rotations_and_crops(plan, mappings)
    tiles = np.full(SLOTS, NO_TILE, dtype=np.int64)
    tiles[slots] = np.arange(len(slots))
    warp_size = max((m.warp.size for m in mappings.values() if m.warp is not None), default=0)
    projective = plan.projective
    return {
        "ow_light_rot": light.rotation.T,
        "ow_layer_rot": rotations,
        "ow_layer_crop": crops,
        "ow_slot_tile": tiles,
        "ow_layer_kind": plan.layer_kind,
        "ow_param": PARAM_CODES[plan.parameterization],
        "ow_hemi": 1 if light.emission == "hemi" else 0,
        "ow_warp_size": warp_size,
        "ow_scatter_mode": mode,
        "ow_count_size": size,
        "ow_weighted": int(weighted),
        # A spot's or sun's one map: the samples through its matrix (scatter.comp).
        "ow_projective": int(projective is not None),
        "ow_map_matrix": projective.matrix if projective is not None else np.eye(4),
    }


def scatter(backend: ShadowBackend, light: LightSpec, plan: Plan, mappings: dict[int, LayerMapping], size: int,
            mode: int, weighted: bool = False, read: bool = True) -> dict[int, np.ndarray] | None:
    """Count maps of the uploaded samples in one dispatch, left in the backend's strip of
    `size`; with `read`, read back as one (size, size) map (row 0 = v = 0) per drawn layer.

    mode 0: after each layer's crop only; 1: through the row warps; 2: through the full
    warp. A layer missing from `mappings` counts uncropped. The warp tables must be bound
    for modes 1 and 2. `weighted` sums the samples' importance weights instead of
    counting them.
    """
    slots = plan.drawn_slots
    uniforms = scatter_uniforms(light, plan, mappings, size, mode, weighted)
    strip = backend.scatter_counts(size, max(len(slots), 1), uniforms, read=read)
    if strip is None:
        return None
    return {slot: strip[:, tile * size:(tile + 1) * size].copy() for tile, slot in enumerate(slots)}


def count_maps(backend: ShadowBackend, light: LightSpec, plan: Plan, mappings: dict[int, LayerMapping], size: int,
               mode: int, weighted: bool = False) -> dict[int, np.ndarray]:
    """GPU count maps (row 0 = v = 0) of the uploaded samples, one per drawn layer (`scatter`)."""
    return scatter(backend, light, plan, mappings, size, mode, weighted)


def analyse(backend: ShadowBackend, light: LightSpec, settings: ShadowSettings,
            plan: Plan) -> tuple[dict[int, LayerMapping], dict[int, np.ndarray]]:
    """DV crop and warp of every drawn layer, the tables bound for the next passes; and
    the weighted count maps the host read, where it read them (none for a GPU build).

    Each step scatters all layers at once. The counts sum the samples' importance weights
    (1 each unless ViewSamples.importance says otherwise); the DV crop only asks which
    cells are occupied.
    """
    size = settings.analysis_size or analysis_size_for(settings.resolution)
    if 2 <= size <= MAX_GPU_WARP_SIZE:
        return _on_gpu(backend, light, plan, size, settings.warp), {}
    return _on_host(backend, light, settings, plan, size)


def _on_gpu(backend: ShadowBackend, light: LightSpec, plan: Plan, size: int, kind: str) -> dict[int, GpuMapping]:
    """The crop and both families built on the GPU; nothing read back. NoTW scatters three
    times (the columns from the counts through the row warps), RTW twice."""
    slots = plan.drawn_slots

    def mappings() -> dict[int, GpuMapping]:
        return {slot: GpuMapping(GpuWarp(backend, slot, size, tile, kind)) for tile, slot in enumerate(slots)}

    scatter(backend, light, plan, {}, size, SCATTER_MODE_CODES["crop"], read=False)
    backend.build_warp_crop(size, slots)
    # From here on the passes take each layer's crop from its rows table (ow_warp_size = A).
    scatter(backend, light, plan, mappings(), size, SCATTER_MODE_CODES["crop"], weighted=True, read=False)
    backend.build_warp_family(size, slots, "rows", kind)
    if kind == "notw":
        scatter(backend, light, plan, mappings(), size, SCATTER_MODE_CODES["rows"], weighted=True, read=False)
    backend.build_warp_family(size, slots, "cols", kind)
    return mappings()


def _on_host(backend: ShadowBackend, light: LightSpec, settings: ShadowSettings, plan: Plan,
             size: int) -> tuple[dict[int, LayerMapping], dict[int, np.ndarray]]:
    """A warp past the GPU build's size, in numpy: RTW (2 scatters) and NoTW (3)."""
    whole = scatter(backend, light, plan, {}, size, 0)  # mode 0 reads no warp table
    crops = {slot: LayerMapping(*dv_crop_from_counts(counts), None) for slot, counts in whole.items()}
    counts = scatter(backend, light, plan, crops, size, 0, weighted=True)
    mappings: dict[int, LayerMapping] = {}
    if settings.warp == "rtw":
        for slot, crop in crops.items():
            mappings[slot] = LayerMapping(crop.lo, crop.hi, rtw_from_counts(counts[slot]))
    else:
        rows = {slot: notw_rows(counts[slot]) for slot in crops}
        row_only = {slot: LayerMapping(crop.lo, crop.hi, warp_of(rows[slot][0], None, size))
                    for slot, crop in crops.items()}
        backend.set_warp_tables(*stack_tables(row_only, size))
        after_rows = scatter(backend, light, plan, row_only, size, 1, weighted=True)
        for slot, crop in crops.items():
            cols, col_window = notw_cols(after_rows[slot])
            row_table, row_window = rows[slot]
            mappings[slot] = LayerMapping(crop.lo, crop.hi, warp_of(row_table, cols, size, row_window, col_window))
    backend.set_warp_tables(*stack_tables(mappings, size))
    return mappings, counts


def stack_tables(mappings: dict[int, LayerMapping], size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slot-major (6 * A, A + 1) tables of every layer's row and column offsets, and the
    (6, 4) crops that go with the rows table (`set_warp_tables`)."""
    rows = np.zeros((6 * size, size + 1), dtype=np.float32)
    cols = np.zeros((6 * size, size + 1), dtype=np.float32)
    crops = np.tile(np.array([0.0, 0.0, 1.0, 1.0], dtype=np.float32), (SLOTS, 1))
    for slot, mapping in mappings.items():
        crops[slot] = mapping.crop_vec4()
        if mapping.warp is not None:
            rows[slot * size:(slot + 1) * size] = mapping.warp.rows
            cols[slot * size:(slot + 1) * size] = mapping.warp.cols
    return rows, cols, crops


def warp_of(rows: np.ndarray, cols: np.ndarray | None, size: int, row_window: int = 0, col_window: int = 0) -> Warp:
    """A NoTW warp from its tables; no column warps yet means identity columns."""
    return Warp(rows, np.zeros((size, size + 1)) if cols is None else cols,
                WarpParams(FLOOR_SHARE, MAX_SLOPE, row_window, col_window), "notw")
