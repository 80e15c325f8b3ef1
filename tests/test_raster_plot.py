"""core/raster_plot.py: the report's plots drawn without matplotlib (a stock Blender's
Python has none), through report.write_plot and report.write_frame_plot."""
from __future__ import annotations

import logging
import math
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from addon import report
from addon.core import bitmap_font, raster_plot
from addon.core.rows import make_row
from tests.test_png import read_png


@pytest.fixture
def no_matplotlib(monkeypatch):
    """matplotlib unimportable, as in Blender's own Python."""
    for name in ("matplotlib", "matplotlib.pyplot", "matplotlib.image"):
        monkeypatch.setitem(sys.modules, name, None)


def _row(preset: str, method: str, resolution: int, error: float, ms: float, gpu: float | None = None,
         frame: int | None = None, light: str | None = None) -> dict:
    figure = SimpleNamespace(error_pct=error, false_shadow_pct=error, false_lit_pct=0.0, evaluated_pixels=100)
    shot = {key: value for key, value in (("frame", frame), ("light", light)) if value is not None}
    row = make_row(preset, method, "omni", figure, {"total": ms}, "llvmpipe", "moderngl", 1, (16, 12),
                   resolution=resolution, **shot)
    if gpu is not None:
        row["gpu_ms"] = {"total": gpu}
    return row


# Two presets, three methods, two resolutions: points far apart on both axes.
ROWS = [_row(preset, method, res, error * (4.0 if preset == "beta" else 1.0) / (1 + k),
             ms * (1 + 3 * k) * (1.6 if preset == "beta" else 1.0))
        for preset in ("alpha", "beta")
        for method, error, ms in (("dpsm", 2.0, 1.0), ("cube", 0.5, 30.0), ("exact", 0.05, 900.0))
        for k, res in enumerate((512, 2048))]


def _pixel(img: np.ndarray, axes: raster_plot.Axes, x: float, y: float) -> np.ndarray:
    col, row = axes.to_pixel(x, y)
    return img[int(np.round(row)), int(np.round(col)), :3]


def _colour(index: int) -> np.ndarray:
    return np.round(raster_plot._rgb(index) * 255).astype(np.uint8)


def test_the_plot_is_drawn_without_matplotlib(tmp_path, no_matplotlib, caplog):
    path = tmp_path / "error_vs_time.png"
    with caplog.at_level(logging.INFO, logger="addon.report"):
        assert report.write_plot(ROWS, path)
    assert any("built-in painter" in r.getMessage() and r.levelno == logging.INFO for r in caplog.records)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    img = read_png(path)
    chart = report.pareto_chart(ROWS)
    assert img.shape == (chart.size[1], chart.size[0], 3) == (715, 1210, 3)
    assert chart.log_x and chart.log_y  # errors from 0.025 to 8 %: over 30 times apart
    axes = raster_plot.chart_axes(chart)
    seen = {}
    for row in ROWS:
        pixel = _pixel(img, axes, report.plot_time_ms(row), row["error_pct"])
        preset = ("alpha", "beta").index(row["preset"])
        assert np.array_equal(pixel, _colour(preset)), (row["preset"], row["method"], row["resolution"])
        seen.setdefault(row["preset"], tuple(pixel))
    assert seen["alpha"] != seen["beta"]
    # The box, the texts and the legend are there: dark pixels left of, under and right of the box.
    dark = img.sum(axis=2) < 200
    assert dark[:, :axes.left].any() and dark[axes.bottom + 2:].any() and dark[:, axes.right + 2:].any()
    assert dark[:axes.top].any()  # the title


def test_each_method_has_its_own_marker_and_each_preset_its_colour():
    masks = [raster_plot.marker_mask(m) for m in raster_plot.MARKERS]
    assert all(mask.any() and mask[mask.shape[0] // 2, mask.shape[1] // 2] for mask in masks)
    assert len({mask.tobytes() for mask in masks}) == len(masks)
    assert len(set(raster_plot.COLOURS)) == len(raster_plot.COLOURS)
    series = report.pareto_chart(ROWS).series
    methods = ("cube", "dpsm", "exact")  # sorted: a marker each, in this order
    assert {(s.label, s.colour, s.marker) for s in series} == {
        (f"{p} / {m}", pi, mi) for pi, p in enumerate(("alpha", "beta")) for mi, m in enumerate(methods)}


def test_log_axes_have_decade_ticks_and_a_linear_y_when_errors_are_close():
    labels = [label for _, label in raster_plot._ticks(math.log10(0.8), math.log10(1500), True) if label]
    assert labels == ["1", "10", "100", "1000"]
    assert [label for _, label in raster_plot._ticks(0.0, 0.7, False)] == ["0.0", "0.1", "0.2", "0.3", "0.4",
                                                                           "0.5", "0.6", "0.7"]
    close = [r for r in ROWS if r["method"] != "exact" and r["preset"] == "alpha"]  # 0.25 to 2 %
    chart = report.pareto_chart(close)
    assert not chart.log_y
    axes = raster_plot.chart_axes(chart)
    (_, low), (_, high) = axes.to_pixel(1.0, 0.5), axes.to_pixel(1.0, 1.0)
    (_, top) = axes.to_pixel(1.0, 1.5)
    assert high - low == pytest.approx(top - high)  # linear: equal steps, equal pixels


def test_zero_errors_and_a_single_row_still_draw(tmp_path, no_matplotlib):
    rows = [_row("alpha", "exact", 1024, 0.0, 12.0), _row("alpha", "dpsm", 1024, 1.5, 3.0)]
    assert report.write_plot(rows, tmp_path / "zero.png")
    assert report.write_plot(rows[:1], tmp_path / "one.png")
    assert read_png(tmp_path / "one.png").shape == (715, 1210, 3)


def test_every_character_of_the_plots_texts_has_a_glyph():
    assert set(bitmap_font.GLYPHS) == {chr(c) for c in range(32, 127)}
    for digits in bitmap_font.GLYPHS.values():
        rows = [int(digits[i:i + 2], 16) for i in range(0, 16, 2)]
        assert len(digits) == 16 and all(row < 32 for row in rows)
    assert len(set(bitmap_font.GLYPHS.values())) == len(bitmap_font.GLYPHS)  # no two alike
    gpu = [_row("alpha", "exact", 512, 0.01, 5.0, gpu=2.0), _row("alpha", "dpsm", 512, 1.0, 3.0)]
    gpu[0]["list_entries"] = 3_400_000
    charts = [report.pareto_chart(ROWS), report.pareto_chart(gpu), report.pareto_chart(gpu[:1]),
              report.frame_chart([_row("s", "dpsm", 256, 0.1, 1.0, frame=f, light=light)
                                  for f in (1, 2) for light in ("key", "rim")])]
    texts = ["0123456789.-e+"]  # the tick labels
    for chart in charts:
        texts += [chart.title, chart.xlabel, chart.ylabel]
        texts += [s.label for s in chart.series] + [t for s in chart.series for t in s.point_labels]
    assert "512 (3.4M entries)" in texts and "512 wall" in texts
    missing = {c for text in texts for c in text} - set(bitmap_font.GLYPHS)
    assert not missing


def test_text_is_drawn_from_the_glyphs():
    mask = bitmap_font.text_mask("1.5 ms", scale=2)
    assert mask.shape == (16, (6 * 6 - 1) * 2)
    assert np.array_equal(mask[::2, :10:2], bitmap_font.glyph("1"))
    assert np.array_equal(bitmap_font.glyph("\u00b5"), bitmap_font.glyph("?"))  # not in the table


def test_the_frame_plot_is_drawn_without_matplotlib(tmp_path, no_matplotlib):
    rows = [_row("shot", method, 512, base + 0.02 * f, 1.0, frame=f, light="key")
            for method, base in (("dpsm", 1.0), ("exact", 0.1)) for f in range(1, 6)]
    assert not report.write_frame_plot(rows[:1], tmp_path / "one.png")
    assert not (tmp_path / "one.png").exists()
    path = tmp_path / "error_vs_frame.png"
    assert report.write_frame_plot(rows, path)
    img = read_png(path)
    assert img.shape == (660, 1210, 3)
    chart = report.frame_chart(rows)
    axes = raster_plot.chart_axes(chart)
    assert not chart.log_x and not chart.log_y
    for index, series in enumerate(chart.series):
        for x, y in zip(series.xs, series.ys):
            assert np.array_equal(_pixel(img, axes, x, y), _colour(index))
    assert [s.label for s in chart.series] == ["dpsm @512", "exact @512"]


def test_matplotlib_still_draws_where_it_is_installed(tmp_path):
    pytest.importorskip("matplotlib")
    assert report.write_plot(ROWS, tmp_path / "mpl.png")
    assert b"matplotlib" in (tmp_path / "mpl.png").read_bytes().lower()  # its Software tag
