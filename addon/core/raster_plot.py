"""The report's plots drawn with numpy alone, for a Python without matplotlib (a stock
Blender's): a white picture with the axes box, grid, ticks and their labels, the axis
titles, a title, the points (a colour per `Series.colour`, a marker shape per
`Series.marker`), their small labels, the lines and a legend at the right.

`report.py` describes a plot once as a `Chart` and hands it to matplotlib where it is
installed, else to `write_chart` here. `chart_axes` is the one mapping from data to
pixels that `plot_image` draws with (tests ask it where a point must be). Colours are
matplotlib's default cycle (Tableau 10), markers its letters (`MARKERS`), so both
painters agree on which preset and method is which.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import bitmap_font as font
from .png import write_png

COLOURS = ("1f77b4", "ff7f0e", "2ca02c", "d62728", "9467bd", "8c564b", "e377c2", "7f7f7f", "bcbd22", "17becf")
MARKERS = "osD^v<>ph*XP8dH"  # circle, square, diamond, triangles, pentagon, hexagon, star, x, plus, octagon...
MARKER_RADIUS = 4.5  # pixels: about matplotlib's scatter size 40 at 110 dpi
ENTRY_HEIGHT = 12  # a legend line, pixels


@dataclass(frozen=True)
class Series:
    """Points of one legend entry: scattered markers with their labels, or (`joined`) a
    line through them with small circles."""
    label: str
    colour: int
    xs: tuple[float, ...]
    ys: tuple[float, ...]
    marker: int = 0
    point_labels: tuple[str, ...] = ()
    joined: bool = False


@dataclass(frozen=True)
class Line:
    """A line without a legend entry (a Pareto front), drawn see-through."""
    colour: int
    xs: tuple[float, ...]
    ys: tuple[float, ...]
    alpha: float = 0.6


@dataclass(frozen=True)
class Chart:
    """One plot: its texts, its series and lines in drawing order, the axis scales, the
    picture's size in pixels (matplotlib's figure is size / 110 inches at 110 dpi) and
    the legend's columns (matplotlib's; the raster legend adds columns where needed)."""
    title: str
    xlabel: str
    ylabel: str
    items: tuple[Series | Line, ...]
    log_x: bool = False
    log_y: bool = False
    size: tuple[int, int] = (1210, 715)
    legend_columns: int = 1

    @property
    def series(self) -> list[Series]:
        return [item for item in self.items if isinstance(item, Series)]


@dataclass(frozen=True)
class Axes:
    """The plot box in pixels (`left`..`right` columns, `top`..`bottom` rows) and the data
    range it shows, in axis units (log10 of the value on a log axis)."""
    left: int
    top: int
    right: int
    bottom: int
    x_range: tuple[float, float]
    y_range: tuple[float, float]
    log_x: bool
    log_y: bool

    def to_pixel(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Column and row (floats) of data points; a log axis puts values <= 0 at its low end."""
        u = _axis_units(x, self.log_x, self.x_range[0])
        v = _axis_units(y, self.log_y, self.y_range[0])
        (x0, x1), (y0, y1) = self.x_range, self.y_range
        return (self.left + (u - x0) / (x1 - x0) * (self.right - self.left),
                self.bottom - (v - y0) / (y1 - y0) * (self.bottom - self.top))


def _axis_units(values, log: bool, low: float) -> np.ndarray:
    v = np.asarray(values, dtype=np.float64)
    if not log:
        return v
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(v > 0, np.log10(np.where(v > 0, v, 1.0)), low)


def _data_range(values: list[float], log: bool) -> tuple[float, float]:
    """The axis range in axis units: the data with 5 % margins (half a decade or one unit
    around a single value)."""
    v = np.asarray([x for x in values if math.isfinite(x) and (x > 0 or not log)], dtype=np.float64)
    if v.size == 0:
        return (0.0, 1.0)
    if log:
        v = np.log10(v)
    lo, hi = float(v.min()), float(v.max())
    if hi - lo < 1e-9:
        pad = 0.5 if log else max(abs(lo) * 0.1, 1.0)
        return lo - pad, hi + pad
    pad = 0.05 * (hi - lo)
    return lo - pad, hi + pad


def _ticks(lo: float, hi: float, log: bool, integers: bool = False) -> list[tuple[float, str]]:
    """(position in axis units, label) of every tick in [lo, hi]; an empty label is a minor
    tick. Log: decades labelled 1, 10, 100 ... and 2..9 between (2 and 5 labelled too when
    fewer than two decades show). Linear: steps of 1, 2 or 5 times a power of ten."""
    if log:
        ticks = []
        for k in range(math.floor(lo), math.ceil(hi) + 1):
            for m in range(1, 10):
                pos = k + math.log10(m)
                if lo - 1e-9 <= pos <= hi + 1e-9:
                    ticks.append((pos, f"{m * 10.0 ** k:g}" if m == 1 else ""))
        if sum(1 for _, label in ticks if label) < 2:
            ticks = [(p, f"{10 ** p:.3g}" if round(10 ** (p % 1)) in (1, 2, 5) else "") for p, _ in ticks]
        return ticks
    raw = (hi - lo) / 8.0
    base = 10.0 ** math.floor(math.log10(raw))
    step = next(base * m for m in (1, 2, 5, 10) if base * m >= raw * 0.999)
    if integers:
        step = max(step, 1.0)
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    first = math.ceil(lo / step - 1e-9)
    values = [i * step for i in range(first, math.floor(hi / step + 1e-9) + 1)]
    return [(v, f"{0.0 if abs(v) < step * 1e-9 else v:.{decimals}f}") for v in values]


def _legend_layout(chart: Chart, box_height: int) -> tuple[int, int, int]:
    """(columns, entries a column, column width in pixels) of the legend."""
    labels = [s.label for s in chart.series if s.label]
    if not labels:
        return 0, 0, 0
    columns = max(1, chart.legend_columns)
    while math.ceil(len(labels) / columns) * ENTRY_HEIGHT + 8 > box_height and columns < len(labels):
        columns += 1
    width = 26 + font.text_size(max(labels, key=len))[0] + 8
    return columns, math.ceil(len(labels) / columns), width


def chart_axes(chart: Chart) -> Axes:
    """Where `plot_image` puts the plot box, and the data range it shows."""
    width, height = chart.size
    xs = [x for item in chart.items for x in item.xs]
    ys = [y for item in chart.items for y in item.ys]
    x_range, y_range = _data_range(xs, chart.log_x), _data_range(ys, chart.log_y)
    label_width = max((font.text_size(label)[0] for _, label in _ticks(*y_range, chart.log_y)), default=0)
    left = 6 + font.GLYPH_HEIGHT + 8 + label_width + 8
    top, bottom = 40, height - 50
    columns, _, column_width = _legend_layout(chart, bottom - top)
    right = width - 12 - (columns * column_width + 10 if columns else 0)
    return Axes(left, top, right, bottom, x_range, y_range, chart.log_x, chart.log_y)


# ---------------------------------------------------------------------------- painting
def _rgb(colour: int | str) -> np.ndarray:
    hex_colour = COLOURS[colour % len(COLOURS)] if isinstance(colour, int) else colour
    return np.array([int(hex_colour[i:i + 2], 16) for i in (0, 2, 4)], dtype=np.float64) / 255.0


def _blend(img: np.ndarray, rows: np.ndarray, cols: np.ndarray, rgb: np.ndarray, alpha: float = 1.0) -> None:
    """Paint the pixels (rows, cols) inside the picture, each once."""
    height, width = img.shape[:2]
    keep = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)
    flat = np.unique(rows[keep].astype(np.int64) * width + cols[keep].astype(np.int64))
    r, c = np.divmod(flat, width)
    img[r, c] = img[r, c] * (1.0 - alpha) + rgb * alpha


def _paste(img: np.ndarray, mask: np.ndarray, x: int, y: int, rgb: np.ndarray, alpha: float = 1.0) -> None:
    """Paint a bool mask with its top-left pixel at column x, row y."""
    rows, cols = np.nonzero(mask)
    _blend(img, rows + int(y), cols + int(x), rgb, alpha)


def _polyline(img: np.ndarray, px: np.ndarray, py: np.ndarray, rgb: np.ndarray, width: int = 2,
              alpha: float = 1.0) -> None:
    """A line through the pixel points (DDA), `width` pixels across."""
    rows, cols = [], []
    for x0, y0, x1, y1 in zip(px[:-1], py[:-1], px[1:], py[1:]):
        n = int(max(abs(x1 - x0), abs(y1 - y0))) + 2
        t = np.linspace(0.0, 1.0, n)
        x, y = np.round(x0 + (x1 - x0) * t), np.round(y0 + (y1 - y0) * t)
        steep = abs(y1 - y0) > abs(x1 - x0)
        for k in range(width):  # thicken across the line's main direction
            rows.append(y if steep else y + k)
            cols.append(x + k if steep else x)
    if rows:
        _blend(img, np.concatenate(rows), np.concatenate(cols), rgb, alpha)


def _polygon(xs: np.ndarray, ys: np.ndarray, corners: list[tuple[float, float]]) -> np.ndarray:
    """Even-odd test of the points (xs, ys) against a closed polygon."""
    inside = np.zeros(xs.shape, bool)
    for (xa, ya), (xb, yb) in zip(corners, corners[1:] + corners[:1]):
        crosses = (ya > ys) != (yb > ys)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cut = xa + (xb - xa) * (ys - ya) / (yb - ya)
        inside ^= crosses & (xs < x_cut)
    return inside


def _regular(n: int, radius: float, start_deg: float, inner: float = 0.0) -> list[tuple[float, float]]:
    """Corners of a regular polygon (or a star, with an `inner` radius), y up."""
    count = 2 * n if inner else n
    angles = [math.radians(start_deg) + 2 * math.pi * i / count for i in range(count)]
    radii = [radius if not inner or i % 2 == 0 else inner for i in range(count)]
    return [(r * math.cos(a), r * math.sin(a)) for r, a in zip(radii, angles)]


def marker_mask(marker: str, radius: float = MARKER_RADIUS) -> np.ndarray:
    """(2R+1, 2R+1) bool: the filled marker (a matplotlib letter) centred in the square."""
    size = int(math.ceil(radius * 1.2))
    x, y = np.meshgrid(np.arange(-size, size + 1, dtype=np.float64), -np.arange(-size, size + 1, dtype=np.float64))
    r, ax, ay = radius, np.abs(x), np.abs(y)
    bar = 0.3 * r
    shapes = {
        "o": lambda: x * x + y * y <= r * r, "s": lambda: (ax <= 0.85 * r) & (ay <= 0.85 * r),
        "D": lambda: ax + ay <= 1.1 * r, "d": lambda: ax / 0.6 + ay <= 1.1 * r,
        "^": lambda: _polygon(x, y, _regular(3, 1.2 * r, 90)), "v": lambda: _polygon(x, y, _regular(3, 1.2 * r, 270)),
        "<": lambda: _polygon(x, y, _regular(3, 1.2 * r, 180)), ">": lambda: _polygon(x, y, _regular(3, 1.2 * r, 0)),
        "p": lambda: _polygon(x, y, _regular(5, 1.05 * r, 90)), "h": lambda: _polygon(x, y, _regular(6, r, 90)),
        "H": lambda: _polygon(x, y, _regular(6, r, 0)), "8": lambda: _polygon(x, y, _regular(8, r, 22.5)),
        "*": lambda: _polygon(x, y, _regular(5, 1.2 * r, 90, inner=0.5 * r)),
        "X": lambda: ((np.abs(x - y) <= 1.5 * bar) | (np.abs(x + y) <= 1.5 * bar)) & (ax <= 0.8 * r) & (ay <= 0.8 * r),
        "P": lambda: ((ax <= bar) | (ay <= bar)) & (ax <= 0.9 * r) & (ay <= 0.9 * r),
    }
    return shapes.get(marker, shapes["o"])()


def _text(img: np.ndarray, text: str, x: float, y: float, rgb: np.ndarray, scale: int = 1, align: str = "left",
          vertical: bool = False) -> None:
    """One line of text, its top at row y; `align` says whether x is its left end, centre
    or right end. `vertical` turns it a quarter left (read upwards), centred on (x, y)."""
    mask = font.text_mask(text, scale)
    if vertical:
        mask = np.rot90(mask)
        _paste(img, mask, round(x - mask.shape[1] / 2), round(y - mask.shape[0] / 2), rgb)
        return
    shift = {"left": 0.0, "center": mask.shape[1] / 2, "right": float(mask.shape[1])}[align]
    _paste(img, mask, round(x - shift), round(y), rgb)


def _draw_series(img: np.ndarray, axes: Axes, item: Series | Line) -> None:
    px, py = axes.to_pixel(item.xs, item.ys)
    rgb = _rgb(item.colour)
    if isinstance(item, Line):
        _polyline(img, px, py, rgb, 2, item.alpha)
        return
    if item.joined:
        _polyline(img, px, py, rgb, 2)
    mask = marker_mask("o", 2.5) if item.joined else marker_mask(MARKERS[item.marker % len(MARKERS)])
    half = mask.shape[0] // 2
    for cx, cy in zip(np.round(px), np.round(py)):
        _paste(img, mask, cx - half, cy - half, rgb)
    for label, cx, cy in zip(item.point_labels, px, py):
        _text(img, label, cx + 6, cy - 13, _rgb("202020"))


def _draw_frame(img: np.ndarray, chart: Chart, axes: Axes) -> None:
    """Grid, box, ticks and their labels, the axis titles and the title."""
    black, major, minor = _rgb("000000"), _rgb("d9d9d9"), _rgb("eeeeee")
    x_ticks = _ticks(*axes.x_range, axes.log_x, integers=all(float(x).is_integer() for i in chart.items for x in i.xs))
    y_ticks = _ticks(*axes.y_range, axes.log_y)
    top, bottom, left, right = axes.top, axes.bottom, axes.left, axes.right
    span = np.arange(top, bottom + 1)
    for pos, label in x_ticks:
        col = round(axes.to_pixel(10 ** pos if axes.log_x else pos, 1.0)[0])
        _blend(img, span, np.full_like(span, col), major if label else minor)
        _blend(img, np.arange(bottom + 1, bottom + (5 if label else 3)), np.full(4 if label else 2, col), black)
        if label:
            _text(img, label, col, bottom + 8, black, align="center")
    span = np.arange(left, right + 1)
    for pos, label in y_ticks:
        row = round(axes.to_pixel(1.0, 10 ** pos if axes.log_y else pos)[1])
        _blend(img, np.full_like(span, row), span, major if label else minor)
        _blend(img, np.full(4 if label else 2, row), np.arange(left - (4 if label else 2), left), black)
        if label:
            _text(img, label, left - 7, row - font.GLYPH_HEIGHT // 2 + 1, black, align="right")
    box_x = np.array([left, right, right, left, left], dtype=np.float64)
    box_y = np.array([top, top, bottom, bottom, top], dtype=np.float64)
    _polyline(img, box_x, box_y, black, 1)
    width = img.shape[1]
    centre = (left + right) / 2
    xlabel_width = font.text_size(chart.xlabel)[0]
    x_centre = min(max(centre, xlabel_width / 2 + 4), width - xlabel_width / 2 - 4)
    _text(img, chart.xlabel, x_centre, bottom + 26, black, align="center")
    _text(img, chart.ylabel, 6 + font.GLYPH_HEIGHT / 2, (top + bottom) / 2, black, vertical=True)
    _text(img, chart.title, centre, 12, black, scale=2, align="center")


def _draw_legend(img: np.ndarray, chart: Chart, axes: Axes) -> None:
    entries = [s for s in chart.series if s.label]
    columns, per_column, column_width = _legend_layout(chart, axes.bottom - axes.top)
    if not entries:
        return
    x0, y0 = axes.right + 10, axes.top
    x1, y1 = x0 + columns * column_width, y0 + per_column * ENTRY_HEIGHT + 8
    grey = _rgb("b0b0b0")
    _polyline(img, np.array([x0, x1, x1, x0, x0], float), np.array([y0, y0, y1, y1, y0], float), grey, 1)
    for i, entry in enumerate(entries):
        col, row = divmod(i, per_column)
        ex, ey = x0 + col * column_width + 4, y0 + 4 + row * ENTRY_HEIGHT
        rgb, mid = _rgb(entry.colour), ey + ENTRY_HEIGHT // 2
        if entry.joined:
            _polyline(img, np.array([ex, ex + 16], float), np.array([mid, mid], float), rgb, 2)
        mask = marker_mask("o", 2.5) if entry.joined else marker_mask(MARKERS[entry.marker % len(MARKERS)], 4.0)
        _paste(img, mask, ex + 8 - mask.shape[1] // 2, mid - mask.shape[0] // 2, rgb)
        _text(img, entry.label, ex + 22, mid - 3, _rgb("000000"))


def plot_image(chart: Chart) -> np.ndarray:
    """(H, W, 3) float RGB in [0, 1], row 0 at the top: the chart drawn."""
    width, height = chart.size
    img = np.ones((height, width, 3), dtype=np.float64)
    axes = chart_axes(chart)
    _draw_frame(img, chart, axes)
    for item in chart.items:
        _draw_series(img, axes, item)
    _draw_legend(img, chart, axes)
    return img


def write_chart(chart: Chart, path: str | Path) -> None:
    """The chart as a PNG file."""
    write_png(path, plot_image(chart))
