"""NoTW / RTW warps (addon/core/warping.py): bounds that follow from the method itself.

Every 1D offset function must be strictly increasing with slope in [floor, max_slope],
hold 0 at both ends, and be the identity for an empty row; the 2D warp must then be
monotone per axis, fold-free (positive Jacobian), finite and exactly invertible.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from addon.core import warping as W
from addon.core.errors import InputError

SIZES = st.sampled_from([1, 2, 3, 8, 17, 32])


def count_maps(size_strategy=SIZES):
    """Random, sparse, spiky and extreme count maps (including NaN and inf entries)."""
    return size_strategy.flatmap(lambda n: arrays(
        np.float64, (n, n),
        elements=st.one_of(st.just(0.0), st.just(0.0), st.floats(0, 10), st.floats(0, 1e30),
                           st.just(np.nan), st.just(np.inf), st.just(-5.0)),
    ))


def _check_family(offsets: np.ndarray, floor: float, max_slope: float) -> None:
    size = offsets.shape[1] - 1
    assert np.all(np.isfinite(offsets))
    assert np.all(offsets[:, 0] == 0.0) and np.all(offsets[:, -1] == 0.0)
    nodes = np.arange(size + 1) / size + offsets
    steps = np.diff(nodes, axis=1) * size  # slope of x + o(x) per cell
    assert steps.min() >= floor * (1 - 1e-9)
    assert steps.max() <= max_slope * (1 + 1e-9)


@settings(max_examples=150, deadline=None)
@given(count_maps(), st.sampled_from([0.02, 0.1, 0.5, 1.0]), st.sampled_from([1.0, 2.0, 8.0, 64.0]))
def test_row_offsets_increasing_bounded_finite(counts, floor, max_slope):
    """Density floor and steepness clamp hold for any count map, even NaN/inf/negative entries."""
    _check_family(W.offsets_from_counts(counts, floor, max_slope), floor, max_slope)


@settings(max_examples=60, deadline=None)
@given(count_maps(st.sampled_from([4, 16, 32])), st.integers(0, 20))
def test_smoothing_keeps_monotone_and_limits_shear(counts, window):
    """A count-weighted tent average of increasing functions stays increasing (same floor)."""
    clean = np.nan_to_num(np.maximum(np.nan_to_num(counts, posinf=0.0), 0.0))
    offsets = W.offsets_from_counts(clean)
    smooth = W.smooth_offsets(offsets, clean.sum(axis=1), window)
    _check_family(smooth, W.FLOOR_SHARE, W.MAX_SLOPE)
    chosen = W.choose_window(offsets, clean.sum(axis=1))
    if chosen < offsets.shape[0] // 2:
        assert W.max_shear(W.smooth_offsets(offsets, clean.sum(axis=1), chosen)) <= W.SHEAR_LIMIT


def test_uniform_count_map_gives_identity():
    counts = np.full((32, 32), 7.0)
    warp = W.build_notw((np.stack(np.meshgrid((np.arange(64) + 0.5) / 64, (np.arange(64) + 0.5) / 64), -1)
                         .reshape(-1, 2)), 32)
    assert np.abs(W.offsets_from_counts(counts)).max() < 1e-12
    assert np.abs(warp.rows).max() < 1e-12 and np.abs(warp.cols).max() < 1e-12
    q = np.random.default_rng(0).random((100, 2))
    assert np.allclose(warp.forward(q), q, atol=1e-12)


def test_empty_rows_are_identity_and_empty_map_is_identity():
    counts = np.zeros((16, 16))
    counts[5, 3] = 10.0
    offsets = W.offsets_from_counts(counts)
    assert np.all(offsets[np.arange(16) != 5] == 0.0)
    assert np.any(offsets[5] != 0.0)
    empty = W.build_notw(np.zeros((0, 2)), 16)
    assert np.all(empty.rows == 0.0) and np.all(empty.cols == 0.0)


def test_bad_parameters_are_named():
    with pytest.raises(InputError, match="floor"):
        W.offsets_from_counts(np.ones((4, 4)), floor=0.0)
    with pytest.raises(InputError, match="steepness"):
        W.offsets_from_counts(np.ones((4, 4)), max_slope=0.5)


def _sample_sets():
    """Random, clustered, single-texel and edge-hugging view-sample sets in uv."""
    rng = np.random.default_rng(7)
    return {
        "uniform": rng.random((5000, 2)),
        "cluster": np.clip(rng.normal([0.3, 0.7], 0.02, (5000, 2)), 0, 0.999),
        "single_texel": np.full((3000, 2), 0.50001),
        "one_sample": np.array([[0.9, 0.1]]),
        "edge": np.column_stack([rng.random(4000), np.full(4000, 0.9999)]),
        "two_clusters": np.concatenate([rng.normal([0.2, 0.2], 0.01, (3000, 2)),
                                        rng.normal([0.8, 0.8], 0.05, (3000, 2))]).clip(0, 0.999),
    }


@pytest.mark.parametrize("kind", ["notw", "rtw"])
@pytest.mark.parametrize("name", list(_sample_sets()))
@pytest.mark.parametrize("size", [8, 64])
def test_warp_is_monotone_fold_free_finite_and_invertible(kind, name, size):
    uv = _sample_sets()[name]
    warp = W.build_notw(uv, size) if kind == "notw" else W.build_rtw(uv, size)
    assert np.all(np.isfinite(warp.rows)) and np.all(np.isfinite(warp.cols))
    grid = np.linspace(0.0, 1.0, 97)
    u, v = np.meshgrid(grid, grid, indexing="xy")
    warped = warp.forward(np.stack([u, v], -1))
    assert np.all(np.isfinite(warped))
    # Monotone: u' increases along u at fixed v.
    assert np.all(np.diff(warped[..., 0], axis=1) > 0)
    # v' increases along v at fixed u' (columns are indexed by the warped u).
    for column in np.linspace(0.01, 0.99, 13):
        vv = W.family_offset(warp.cols, grid, np.full_like(grid, column)) + grid
        assert np.all(np.diff(vv) > 0)
    # Fold-free: the Jacobian determinant of the 2D map is positive everywhere.
    h = 1e-6
    pts = np.random.default_rng(3).uniform(0.001, 0.999, (4000, 2))
    du = (warp.forward(pts + [h, 0]) - warp.forward(pts - [h, 0])) / (2 * h)
    dv = (warp.forward(pts + [0, h]) - warp.forward(pts - [0, h])) / (2 * h)
    det = du[:, 0] * dv[:, 1] - du[:, 1] * dv[:, 0]
    assert det.min() > 0
    su, sv = warp.slopes(pts)
    # Away from cell borders the analytic Jacobian matches finite differences, and its
    # determinant is the product of the two 1D slopes (triangular structure of eq. 4.9).
    jac = warp.jacobian(pts)
    fd = np.stack([du, dv], axis=-1)
    smooth = np.all(np.abs(jac - fd) < 1e-3, axis=(1, 2))
    assert smooth.mean() > 0.8
    assert np.allclose(np.linalg.det(jac), su * sv, rtol=1e-9)
    assert np.all(su >= W.FLOOR_SHARE * (1 - 1e-9)) and np.all(sv >= W.FLOOR_SHARE * (1 - 1e-9))
    # The corners stay put, and the inverse is exact.
    corners = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    assert np.allclose(warp.forward(corners), corners, atol=1e-12)
    assert np.allclose(warp.inverse(warp.forward(pts)), pts, atol=1e-9)


def test_warp_is_continuous_across_row_borders():
    """Offsets are interpolated between row centres: no jump at i = floor(v * A)."""
    uv = _sample_sets()["two_clusters"]
    warp = W.build_notw(uv, 32)
    u = np.linspace(0, 1, 50)
    for border in np.arange(1, 32) / 32:
        below = warp.forward(np.column_stack([u, np.full(50, border - 1e-9)]))
        above = warp.forward(np.column_stack([u, np.full(50, border + 1e-9)]))
        assert np.abs(below - above).max() < 1e-6


def test_notw_evens_out_the_count_map():
    """Clustered samples: the count after the warp is far lower at the peak."""
    uv = _sample_sets()["cluster"]
    before = W.scatter_counts(uv, 64)
    after = W.scatter_counts(W.build_notw(uv, 64).forward(uv), 64)
    assert after.max() < 0.5 * before.max()
    assert np.count_nonzero(after) > 2 * np.count_nonzero(before)


def test_scatter_counts_and_dv_crop():
    uv = np.array([[0.1, 0.2], [0.1, 0.2], [0.7, 0.4], [1.0, 0.5], [np.nan, 0.3]])
    counts = W.scatter_counts(uv, 10)
    assert counts.sum() == 3 and counts[2, 1] == 2 and counts[4, 7] == 1  # row = v
    lo, hi = W.dv_crop_from_counts(counts, margin_texels=0.0)
    assert np.allclose(lo, [0.1, 0.2]) and np.allclose(hi, [0.8, 0.5])
    assert np.array_equal(W.dv_crop_from_counts(np.zeros((4, 4)))[1], [1.0, 1.0])


def test_layer_mapping_round_trip():
    uv = _sample_sets()["cluster"]
    mapping = W.LayerMapping(np.array([0.2, 0.6]), np.array([0.4, 0.8]), W.build_notw((uv - [0.2, 0.6]) / 0.2, 32))
    xy = np.random.default_rng(5).uniform(-0.55, -0.25, (500, 2)) + [0.0, 0.8]
    assert np.allclose(mapping.inverse(mapping.forward(xy)), xy, atol=1e-9)
    assert W.LayerMapping.identity().is_identity and not mapping.is_identity


@settings(max_examples=80, deadline=None)
@given(count_maps(st.sampled_from([2, 8, 32, 64])))
def test_notw_and_rtw_families_from_any_count_map(counts):
    """The full row construction (blur, floor, clamp, automatic smoothing) and RTW keep
    every guarantee for random, empty, one-texel and extreme maps."""
    rows, window = W.notw_rows(counts)
    _check_family(rows, W.FLOOR_SHARE, W.MAX_SLOPE)
    assert 0 <= window <= counts.shape[0]
    cols, _ = W.notw_cols(counts)
    _check_family(cols, W.FLOOR_SHARE, W.MAX_SLOPE)
    rtw = W.rtw_from_counts(counts)
    _check_family(rtw.rows, W.FLOOR_SHARE, W.MAX_SLOPE)
    _check_family(rtw.cols, W.FLOOR_SHARE, W.MAX_SLOPE)


def test_subnormal_counts_give_a_finite_warp():
    """Regression (hypothesis found it): one subnormal count made the smoothing prior
    underflow to 0 and empty rows 0 / 0."""
    counts = np.array([[0.0, 0.0], [0.0, 5e-324]])
    rows, _ = W.notw_rows(counts)
    _check_family(rows, W.FLOOR_SHARE, W.MAX_SLOPE)
    assert np.all(np.isfinite(W.rtw_from_counts(counts).rows))


@pytest.mark.parametrize("window", [1, 2])
def test_smoothing_subnormal_totals_stays_monotone(window):
    """Regression (hypothesis found it): with a single subnormal count, offsets * totals
    lost its digits and the smoothed row fell by 3 per cell."""
    counts = np.zeros((4, 4))
    counts[0, 0] = 5e-324
    offsets = W.offsets_from_counts(counts)
    smooth = W.smooth_offsets(offsets, counts.sum(axis=1), window)
    _check_family(smooth, W.FLOOR_SHARE, W.MAX_SLOPE)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=4, max_size=4))
def test_closed_form_singular_values_match_svd(entries):
    m = np.array(entries, dtype=np.float64).reshape(2, 2)
    big, small = W.singular_values_2x2(m[None])
    expected = np.linalg.svd(m, compute_uv=False)
    scale = max(expected[0], 1e-300)
    assert abs(big[0] - expected[0]) <= 1e-9 * scale
    # The smaller one loses digits to cancellation when the matrix is nearly singular.
    assert abs(small[0] - expected[1]) <= 1e-6 * scale


def test_texel_reach_of_plain_and_stretched_maps():
    """A plain map's texel spans one texel in every direction (the isotropic cap);
    a map stretched 2x along u spans half a plain texel along u and stays at the cap
    (1 / sigma_min = 2) along a v it compresses."""
    angles = np.linspace(0.0, 2.0 * np.pi, 17)
    dirs = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    assert np.allclose(W.texel_reach(np.broadcast_to(np.eye(2), (17, 2, 2)), dirs), 1.0)
    stretched = np.broadcast_to(np.diag([2.0, 0.5]), (2, 2, 2))
    assert np.allclose(W.texel_reach(stretched, np.array([[1.0, 0.0], [0.0, 1.0]])), [0.5, 2.0])
    # Shear: J = [[1, s], [0, 1]] moves u with v; along u the preimage is wider than 1.
    sheared = np.array([[1.0, 0.5], [0.0, 1.0]])
    _, smallest = W.singular_values_2x2(sheared)
    assert np.isclose(W.texel_reach(sheared, np.array([1.0, 0.0])), min(1.5, 1.0 / smallest))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-4.0, 4.0, allow_nan=False), min_size=4, max_size=4), st.floats(0.0, 2.0 * np.pi))
def test_texel_reach_lies_between_the_euclidean_preimage_and_the_cap(entries, angle):
    """||J^-T g||_2 <= reach <= 1 / sigma_min for every invertible J and unit g."""
    m = np.array(entries, dtype=np.float64).reshape(2, 2)
    assume(abs(np.linalg.det(m)) >= 1e-3)
    g = np.array([np.cos(angle), np.sin(angle)])
    reach = float(W.texel_reach(m, g))
    cap = 1.0 / np.linalg.svd(m, compute_uv=False)[1]
    euclid = float(np.linalg.norm(np.linalg.solve(m.T, g)))
    assert reach <= cap * (1 + 1e-6)
    assert reach >= min(euclid, cap) * (1 - 1e-6)
