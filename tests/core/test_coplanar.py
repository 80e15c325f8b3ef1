"""Faces laid over other faces (core/coplanar.py): coplanar triangles whose insides
overlap are flagged, whatever their corner order or facing; neighbours that share an edge
or meet at a fold, and parallel faces apart, are not."""
from __future__ import annotations

import numpy as np

from addon.core.coplanar import overlapping_faces


def _grid(n: int = 6, z=lambda x, y: 0.0 * x) -> np.ndarray:
    """A tiled n x n square of 2n^2 triangles over z(x, y)."""
    xs = np.linspace(-1.0, 1.0, n + 1)
    x, y = np.meshgrid(xs, xs)
    points = np.stack([x, y, z(x, y)], axis=-1)
    quads = np.stack([points[:-1, :-1], points[:-1, 1:], points[1:, 1:], points[1:, :-1]], axis=2).reshape(-1, 4, 3)
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def test_a_tiled_floor_and_a_folded_sheet_have_no_overlaps():
    assert not overlapping_faces(_grid()).any()
    assert not overlapping_faces(_grid(z=lambda x, y: 0.05 * np.sin(3.0 * x) * np.cos(2.0 * y))).any()


def test_a_copy_in_another_corner_order_and_facing_is_flagged_with_its_original():
    floor = _grid()
    copy = floor[5:8][:, [2, 1, 0]]  # reversed: facing the other way
    flags = overlapping_faces(np.concatenate([floor, copy]))
    assert set(np.flatnonzero(flags)) == {5, 6, 7, len(floor), len(floor) + 1, len(floor) + 2}


def test_a_face_over_part_of_others_flags_what_it_covers():
    floor = _grid(2)  # four cells of 1 x 1, eight triangles
    patch = np.array([[[0.2, 0.2, 0.0], [0.8, 0.2, 0.0], [0.8, 0.8, 0.0]]])  # inside the cell (0..1, 0..1)
    flags = overlapping_faces(np.concatenate([floor, patch]))
    covered = np.flatnonzero(flags[:-1])
    assert flags[-1] and len(covered) >= 1
    centres = floor[covered].mean(axis=1)
    assert np.all((centres[:, 0] > 0.0) & (centres[:, 1] > 0.0))  # only the cell under it


def test_a_parallel_face_apart_and_a_face_touching_at_an_edge_are_not_flagged():
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    above = tri + np.array([0.0, 0.0, 1e-3])  # 1 mm over: a real blocker, not a twin
    beside = np.array([[[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]])  # shares the diagonal
    assert not overlapping_faces(np.concatenate([tri, above, beside])).any()
