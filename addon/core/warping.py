"""Texture warps: NoTW (thesis 4.2, Algorithm 3, eq. 4.4-4.9) and RTW (Rosen 2012).

Coordinates are map uv in [0, 1]^2 of one layer, after the DV crop. A warp is two
families of 1D offset functions stored on a grid of A rows x (A + 1) nodes:

  rows[i, k]  offset o_x at node u_k = k / A of row i (row centre v_i = (i + 0.5) / A)
  cols[j, k]  offset o_y at node v_k = k / A of column j (centre u'_j = (j + 0.5) / A,
              indexed by the row-warped u', as in eq. 4.9)

  warp(u, v) = (u' , v') with u' = u + o_x(u; v) and v' = v + o_y(v; u')

Between nodes and between row (column) centres the offsets are interpolated
linearly, so the warp is continuous everywhere. Every stored 1D function is
strictly increasing (density floor), hence u' is increasing in u, v' increasing
in v, and the Jacobian determinant (du'/du)(dv'/dv) is positive: no fold.
Outside [0, 1] the offset is 0 (nodes 0 and A hold 0), so geometry beyond the
map edge stays continuous with it.

The GLSL in gpu_shaders/lib/warp.glsl evaluates the same functions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError

# Rules for the automatic parameters (docs/warping.md explains them).
FLOOR_SHARE = 0.1  # uniform share mixed into every row's density: slope >= FLOOR_SHARE
MAX_SLOPE = 8.0  # one cell may grow to at most this many cells (steepness clamp)
SHEAR_LIMIT = 0.5  # largest |du'/dv| (resp. |dv'/du'|) the smoothing may leave (docs/warping.md)
IDENTITY_PRIOR = 0.02  # pseudo-count (share of the mean populated row) pulling sparse rows to identity
# Count-map cells the DV crop grows by on each side (dv_crop_from_counts).
CROP_MARGIN = 2.0
ALONG_BLUR_SHARE = 1 / 32  # tent half-width along each row, as a share of A (smooths kinks)


@dataclass(frozen=True)
class WarpParams:
    """Parameters of one 1D-family construction, as chosen for the row and column passes."""

    floor: float
    max_slope: float
    row_window: int
    col_window: int


@dataclass
class Warp:
    """A NoTW or RTW warp of one layer (or the identity)."""

    rows: np.ndarray  # (A, A + 1) float64
    cols: np.ndarray  # (A, A + 1) float64
    params: WarpParams | None = None
    kind: str = "notw"

    @property
    def size(self) -> int:
        return self.rows.shape[0]

    @staticmethod
    def identity(size: int) -> "Warp":
        z = np.zeros((size, size + 1))
        return Warp(z, z.copy(), None, "identity")

    def forward(self, uv: np.ndarray) -> np.ndarray:
        """Warp map points (..., 2)."""
        uv = np.asarray(uv, dtype=np.float64)
        u2 = uv[..., 0] + family_offset(self.rows, uv[..., 0], uv[..., 1])
        v2 = uv[..., 1] + family_offset(self.cols, uv[..., 1], u2)
        return np.stack([u2, v2], axis=-1)

    def inverse(self, uv_warped: np.ndarray) -> np.ndarray:
        """Unwarp map points (..., 2): the exact inverse of `forward` inside [0, 1]^2."""
        w = np.asarray(uv_warped, dtype=np.float64)
        v = family_inverse(self.cols, w[..., 1], w[..., 0])
        u = family_inverse(self.rows, w[..., 0], v)
        return np.stack([u, v], axis=-1)

    def jacobian(self, uv: np.ndarray) -> np.ndarray:
        """(..., 2, 2) d(u', v')/d(u, v): rows (du', dv'), columns (d/du, d/dv)."""
        uv = np.asarray(uv, dtype=np.float64)
        u, v = uv[..., 0], uv[..., 1]
        u2 = u + family_offset(self.rows, u, v)
        du_du = 1.0 + family_slope(self.rows, u, v)
        du_dv = family_shear(self.rows, u, v)
        dv_dv_fixed = 1.0 + family_slope(self.cols, v, u2)
        shear_v = family_shear(self.cols, v, u2)
        return np.stack([np.stack([du_du, du_dv], -1),
                         np.stack([shear_v * du_du, dv_dv_fixed + shear_v * du_dv], -1)], -2)

    def slopes(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """du'/du and dv'/dv (at fixed u') at map points: the local magnifications."""
        uv = np.asarray(uv, dtype=np.float64)
        u2 = uv[..., 0] + family_offset(self.rows, uv[..., 0], uv[..., 1])
        return (1.0 + family_slope(self.rows, uv[..., 0], uv[..., 1]),
                1.0 + family_slope(self.cols, uv[..., 1], u2))


def singular_values_2x2(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest and smallest singular values of (..., 2, 2) matrices, in closed form.

    From the eigenvalues of M^T M: mean +- sqrt(((a - c) / 2)^2 + b^2), with a, c the
    squared column norms and b their dot product (as `ow_min_singular` in GLSL).
    Much faster than np.linalg.svd on many small matrices.
    """
    m = np.asarray(m, dtype=np.float64)
    # Scaled to a largest entry of 1 first, so squaring neither under- nor overflows.
    peak = np.abs(m).max(axis=(-2, -1))
    scale = np.where(peak > 0.0, peak, 1.0)
    m = m / scale[..., None, None]
    col0, col1 = m[..., :, 0], m[..., :, 1]
    a = np.einsum("...i,...i->...", col0, col0)
    c = np.einsum("...i,...i->...", col1, col1)
    b = np.einsum("...i,...i->...", col0, col1)
    mean = 0.5 * (a + c)
    spread = np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return scale * np.sqrt(mean + spread), scale * np.sqrt(np.maximum(mean - spread, 0.0))


def texel_reach(jacobian: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Plain-map texels one map texel spans along unit plain-map directions (as `ow_texel_reach`).

    jacobian: (..., 2, 2) d(map uv)/d(plain uv); direction: (..., 2) unit vectors g.
    The width of the texel's preimage J^-1 S (S the unit square) along g is
    ||J^-T g||_1; it is capped at 1/sigma_min, the isotropic reach. The shadow test
    scales its normal offset and slope bias by it (docs/warping.md).
    """
    jacobian = np.asarray(jacobian, dtype=np.float64)
    direction = np.asarray(direction, dtype=np.float64)
    _, smallest = singular_values_2x2(jacobian)
    cap = 1.0 / np.maximum(smallest, 1e-30)
    pre = np.linalg.solve(np.swapaxes(jacobian, -1, -2), direction[..., None])[..., 0]
    return np.minimum(np.abs(pre).sum(axis=-1), cap)


# ---------------------------------------------------------------------------
# evaluation of one family (shared by rows and columns)
# ---------------------------------------------------------------------------
def _blend_rows(table: np.ndarray, across: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices of the two neighbouring function centres and the blend weight."""
    size = table.shape[0]
    t = np.asarray(across, dtype=np.float64) * size - 0.5
    t = np.where(np.isfinite(t), t, 0.0)
    # Past the end centres both indices are the end row, so the weight is moot there.
    np.clip(t, 0.0, size - 1.0, out=t)
    i0 = t.astype(np.int64)  # t >= 0, so truncation is floor
    return i0, np.minimum(i0 + 1, size - 1), t - i0


def _node(along: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    s = np.asarray(along, dtype=np.float64) * size
    s = np.where(np.isfinite(s), s, 0.0)
    np.clip(s, 0.0, float(size), out=s)
    k = np.minimum(s.astype(np.int64), size - 1)
    return k, s - k


def _bracket(table: np.ndarray, along: np.ndarray, across: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two neighbouring functions' offsets at `along` and the blend weight between them."""
    i0, i1, f = _blend_rows(table, across)
    k, s = _node(along, table.shape[0])
    # Gathers from the flat table: one index array each, much cheaper than 2D fancy indexing.
    flat = table.ravel()
    at0 = i0 * table.shape[1] + k
    at1 = i1 * table.shape[1] + k
    o0 = flat[at0] * (1 - s) + flat[at0 + 1] * s
    o1 = flat[at1] * (1 - s) + flat[at1 + 1] * s
    return o0, o1, f


def family_offset(table: np.ndarray, along: np.ndarray, across: np.ndarray) -> np.ndarray:
    """Offset of the function family `table` at position `along`, interpolated `across`."""
    o0, o1, f = _bracket(table, along, across)
    return o0 * (1 - f) + o1 * f


def family_slope(table: np.ndarray, along: np.ndarray, across: np.ndarray) -> np.ndarray:
    """d(offset)/d(along) inside the current cell (0 outside [0, 1])."""
    size = table.shape[0]
    i0, i1, f = _blend_rows(table, across)
    k, _ = _node(along, size)
    d0 = table[i0, k + 1] - table[i0, k]
    d1 = table[i1, k + 1] - table[i1, k]
    a = np.asarray(along, dtype=np.float64)
    inside = (a >= 0.0) & (a <= 1.0)
    return np.where(inside, (d0 * (1 - f) + d1 * f) * size, 0.0)


def family_shear(table: np.ndarray, along: np.ndarray, across: np.ndarray) -> np.ndarray:
    """d(offset)/d(across): how fast neighbouring functions differ (0 beyond the end centres)."""
    size = table.shape[0]
    o0, o1, _ = _bracket(table, along, across)
    t = np.asarray(across, dtype=np.float64) * size - 0.5
    blending = (t > 0.0) & (t < size - 1)
    return np.where(blending, (o1 - o0) * size, 0.0)


def family_inverse(table: np.ndarray, warped: np.ndarray, across: np.ndarray) -> np.ndarray:
    """Solve x + o(x; across) = warped for x by binary search over the nodes.

    The blended function is piecewise linear on the same nodes and increasing, so
    the search finds the cell, and one division inverts it exactly.
    """
    size = table.shape[0]
    w = np.asarray(warped, dtype=np.float64)
    i0, i1, f = _blend_rows(table, across)

    def node_value(k):
        return k / size + table[i0, k] * (1 - f) + table[i1, k] * f

    lo = np.zeros(w.shape, dtype=np.int64)
    hi = np.full(w.shape, size, dtype=np.int64)
    for _ in range(int(math.ceil(math.log2(size))) + 1):
        mid = (lo + hi) // 2
        go_right = node_value(mid) <= w
        lo = np.where(go_right & (mid < hi), mid, lo)
        hi = np.where(go_right, hi, mid)
    k = np.clip(lo, 0, size - 1)
    x0, x1 = node_value(k), node_value(k + 1)
    frac = (w - x0) / np.maximum(x1 - x0, 1e-300)
    inside = (k + frac) / size
    # Outside [0, 1] the warp is the identity.
    return np.where(w < 0.0, w, np.where(w > 1.0, w, inside))


# ---------------------------------------------------------------------------
# construction
# ---------------------------------------------------------------------------
def scatter_counts(uv: np.ndarray, size: int, weights: np.ndarray | None = None) -> np.ndarray:
    """Count map (size x size, row = v) of map points; points outside [0,1)^2 are dropped.

    The numpy oracle of the GPU scatter pass. `weights` (one per point) are summed
    instead of counting each point once, as the weighted scatter does.
    """
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    ok = np.all(np.isfinite(uv), axis=1) & np.all((uv >= 0.0) & (uv < 1.0), axis=1)
    idx = np.floor(uv[ok] * size).astype(np.int64)
    flat = np.clip(idx[:, 1], 0, size - 1) * size + np.clip(idx[:, 0], 0, size - 1)
    picked = None if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)[ok]
    return np.bincount(flat, weights=picked, minlength=size * size).reshape(size, size).astype(np.float64)


def _cap_density(p: np.ndarray, cap: float) -> np.ndarray:
    """Clip each row's cell shares at `cap`, scaling the others up so each row still sums to 1.

    Exact water filling: with the shares sorted in descending order and the first m
    cells capped, the rest scale by lambda_m = (1 - m cap) / (sum of the rest); the
    answer is the smallest m whose first uncapped cell stays under the cap.
    """
    p = np.asarray(p, dtype=np.float64)
    rows, size = p.shape
    if cap * size < 1.0:
        raise InputError(f"a cap of {cap} per cell cannot hold a whole row of {size} cells")
    order = np.argsort(-p, axis=1)
    desc = np.take_along_axis(p, order, axis=1)
    tail = np.cumsum(desc[:, ::-1], axis=1)[:, ::-1]  # tail[m] = sum of desc[m:]
    m = np.arange(size)[None, :]
    lam = (1.0 - m * cap) / np.maximum(tail, 1e-300)
    ok = desc * lam <= cap * (1 + 1e-12)
    first = np.argmax(ok, axis=1)  # smallest m that fits (m = 0: nothing capped)
    lam_row = lam[np.arange(rows), first][:, None]
    capped = m < first[:, None]
    out_sorted = np.where(capped, cap, np.minimum(desc * lam_row, cap))
    out = np.empty_like(p)
    np.put_along_axis(out, order, out_sorted, axis=1)
    return out


def clean_counts(counts: np.ndarray) -> np.ndarray:
    """Counts as finite, non-negative float64: NaN, inf and negative entries count 0.

    Huge finite counts are scaled down per row, so prefix sums cannot overflow.
    """
    c = np.nan_to_num(np.asarray(counts, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    c = np.maximum(c, 0.0)
    if c.ndim == 2 and c.size:
        peak = c.max(axis=1, keepdims=True)
        c = np.where(peak > 1e100, c / np.where(peak > 0, peak, 1.0), c)
        # The warp depends only on relative counts; lifting a map of subnormal counts
        # keeps the smoothing prior (a share of the mean count) from underflowing to 0,
        # which made 0 / (0 + 0) in empty rows (found by hypothesis: a single 5e-324).
        top = float(c.max())
        if 0.0 < top < 1e-100:
            c = c / top
    return c


def offsets_from_counts(counts: np.ndarray, floor: float = FLOOR_SHARE, max_slope: float = MAX_SLOPE) -> np.ndarray:
    """Offsets o_i(x_k) = g_i(x_k)/N_i - x_k (eq. 4.7) of every row of a count map.

    Each row's density gets a uniform share `floor` mixed in (so the warp is strictly
    increasing with slope >= floor) and is clamped at `max_slope` times uniform. An
    empty row gives the identity (all offsets 0).
    """
    counts = clean_counts(counts)
    rows, size = counts.shape
    if not (0.0 < floor <= 1.0):
        raise InputError(f"warp floor must lie in (0, 1], got {floor}")
    if max_slope < 1.0:
        raise InputError(f"warp steepness clamp must be >= 1, got {max_slope}")
    totals = counts.sum(axis=1, keepdims=True)
    empty = totals[:, 0] <= 0.0
    share = np.where(totals > 0, counts / np.where(totals > 0, totals, 1.0), 1.0 / size)
    share = (1.0 - floor) * share + floor / size
    share = _cap_density(share, max_slope / size)
    cumulative = np.concatenate([np.zeros((rows, 1)), np.cumsum(share, axis=1)], axis=1)
    cumulative /= cumulative[:, -1:]  # exact 1 at the end despite rounding
    offsets = cumulative - np.arange(size + 1)[None, :] / size
    offsets[:, 0] = 0.0
    offsets[:, -1] = 0.0
    offsets[empty] = 0.0
    return offsets


def smooth_offsets(offsets: np.ndarray, totals: np.ndarray, window: int,
                   prior: float | None = None) -> np.ndarray:
    """Count-weighted tent average of neighbouring rows' offsets (thesis 4.2.4, Fig. 4.11).

    Row i becomes sum_j K(i-j) N_j o_j / (sum_j K(i-j) N_j + prior), a convex mix of
    increasing functions and the identity, so it stays increasing with the same
    floor. The prior pulls rows far from any sample smoothly back to the identity.
    K is a tent of half-width `window` rows (two box filters, O(rows) per column).
    """
    offsets = np.asarray(offsets, dtype=np.float64)
    if window <= 0:
        return offsets.copy()
    weighted, weights, prior = _smoothing_terms(offsets, totals, prior)
    num = tent_filter(weighted, window)
    den = tent_filter(weights, window) + prior
    # Where no row nearby holds a count and the prior is 0, the row stays the identity.
    return np.divide(num, den, out=np.zeros_like(num), where=den > 0.0)


def _smoothing_terms(offsets: np.ndarray, totals: np.ndarray,
                     prior: float | None) -> tuple[np.ndarray, np.ndarray, float]:
    """Numerator values N_j o_j, weights N_j and the prior of `smooth_offsets`.

    The mix depends only on relative totals (and a prior in the same units), so they
    are scaled to a peak of 1: subnormal totals lose their digits in offsets * totals,
    which broke monotonicity (hypothesis found a single 5e-324).
    """
    totals = np.asarray(totals, dtype=np.float64).reshape(-1)
    top = float(totals.max()) if totals.size else 0.0
    scale = top if top > 0.0 else 1.0
    totals = totals / scale
    if prior is None:
        populated = totals[totals > 0]
        prior = IDENTITY_PRIOR * float(populated.mean()) if populated.size else 1.0
    else:
        prior = prior / scale
    return offsets * totals[:, None], totals[:, None], prior


def _window_sum(values: np.ndarray, first: int, last: int) -> np.ndarray:
    """out[i] = sum of values[i + first .. i + last] (zero outside), by cumulative sums."""
    n = values.shape[0]
    csum = np.concatenate([np.zeros((1,) + values.shape[1:]), np.cumsum(values, axis=0)])
    upper = np.clip(np.arange(n) + last + 1, 0, n)
    lower = np.clip(np.arange(n) + first, 0, n)
    return csum[upper] - csum[lower]


def tent_filter(values: np.ndarray, window: int) -> np.ndarray:
    """Tent of half-width `window` (weights 1 - |d|/(window+1)) along axis 0, zero padded.

    A forward and a backward box of width n = window + 1 convolve to n - |d|, the
    tent times n, centred; each box costs O(rows) through cumulative sums.
    """
    values = np.asarray(values, dtype=np.float64)
    n = window + 1
    # Pad so the intermediate box sums exist where the tent reaches past the ends.
    pad = np.zeros((window,) + values.shape[1:])
    padded = np.concatenate([pad, values, pad])
    full = _window_sum(_window_sum(padded, 0, n - 1), -(n - 1), 0) / n
    return full[window:window + values.shape[0]]


def max_shear(offsets: np.ndarray) -> float:
    """Largest |d offset / d across| between neighbouring rows, in map units per map unit."""
    if offsets.shape[0] < 2:
        return 0.0
    return float(np.abs(np.diff(offsets, axis=0)).max() * offsets.shape[0])


def box_stretch(scale: float, row_slope: float, row_shear: float, col_slope: float, col_shear: float) -> float:
    """An upper bound of how much a crop of larger scale `scale` and a warp widen a box of
    the plain map (map uv per plain uv, on the box's longer side), as footprint.warp_box
    widens it, from each family's steepest slope and largest shear.

    A plain box of side d is at most s d a side after the crop. The row warp widens it by
    its offsets' steepest slope along the rows and by the shear across them: W <= s d
    (1 + slope_r + shear_r). The column warp then takes the box's height and the new
    width: H <= s d (1 + slope_c) + shear_c W. Bounding the two in turn, not their
    product, keeps more chunks within a point sprite on a warped layer.
    """
    width = scale * (1.0 + row_slope + row_shear)
    height = scale * (1.0 + col_slope) + col_shear * width
    return max(width, height)


def choose_window(offsets: np.ndarray, totals: np.ndarray, shear_limit: float = SHEAR_LIMIT) -> int:
    """Narrowest smoothing half-width (1, 2, 4, ... rows) that brings the shear under the limit.

    Narrow windows keep the warp local (the point of NoTW); the shear bound keeps
    neighbouring rows from sliding past each other so fast that rasterised edges
    and the interpolation between rows stop following the warp.

    The candidates are tried from double prefix sums, built once: each window then
    costs three gathers instead of two box-filter passes (the analysis smooths every
    family of every layer up to seven times). `smooth_offsets` makes the final one.
    """
    offsets = np.asarray(offsets, dtype=np.float64)
    size = offsets.shape[0]
    weighted, weights, prior = _smoothing_terms(offsets, totals, None)
    num_sums = _TentSums(weighted, size // 2)
    den_sums = _TentSums(weights, size // 2)
    window = 1
    while window < size // 2:
        den = den_sums.tent(window) + prior
        smoothed = np.divide(num_sums.tent(window), den, out=np.zeros(offsets.shape), where=den > 0.0)
        if max_shear(smoothed) <= shear_limit:
            return window
        window *= 2
    return window


class _TentSums:
    """Tent filters of one array along axis 0 for any half-width up to `max_window`.

    With P1 and P2 the first and second prefix sums of the zero-padded values, the
    tent of width n = w + 1 (weights n - |d|, as `tent_filter`) at row i is
    (P2[i + n + 1] - 2 P2[i + 1] + P2[i - n + 1]) / n.
    """

    def __init__(self, values: np.ndarray, max_window: int) -> None:
        self.pad = max_window + 1
        self.rows = values.shape[0]
        zeros = np.zeros((self.pad,) + values.shape[1:])
        padded = np.concatenate([zeros, values, zeros])
        first = np.concatenate([np.zeros((1,) + values.shape[1:]), np.cumsum(padded, axis=0)])
        self.second = np.concatenate([np.zeros((1,) + values.shape[1:]), np.cumsum(first, axis=0)])

    def tent(self, window: int) -> np.ndarray:
        n = window + 1
        i = np.arange(self.rows) + self.pad
        p2 = self.second
        return (p2[i + n + 1] - 2.0 * p2[i + 1] + p2[i - n + 1]) / n


def _one_family(counts: np.ndarray, floor: float | None, max_slope: float | None,
                shear_limit: float | None) -> tuple[np.ndarray, int]:
    # None reads the module's rule constants at call time (the study script varies them).
    floor = FLOOR_SHARE if floor is None else floor
    max_slope = MAX_SLOPE if max_slope is None else max_slope
    shear_limit = SHEAR_LIMIT if shear_limit is None else shear_limit
    counts = clean_counts(counts)
    along = int(round(counts.shape[1] * ALONG_BLUR_SHARE))
    if along > 0:
        # Blurring along the row keeps the density, and so the offsets' slope, from
        # changing cell to cell: fewer kinks for rasterised edges to follow. Dividing
        # by the blurred ones keeps a uniform row uniform up to its ends.
        counts = (tent_filter(counts.T, along) / tent_filter(np.ones((counts.shape[1], 1)), along)).T
    offsets = offsets_from_counts(counts, floor, max_slope)
    totals = counts.sum(axis=1)
    if not np.any(totals > 0):
        return offsets, 0
    window = choose_window(offsets, totals, shear_limit)
    return smooth_offsets(offsets, totals, window), window


def notw_rows(counts: np.ndarray, floor: float | None = None, max_slope: float | None = None,
              shear_limit: float | None = None) -> tuple[np.ndarray, int]:
    """Smoothed row offsets of a count map (row = v), and the window chosen."""
    return _one_family(counts, floor, max_slope, shear_limit)


def notw_cols(counts_after_rows: np.ndarray, floor: float | None = None, max_slope: float | None = None,
              shear_limit: float | None = None) -> tuple[np.ndarray, int]:
    """Column offsets from the count map re-scattered through the row warps."""
    return _one_family(np.asarray(counts_after_rows).T, floor, max_slope, shear_limit)


def build_notw(uv: np.ndarray, size: int, floor: float = FLOOR_SHARE, max_slope: float = MAX_SLOPE,
               shear_limit: float = SHEAR_LIMIT) -> Warp:
    """The whole NoTW construction on the CPU (the oracle of the GPU analysis)."""
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    rows, row_window = notw_rows(scatter_counts(uv, size), floor, max_slope, shear_limit)
    u2 = uv[:, 0] + family_offset(rows, uv[:, 0], uv[:, 1])
    cols, col_window = notw_cols(scatter_counts(np.stack([u2, uv[:, 1]], axis=1), size),
                                 floor, max_slope, shear_limit)
    return Warp(rows, cols, WarpParams(floor, max_slope, row_window, col_window), "notw")


def rtw_blur(size: int) -> int:
    """RTW's tent half-width on an A = `size` count map."""
    return max(1, size // 64)


def rtw_from_counts(counts: np.ndarray, floor: float = FLOOR_SHARE, max_slope: float = MAX_SLOPE,
                    blur: int | None = None) -> Warp:
    """RTW: importance collapsed to the max of each column and each row, tent-blurred,
    prefix-summed into two 1D warps shared by all rows and all columns (Rosen 2012)."""
    counts = clean_counts(counts)
    size = counts.shape[0]
    blur = rtw_blur(size) if blur is None else blur
    along_u = tent_filter(counts.max(axis=0)[:, None], blur)[:, 0]  # importance per column -> warps u
    along_v = tent_filter(counts.max(axis=1)[:, None], blur)[:, 0]
    row_fn = offsets_from_counts(along_u[None, :], floor, max_slope)[0]
    col_fn = offsets_from_counts(along_v[None, :], floor, max_slope)[0]
    rows = np.tile(row_fn, (size, 1))
    cols = np.tile(col_fn, (size, 1))
    return Warp(rows, cols, WarpParams(floor, max_slope, blur, blur), "rtw")


def build_rtw(uv: np.ndarray, size: int, floor: float = FLOOR_SHARE, max_slope: float = MAX_SLOPE) -> Warp:
    """RTW from map points (the CPU oracle)."""
    return rtw_from_counts(scatter_counts(uv, size), floor, max_slope)


@dataclass
class LayerMapping:
    """Map transform of one layer: projection xy -> DV crop -> warp -> map uv in [0, 1]^2."""

    lo: np.ndarray  # crop box in uncropped uv
    hi: np.ndarray
    warp: Warp | None = None

    @staticmethod
    def identity() -> "LayerMapping":
        return LayerMapping(np.zeros(2), np.ones(2), None)

    @property
    def scale(self) -> np.ndarray:
        return 1.0 / (self.hi - self.lo)

    @property
    def is_identity(self) -> bool:
        return self.warp is None and bool(np.all(self.lo == 0.0) and np.all(self.hi == 1.0))

    def crop_vec4(self) -> tuple[float, float, float, float]:
        """(lo.x, lo.y, scale.x, scale.y) as the GLSL `crop` uniform wants it."""
        s = self.scale
        return float(self.lo[0]), float(self.lo[1]), float(s[0]), float(s[1])

    def forward(self, xy: np.ndarray) -> np.ndarray:
        """Projection coordinates (..., 2) in [-1, 1] to final map uv (..., 2)."""
        uv = (np.asarray(xy, dtype=np.float64) * 0.5 + 0.5 - self.lo) * self.scale
        return self.warp.forward(uv) if self.warp is not None else uv

    def magnification(self, xy: np.ndarray) -> np.ndarray:
        """Smallest singular value of d(map uv)/d(uncropped uv) at projection points xy.

        A map texel's preimage spans at most 1/magnification plain-map texels in any
        direction; the shadow test scales its bias footprint by it.
        """
        return singular_values_2x2(self.jacobian(xy))[1]

    def jacobian(self, xy: np.ndarray) -> np.ndarray:
        """d(map uv)/d(uncropped uv) at projection points xy, (..., 2, 2): crop, then warp."""
        xy = np.asarray(xy, dtype=np.float64)
        crop = np.zeros(xy.shape[:-1] + (2, 2))
        crop[..., 0, 0], crop[..., 1, 1] = self.scale
        if self.warp is None:
            return crop
        uv = (xy * 0.5 + 0.5 - self.lo) * self.scale
        return self.warp.jacobian(uv) @ crop

    def reach(self, xy: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """Plain-map texels a map texel spans along unit directions at xy (`texel_reach`)."""
        return texel_reach(self.jacobian(xy), direction)

    def inverse(self, uv: np.ndarray) -> np.ndarray:
        """Final map uv back to projection coordinates."""
        uv = np.asarray(uv, dtype=np.float64)
        if self.warp is not None:
            uv = self.warp.inverse(uv)
        return (self.lo + uv / self.scale) * 2.0 - 1.0


def dv_crop_from_counts(counts: np.ndarray, margin_texels: float = CROP_MARGIN) -> tuple[np.ndarray, np.ndarray]:
    """DV crop from a count map (row = v): first/last occupied column and row, grown by a margin.

    The margin (in count-map texels) covers the shadow test's normal offset, which moves
    a sample's lookup slightly. An empty map keeps the whole map.
    """
    counts = np.asarray(counts)
    cols = np.nonzero(counts.sum(axis=0) > 0)[0]
    rows = np.nonzero(counts.sum(axis=1) > 0)[0]
    bounds = None if cols.size == 0 else (int(cols[0]), int(cols[-1]), int(rows[0]), int(rows[-1]))
    return dv_crop_from_bounds(bounds, counts.shape[0], margin_texels)


def dv_crop_from_bounds(bounds: tuple[int, int, int, int] | None, size: int,
                        margin_texels: float = CROP_MARGIN) -> tuple[np.ndarray, np.ndarray]:
    """DV crop from the first and last occupied column and row (col_lo, col_hi, row_lo,
    row_hi) of a size x size count map, as the GPU reduces them; None: an empty map."""
    if bounds is None:
        return np.zeros(2), np.ones(2)
    col_lo, col_hi, row_lo, row_hi = bounds
    lo = np.array([col_lo, row_lo], dtype=np.float64) - margin_texels
    hi = np.array([col_hi + 1, row_hi + 1], dtype=np.float64) + margin_texels
    return np.clip(lo / size, 0.0, 1.0), np.clip(hi / size, 0.0, 1.0)
