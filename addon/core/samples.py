"""What planning needs from a frame's view samples, as a few numbers (`SampleStats`).

Planning (core.plan) never reads the samples themselves. It needs their count, the
image rectangle that holds them, their view-depth range (strict, and cut at a
percentile for layer culling), their world box and the layer slots they fall into.

The GPU reduces the uploaded sample texture to these numbers in three dispatches
(gpu_shaders/sample_stats.comp) and one read of STAT_COUNT integers: pass 0 the
integers of STAT_FIELDS, pass 1 a histogram of the view depths over the range pass 0
left in the image, pass 2 the bins of the percentile cut (`cut_bins`), written beside
the fields. `measure` is the numpy oracle: it computes the same numbers from arrays,
through the same histogram.

Two things keep the GPU's numbers conservative:
- it reads float32 light-centred positions, so its depth range and box are grown by
  ROUNDING of the coordinates' size (their float32 rounding is below 2^-23 of it);
- the percentile cut comes from the histogram: the low cut is the lower edge of the
  bin before the one holding the low percentile's sample, the high cut the upper
  edge of the bin after the other's, so a sample rounded into a neighbouring bin
  cannot narrow it. The cut only ever widens the exact percentile range.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .frames import pick_slot
from .projection import finite_points
from .scene import CameraSpec, LightSpec

# Screen window of a frustum: (x0, x1, y0, y1) in normalised device coordinates,
# (-1, 1, -1, 1) being the whole camera frame.
Window = tuple[float, float, float, float]
FULL_WINDOW: Window = (-1.0, 1.0, -1.0, 1.0)

# Layer culling cuts the view frustum at these depth percentiles (docs/culling.md).
CULL_DEPTH_PERCENTILE = 0.5
# Bins of the depth histogram the percentile cut is read from: log-spaced for a
# perspective camera (a bin is then about 0.14 % of the depth for a 1:100 range).
HIST_BINS = 1024
# The percentile is taken in steps of 1/CUT_STEPS of a percent, so that its sample ranks
# are integers that the GPU computes exactly (cut_ranks).
CUT_STEPS = 10
# Samples one GPU invocation reduces in registers before its atomics.
STAT_SPAN = 16
# Relative growth of the GPU's depth range and box for float32 rounding.
ROUNDING = 2.0 ** -20

# The integers of pass 0, in this order, at texels 0.. of the reduction image; the
# histogram follows at STAT_COUNT. Every field of pass 0 but `count` (a sum) and the two
# slot masks (bitwise or) is a maximum: a minimum is stored as the maximum of its
# complement, so that the image starts from zeros. Floats are stored order-preserving.
# Pass 2 stores the last three: the histogram bins of the percentile cut's low and high
# samples and whether the bins are log-spaced, each plus 1 (0: no histogram was taken).
STAT_FIELDS = ("count", "col_lo", "col_hi", "row_lo", "row_hi", "depth_lo", "depth_hi",
               "x_lo", "y_lo", "z_lo", "x_hi", "y_hi", "z_hi", "reach", "sides", "faces",
               "cut_lo", "cut_hi", "cut_log")
STAT_COUNT = len(STAT_FIELDS)
# Pass 2 is one work group of CUT_CHUNKS invocations, each summing HIST_BINS / CUT_CHUNKS
# bins into a texel after the histogram, so that no invocation walks the whole histogram.
CUT_CHUNKS = 64
STAT_TEXELS = STAT_COUNT + HIST_BINS + CUT_CHUNKS


@dataclass(frozen=True)
class SampleStats:
    """A frame's view samples as planning sees them. Depths and box are None without a
    sample (depths also without a camera)."""

    count: int
    window: Window  # frame rectangle holding every sample, grown by a pixel
    depth: tuple[float, float] | None  # strict view-depth range
    cull_depth: tuple[float, float] | None  # the percentile cut, never narrower than exact
    box: tuple[np.ndarray, np.ndarray] | None  # world box holding every sample
    sides: frozenset[int]  # dual-paraboloid (and unfold) slots with a sample in the emission
    faces: frozenset[int]  # cube faces with a sample in the emission

    def occupied(self, parameterization: str) -> set[int]:
        """Slots of `parameterization` that some sample in the emission domain falls into."""
        return set(self.faces if parameterization == "cube" else self.sides)

    def reach(self) -> float:
        """The largest absolute world coordinate of the box (0 without samples)."""
        return 0.0 if self.box is None else float(max(np.abs(self.box[0]).max(), np.abs(self.box[1]).max()))


def depth_axis(camera: CameraSpec, light: LightSpec) -> tuple[np.ndarray, float]:
    """(axis, offset): a light-centred point p has view depth p . axis + offset."""
    m = np.asarray(camera.matrix_world, dtype=np.float64)
    axis = -m[:3, 2]
    return axis, float((light.position - m[:3, 3]) @ axis)


def log_bins(camera: CameraSpec, depth: tuple[float, float]) -> bool:
    """Whether the histogram is log-spaced: for a perspective view in front of the camera."""
    return (not camera.ortho) and depth[0] > 0.0


def bin_edge(index: np.ndarray | int, depth: tuple[float, float], log: bool) -> np.ndarray:
    """Depth at the lower edge of histogram bin `index` (HIST_BINS: the upper end)."""
    t = np.asarray(index, dtype=np.float64) / HIST_BINS
    lo, hi = depth
    return lo * (hi / lo) ** t if log else lo + (hi - lo) * t


def depth_bins(depths: np.ndarray, depth: tuple[float, float], log: bool) -> np.ndarray:
    """Histogram bin of each depth; the GLSL pass 1 uses the same formula."""
    lo, hi = depth
    d = np.asarray(depths, dtype=np.float64)
    if hi <= lo:
        return np.zeros(d.shape, dtype=np.int64)
    t = np.log(np.maximum(d, lo) / lo) / math.log(hi / lo) if log else (d - lo) / (hi - lo)
    return np.clip(np.floor(t * HIST_BINS), 0, HIST_BINS - 1).astype(np.int64)


def cut_ranks(n: int, percentile: float) -> tuple[int, int]:
    """The 0-based ranks of the sorted samples that bound the cut at `percentile` and
    100 - `percentile` of `n` samples: np.percentile interpolates between ranks floor(r)
    and ceil(r), r = p (n - 1), so the cut holds both. Integer arithmetic, as on the GPU
    (sample_stats.comp): the percentile in steps of 1/CUT_STEPS of a percent."""
    steps = 100 * CUT_STEPS
    q = int(round(percentile * CUT_STEPS))
    if not math.isclose(q, percentile * CUT_STEPS, abs_tol=1e-9) or not 0 <= q <= steps // 2:
        raise InputError(f"the culling percentile must be a multiple of {1 / CUT_STEPS} in [0, 50], "
                         f"got {percentile}")
    last = n - 1
    return last * q // steps, -(-last * (steps - q) // steps)


def cut_bins(hist: np.ndarray, percentile: float = CULL_DEPTH_PERCENTILE) -> tuple[int, int] | None:
    """The histogram bins holding the cut's low and high samples (cut_ranks); None for an
    empty histogram or a percentile of 0 (no cut)."""
    hist = np.asarray(hist, dtype=np.int64)
    n = int(hist.sum())
    if percentile <= 0.0 or n == 0:
        return None
    k_lo, k_hi = cut_ranks(n, percentile)
    cumulative = np.cumsum(hist)
    return int(np.searchsorted(cumulative, k_lo + 1)), int(np.searchsorted(cumulative, k_hi + 1))


def cut_range(bins: tuple[int, int] | None, depth: tuple[float, float], log: bool) -> tuple[float, float]:
    """The depth range of the cut's bins, widened by one bin each way (module docstring),
    within the strict range; the strict range without bins."""
    if bins is None:
        return depth
    low = float(bin_edge(max(bins[0] - 1, 0), depth, log))
    high = float(bin_edge(min(bins[1] + 2, HIST_BINS), depth, log))
    return max(low, depth[0]), min(high, depth[1])


def percentile_cut(hist: np.ndarray, depth: tuple[float, float], log: bool,
                   percentile: float = CULL_DEPTH_PERCENTILE) -> tuple[float, float]:
    """The depth range at `percentile` and 100 - `percentile` from a histogram, widened
    by one bin each way (module docstring); the strict range when `percentile` is 0."""
    return cut_range(cut_bins(hist, percentile), depth, log)


def sample_window(camera: CameraSpec | None, rows: tuple[int, int] | None, cols: tuple[int, int] | None,
                  shape: tuple[int, int]) -> Window:
    """The frame rectangle holding the sample pixels from rows[0]..rows[1] (row 0 at the
    top of the image) and cols[0]..cols[1], grown by one pixel.

    The truncated frustum is cut at the samples' depths, and also at the sides of the
    image that see only sky: a view sample lies on a ray through its own pixel (with a
    reconstruction filter, within a pixel of it), so the frustum through this rectangle
    still holds every sample. The whole frame when the samples are not an (H, W) image
    of the camera, or hold no sample.
    """
    if camera is None or rows is None or cols is None or tuple(shape) != tuple(camera.resolution[::-1]):
        return FULL_WINDOW
    height, width = shape
    x0 = 2.0 * (cols[0] - 1) / width - 1.0
    x1 = 2.0 * (cols[1] + 2) / width - 1.0
    y0 = 1.0 - 2.0 * (rows[1] + 2) / height
    y1 = 1.0 - 2.0 * (rows[0] - 1) / height
    return (max(x0, -1.0), min(x1, 1.0), max(y0, -1.0), min(y1, 1.0))


def slot_masks(light: LightSpec, offsets: np.ndarray) -> tuple[frozenset[int], frozenset[int]]:
    """(dual-paraboloid sides, cube faces) holding some light-centred offset (N, 3) of
    the emission domain; the same rule as pass 0 and the shadow test's layer choice."""
    local = np.asarray(offsets, dtype=np.float64) @ light.rotation  # world -> light local
    if light.emission == "hemi":
        local = local[local[:, 2] < 0.0]
    sides = frozenset(int(s) for s in np.unique(pick_slot("dpsm", local)))
    faces = frozenset(int(s) for s in np.unique(pick_slot("cube", local)))
    return sides, faces


def measure(camera: CameraSpec | None, light: LightSpec | None, positions: np.ndarray, hit: np.ndarray,
            percentile: float = CULL_DEPTH_PERCENTILE) -> SampleStats:
    """The statistics of world `positions` (..., 3) where `hit` holds and they are finite.

    With an (H, W) image of the camera the window is the samples' rectangle, with any
    other shape the whole frame. Without a light no slot counts as occupied.
    """
    pts = np.asarray(positions, dtype=np.float64)
    mask = np.asarray(hit, dtype=bool) & finite_points(pts)
    points = pts[mask]
    rows = cols = None
    if mask.ndim == 2 and mask.any():
        r, c = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
        rows, cols = (int(r[0]), int(r[-1])), (int(c[0]), int(c[-1]))
    window = sample_window(camera, rows, cols, mask.shape)
    if len(points) == 0:
        return SampleStats(0, window, None, None, None, frozenset(), frozenset())
    # Column by column: numpy reduces an (N, 3) array along axis 0 some 20 times slower.
    box = (np.array([points[:, k].min() for k in range(3)]), np.array([points[:, k].max() for k in range(3)]))
    sides, faces = slot_masks(light, points - light.position) if light is not None else (frozenset(), frozenset())
    depth = cull = None
    if camera is not None:
        depths = camera.view_depths(points)
        depth = (float(depths.min()), float(depths.max()))
        log = log_bins(camera, depth)
        hist = np.bincount(depth_bins(depths, depth, log), minlength=HIST_BINS)
        cull = percentile_cut(hist, depth, log, percentile)
    return SampleStats(len(points), window, depth, cull, box, sides, faces)


def _unordered(values: np.ndarray) -> np.ndarray:
    """float32 values from their order-preserving uint32 keys (the inverse of ow_ordered)."""
    u = np.asarray(values, dtype=np.uint32)
    bits = np.where(u & np.uint32(0x80000000), u & np.uint32(0x7FFFFFFF), ~u)
    return bits.astype(np.uint32).view(np.float32).astype(np.float64)


def _bits(mask: int) -> frozenset[int]:
    return frozenset(slot for slot in range(6) if mask >> slot & 1)


@dataclass(frozen=True)
class Reduction:
    """The reduction image's fields decoded: pass 0's integers and pass 2's cut."""

    count: int
    rows: tuple[int, int] | None  # top-down image rows
    cols: tuple[int, int] | None
    depth: tuple[float, float] | None  # grown by rounding
    box: tuple[np.ndarray, np.ndarray] | None  # world, grown by rounding
    sides: frozenset[int]
    faces: frozenset[int]
    cut: tuple[int, int] | None = None  # pass 2's bins of the percentile cut (cut_bins)
    cut_log: bool = False  # whether pass 1's bins were log-spaced

    @classmethod
    def decode(cls, raw: np.ndarray, camera: CameraSpec | None, light: LightSpec,
               shape: tuple[int, int]) -> "Reduction":
        """The first STAT_COUNT integers of `raw`, of samples of `shape` (H, W), their
        texture rows bottom-up."""
        field = dict(zip(STAT_FIELDS, np.asarray(raw, dtype=np.uint32)[:STAT_COUNT]))
        count = int(field["count"])
        if count == 0:
            return cls(0, None, None, None, None, frozenset(), frozenset())
        low = lambda name: ~field[name]  # noqa: E731 - a minimum is stored complemented
        height = shape[0]
        rows = (height - 1 - int(field["row_hi"]), height - 1 - int(low("row_lo")))
        cols = (int(low("col_lo")), int(field["col_hi"]))
        reach = float(_unordered(field["reach"]))
        grow = ROUNDING * reach
        lo = _unordered(np.array([low("x_lo"), low("y_lo"), low("z_lo")])) - grow + light.position
        hi = _unordered(np.array([field["x_hi"], field["y_hi"], field["z_hi"]])) + grow + light.position
        depth = None
        if camera is not None:
            axis, offset = depth_axis(camera, light)
            depth = (float(_unordered(low("depth_lo"))) - depth_slack(reach, axis, offset),
                     float(_unordered(field["depth_hi"])) + depth_slack(reach, axis, offset))
        cut = None
        if field["cut_lo"] > 0 and field["cut_hi"] > 0:
            cut = (int(field["cut_lo"]) - 1, int(field["cut_hi"]) - 1)
        return cls(count, rows, cols, depth, (lo, hi), _bits(int(field["sides"])), _bits(int(field["faces"])),
                   cut, int(field["cut_log"]) == 2)

    def stats(self, camera: CameraSpec | None, shape: tuple[int, int]) -> SampleStats:
        """The statistics; the percentile cut from pass 2's bins, over this range."""
        window = sample_window(camera, self.rows, self.cols, shape)
        cull = None
        if self.depth is not None:
            cull = cut_range(self.cut, self.depth, self.cut_log)
        return SampleStats(self.count, window, self.depth, cull, self.box, self.sides, self.faces)


def depth_slack(reach: float, axis: np.ndarray, offset: float) -> float:
    """How far float32 rounding of light-centred coordinates up to `reach` may move a view
    depth p . axis + offset: the GPU's depth range grows by it (pass 1 computes the same)."""
    return ROUNDING * (3.0 * reach * float(np.abs(axis).max()) + abs(offset))
