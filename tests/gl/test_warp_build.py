"""The NoTW warp built on the GPU (warp_build.comp) against its numpy oracle (core/warping.py),
on tiny count maps written straight into the count strip: the crop, each family's offsets
and window, and the packed table the passes sample."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import warping as W
from addon.render.passes import samples as passes_samples
from addon.render.passes import warp as PW

pytestmark = pytest.mark.gl


def _strip(gl_backend, maps: list[np.ndarray]) -> int:
    """Put count maps (row = v) side by side in the backend's strip of their size."""
    size = maps[0].shape[0]
    strip = np.concatenate(maps, axis=1).astype(np.uint32)
    held = gl_backend.samples.counts
    with gl_backend.device.bound():
        gl_backend.device.free(held.get(size))
        held[size] = gl_backend.device.texture((size * len(maps), size), "R32UI", strip)
    return size


def _maps(rng, size: int) -> list[np.ndarray]:
    """Tiles as scenes give them: a dense cluster, a sparse scatter, one cell, a band, and
    an empty one."""
    cluster = np.zeros((size, size))
    cluster[size // 4:size // 3, size // 2:size // 2 + 3] = rng.integers(50, 400, (size // 3 - size // 4, 3))
    sparse = (rng.random((size, size)) < 0.08) * rng.integers(1, 9, (size, size))
    single = np.zeros((size, size))
    single[size - 2, 1] = 7
    band = np.zeros((size, size))
    band[:, size // 3:size // 3 + 2] = rng.integers(1, 30, (size, 2))
    return [cluster, sparse, single, band, np.zeros((size, size))]


@pytest.mark.parametrize("size", [16, 64])
def test_crop_bounds_are_the_occupied_rows_and_columns(gl_backend, size):
    rng = np.random.default_rng(size)
    maps = _maps(rng, size)
    _strip(gl_backend, maps)
    slots = [4, 0, 2, 5, 1]
    with gl_backend.device.bound():
        PW.build_crop(gl_backend, size, slots)
        bounds = PW.read_crop_bounds(gl_backend, len(maps))
        rows_table = gl_backend.device.read(gl_backend.warp_tables["ow_warp_rows"], "RGBA32F")
    for counts, got, slot in zip(maps, bounds, slots):
        lo, hi = W.dv_crop_from_counts(counts)
        assert np.array_equal(np.stack(W.dv_crop_from_bounds(got, size)), np.stack((lo, hi)))
        # The crop every warped pass reads: the rows table's texel (A, slot A + 1), as the
        # host's LayerMapping.crop_vec4 gives it to float32.
        stored = rows_table[slot * size + 1, size]
        assert np.allclose(stored, W.LayerMapping(lo, hi).crop_vec4(), rtol=1e-6, atol=0)
    assert bounds[-1] is None and bounds[2] == (1, 1, size - 2, size - 2)


def test_the_candidate_windows_cover_the_largest_count_map():
    """The smoothing tries windows 1, 2, ... 2^(WARP_WINDOWS - 1), each by invocations of its
    own: the last must reach half the largest count map (warping.choose_window's last)."""
    from addon.render.shaders.constants import WARP_WINDOWS

    assert 1 << (WARP_WINDOWS - 2) < PW.MAX_GPU_WARP_SIZE // 2 <= 1 << (WARP_WINDOWS - 1)


@pytest.mark.parametrize("size", [16, 64, 100, 128, 256])
def test_each_family_is_the_numpy_offsets_to_float32(gl_backend, size):
    """Rows from the counts, columns from the same counts taken as after the row warps:
    the GPU's offsets within 5e-5 map units of numpy's (1e-4 at A = 256), the same smoothing window, and the
    table laid out as pack_warp_table lays numpy's out (its shear in column A)."""
    rng = np.random.default_rng(size + 1)
    maps = _maps(rng, size)[:4]  # four tiles, in the slots below
    slots = [3, 0, 5, 1]
    _strip(gl_backend, maps)
    with gl_backend.device.bound():
        PW.build_crop(gl_backend, size, slots)  # allocates the build's images and tables
        for family in ("rows", "cols"):
            PW.build_family(gl_backend, size, slots, family)
        warps = {slot: PW.GpuWarp(gl_backend, slot, size) for slot in slots}
        packed = {name: gl_backend.device.read(gl_backend.warp_tables[name], "RGBA32F")
                  for name in PW.TABLE_OF_FAMILY.values()}
    # float32's running sums lose digits in proportion to the lines they run over: 5e-5
    # map units up to A = 128, twice that at 256 (0.2 of a texel of the 2048 maps it serves).
    tolerance = 5e-5 * max(1.0, size / 128)
    for counts, slot in zip(maps, slots):
        rows, row_window = W.notw_rows(counts)
        cols, col_window = W.notw_cols(counts)
        warp = warps[slot]
        assert np.abs(warp.rows - rows).max() < tolerance
        assert np.abs(warp.cols - cols).max() < tolerance
        assert (warp.params.row_window, warp.params.col_window) == (row_window, col_window)
        for name, table, window in (("ow_warp_rows", rows, row_window), ("ow_warp_cols", cols, col_window)):
            stacked = np.zeros((6 * size, size + 1))
            stacked[slot * size:(slot + 1) * size] = table
            expected = passes_samples.pack_warp_table(stacked, window)[slot * size:(slot + 1) * size]
            got = packed[name][slot * size:(slot + 1) * size]
            assert np.abs(got[:, :size] - expected[:, :size]).max() < tolerance
            # The shear is a difference of offsets times A: its float32 error grows with A.
            assert got[0, size, 0] == pytest.approx(expected[0, size, 0], rel=1e-2, abs=1e-4)
            assert got[0, size, 1] == expected[0, size, 1]
    # The warp does what it is for: the cluster's rows give its cells many more texels.
    cluster_rows = warps[3].rows
    dense = size // 2 + 1
    assert (cluster_rows[size // 4, dense + 1] - cluster_rows[size // 4, dense]) * size > 1.0


def test_a_later_build_makes_an_earlier_warp_unreadable(gl_backend):
    """A GpuWarp's tables are overwritten by the next build: reading it then is refused
    with a clear error, and reading it first keeps it."""
    from addon.core.errors import BackendError

    size = 16
    rng = np.random.default_rng(5)
    _strip(gl_backend, _maps(rng, size)[:2])
    with gl_backend.device.bound():
        PW.build_crop(gl_backend, size, [0, 1])
        PW.build_family(gl_backend, size, [0, 1], "rows")
        PW.build_family(gl_backend, size, [0, 1], "cols")
        kept, dropped = PW.GpuWarp(gl_backend, 0, size), PW.GpuWarp(gl_backend, 1, size)
        rows = kept.rows.copy()
        PW.build_family(gl_backend, size, [0, 1], "rows")
        with pytest.raises(BackendError, match="later frame"):
            _ = dropped.rows
    assert np.array_equal(kept.rows, rows)


def test_the_sprite_stretch_from_the_gpu_bounds_the_hosts_from_its_tables(gl_backend):
    """GpuWarp.stretch (one read of the build's slopes, shears and crop scales) is the
    footprint_runs.map_stretch of the same crop and tables, within rounding: point sprites
    sized from it hold every footprint."""
    from addon.core.presets import build_preset
    from addon.render.footprint_runs import map_stretch
    from addon.render.pipeline import ShadowPipeline, ShadowSettings
    from tests.support.oracle import view_samples

    scene = build_preset("courtyard", (96, 72))
    samples, _, _ = view_samples(scene)
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples,
                                               ShadowSettings("cube", 512, warp="notw"))
    assert result.mappings
    for mapping in result.mappings.values():
        gpu = mapping.warp.stretch()
        host = map_stretch(W.LayerMapping(mapping.lo, mapping.hi,
                                          W.Warp(mapping.warp.rows, mapping.warp.cols)))
        assert host * (1 - 1e-5) <= gpu <= host * 1.01, (gpu, host)


@pytest.mark.parametrize("size", [16, 128])
def test_rtw_is_the_numpy_rtw_to_float32(gl_backend, size):
    """RTW on the GPU: each family one function from the counts' largest across, blurred,
    the same on every line; the window is RTW's blur and the shear 0."""
    rng = np.random.default_rng(size + 7)
    maps = _maps(rng, size)
    slots = [2, 5, 0, 1, 3]
    _strip(gl_backend, maps)
    with gl_backend.device.bound():
        PW.build_crop(gl_backend, size, slots)
        for family in ("rows", "cols"):
            PW.build_family(gl_backend, size, slots, family, kind="rtw")
        warps = {slot: PW.GpuWarp(gl_backend, slot, size, tile, "rtw") for tile, slot in enumerate(slots)}
        for counts, slot in zip(maps, slots):
            expected = W.rtw_from_counts(counts)
            got = warps[slot]
            assert got.kind == "rtw"
            assert np.abs(got.rows - expected.rows).max() < 5e-6
            assert np.abs(got.cols - expected.cols).max() < 5e-6
            assert (got.params.row_window, got.params.col_window) == (W.rtw_blur(size), W.rtw_blur(size))
