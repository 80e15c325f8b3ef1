"""The GPU layout of the warp tables (render.backend.pack_warp_table); no GL needed."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.errors import BackendError
from addon.render.backend import pack_warp_table


def test_each_texel_holds_two_nodes_of_a_function_and_of_the_next():
    size = 4
    table = np.arange(6 * size * (size + 1), dtype=np.float32).reshape(6 * size, size + 1)
    packed = pack_warp_table(table, window=3)
    assert packed.shape == (6 * size, size + 1, 4) and packed.dtype == np.float32
    for row in range(6 * size):
        last_of_slot = row % size == size - 1
        following = row if last_of_slot else row + 1  # never the next slot's first function
        for k in range(size):
            assert packed[row, k].tolist() == [table[row, k], table[row, k + 1],
                                               table[following, k], table[following, k + 1]]


def test_column_a_holds_each_slots_shear_and_window():
    """The footprint pass widens its boxes by the shear it reads at texel (A, s * A)."""
    from addon.core.warping import max_shear

    size = 4
    rng = np.random.default_rng(1)
    table = rng.normal(0.0, 0.01, (6 * size, size + 1)).astype(np.float32)
    packed = pack_warp_table(table, window=2)
    for slot in range(6):
        info = packed[slot * size, size]
        assert info[0] == pytest.approx(max_shear(table[slot * size:(slot + 1) * size].astype(np.float64)), rel=1e-6)
        assert info[1] == 2.0
        assert not packed[slot * size + 1:(slot + 1) * size, size].any()


def test_no_table_packs_to_one_zero_texel_and_bad_shapes_are_named():
    assert pack_warp_table(None).shape == (1, 1, 4) and not pack_warp_table(None).any()
    with pytest.raises(BackendError, match="not"):
        pack_warp_table(np.zeros((10, 5)))
    with pytest.raises(BackendError):
        pack_warp_table(np.zeros((6, 1)))
