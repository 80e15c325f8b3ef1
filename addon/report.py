"""Report outputs of `compare`: a markdown table and the error-vs-time Pareto plot.

The plots are described once (`pareto_chart`, `frame_chart`) and drawn with matplotlib
where it is installed, else with the built-in numpy painter, core/raster_plot.py.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

from .core.raster_plot import MARKERS, Chart, Line, Series, write_chart
from .core.rows import SHOT_FIELDS, Row, row_label

log = logging.getLogger(__name__)


def _pareto(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Points not beaten on both time and error, sorted by time."""
    front, best = [], float("inf")
    for t, e in sorted(points):
        if e < best:
            front.append((t, e))
            best = e
    return front


def _cell(value: object, spec: str = "") -> str:
    """A table cell: blank where the row has no such column (rows.Row)."""
    return "" if value is None else format(value, spec)


SHOT_COLUMNS = SHOT_FIELDS  # a .blend job's; a preset's rows have none


def _shot_columns(rows: Sequence[Row]) -> list[str]:
    """The shot columns some row has: a sweep's table shows them after the preset."""
    return [key for key in SHOT_COLUMNS if any(key in r for r in rows)]


def grouped(rows: Sequence[Row]) -> list[Row]:
    """The rows grouped by scene, frame, light and camera; within a group as measured."""
    def key(r: Row) -> tuple:
        return (r["preset"], *((r.get(k) is not None, r.get(k) or 0 if k == "frame" else r.get(k) or "")
                               for k in SHOT_COLUMNS))

    return sorted(rows, key=key)


def markdown_table(rows: Sequence[Row]) -> str:
    """One line per row: the fields a reader compares; `res` is the map's side only. A
    sweep's rows are grouped by frame and light, with their columns after the preset."""
    shot = _shot_columns(rows)
    rows = grouped(rows) if shot else rows
    head = ("| preset |" + "".join(f" {key} |" for key in shot) + " method | res | error % | false shadow % | false lit % | soft error % | evaluated px | total ms | "
            "prepare ms | analysis ms | maps ms | test ms | passes | triangles | tess. added | texels | "
            "max count before | max count after | texel use |")
    # Rows timed by GPU queries: the GPU's own ms per frame beside the wall time.
    gpu = any("gpu_ms" in r for r in rows)
    if gpu:
        head = head.replace(" total ms |", " total ms | GPU ms |", 1)
    # Scenes with see-through materials: the fractional pixels and their soft error.
    fractional = any("fractional_pixels" in r for r in rows)
    if fractional:
        head += " fractional px | fractional soft error % |"
    # Sized lights: the light as the reference rendered it, and the reference's own noise.
    sized = any("reference_noise_pct" in r for r in rows)
    if sized:
        head += " light | reference noise % |"
    lines = [head, "|" + "|".join(["---"] * (head.count("|") - 1)) + "|"]
    for r in rows:
        t = r["time_ms"]
        cells = [r["preset"], *(_cell(r.get(key)) for key in shot), row_label(r), _cell(r.get("resolution")), f"{r['error_pct']:.3f}",
                 f"{r['false_shadow_pct']:.3f}", f"{r['false_lit_pct']:.3f}",
                 f"{r.get('soft_error_pct', r['error_pct']):.3f}", str(r["evaluated_pixels"]), f"{t['total']:.1f}",
                 *([_cell(r.get("gpu_ms", {}).get("total"), ".2f")] if gpu else []),
                 *(_cell(t.get(stage), ".1f") for stage in ("prepare", "analysis", "shadow_maps", "shadow_test")),
                 _cell(r.get("passes")), _cell(r.get("triangles_drawn")), _cell(r.get("tessellated_triangles")),
                 _cell(r.get("texels")), _cell(r.get("max_count_before"), ".0f"),
                 _cell(r.get("max_count_after"), ".0f"), _cell(r.get("texel_utilization"), ".3f")]
        if fractional:
            cells += [_cell(r.get("fractional_pixels")), _cell(r.get("fractional_soft_error_pct"), ".3f")]
        if sized:
            cells += [_cell(r.get("light_shape", "hard")), _cell(r.get("reference_noise_pct"), ".3f")]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def list_table(rows: Sequence[Row]) -> str:
    """The exact rows' work (rows.Row's list_* fields): the lists, the triangle pass's
    fragments and entries, and the walks and entries moved to later rounds; empty when
    no row has them."""
    listed = [r for r in rows if "list_entries" in r]
    if not listed:
        return ""
    lines = ["| preset | method | res | longest list | mean list | fragments | entries walked | "
             "walks moved on | later rounds | entries in later rounds |", "|" + "---|" * 10]
    for r in listed:
        lines.append("| " + " | ".join([
            r["preset"], row_label(r), _cell(r.get("resolution")), _cell(r.get("list_longest")),
            _cell(r.get("list_mean"), ".2f"), _cell(r.get("list_fragments"), ","), _cell(r.get("list_entries"), ","),
            _cell(r.get("list_cut"), ","), _cell(r.get("list_rounds")), _cell(r.get("list_moved_entries"), ",")]) + " |")
    return "\n".join(lines) + "\n"


def _scene_notes(rows: Sequence[dict]) -> list[str]:
    """One line per scene and note: what its rows cannot follow (see shadow_rule.unfollowed),
    then the rows' notes: once for a note every OmniWarp row of the scene carries (what no
    method draws, readers/left_out.py), else per method (a method's own limit there)."""
    lines = []
    for preset in sorted({r["preset"] for r in rows}):
        notes = next((r["scene_notes"] for r in rows if r["preset"] == preset and r.get("scene_notes")), [])
        lines += [f"- note on {preset}: {note}" for note in notes]
        ours = [r for r in rows if r["preset"] == preset and r["method"] != "eevee"]
        split = [(r["method"], (r.get("note") or "").split("; ")) for r in ours]
        everywhere = [n for n in split[0][1] if n and all(n in parts for _, parts in split)] if split else []
        lines += [f"- note on {preset} (every OmniWarp row): {note}" for note in everywhere]
        own = sorted({f"{method}: {n}" for method, parts in split for n in parts if n and n not in everywhere})
        lines += [f"- note on {preset}: {note}" for note in own]
    return lines


def write_markdown(rows: Sequence[dict], path: Path, stamp: str, command: str = "") -> None:
    """report.md: provenance, then the table."""
    renderers = sorted({r["renderer"] for r in rows})
    backends = sorted({r["backend"] for r in rows})
    sizes = sorted({"x".join(str(v) for v in r.get("camera_size", [])) for r in rows})
    text = [
        "# OmniWarp comparison against Cycles",
        "",
        f"- measured: {stamp}",
        *([f"- command: `{command}`"] if command else []),
        f"- renderer: {', '.join(renderers)}",
        f"- backend: {', '.join(backends)}",
        f"- camera size: {', '.join(sizes)}; times are medians of {rows[0]['frames'] if rows else 0} timed repeats "
        "after one warm-up frame",
        "- error % = mismatching evaluated pixels against the Cycles visibility; soft error % = mean "
        "|visibility - Cycles| (equal to error % for binary methods; antialiased rows differ); times on a "
        "software rasteriser mean little in absolute terms, compare them as ratios within this table",
        *(["- fractional px: pixels Cycles lights through see-through surfaces or a sized light's penumbra "
           "(visibility in (0.02, 0.98)); a hard light's error % leaves them out, a sized light's counts them "
           "(the side of 0.5 each falls on); both are measured by their own soft error"]
          if any("fractional_pixels" in r for r in rows) else []),
        *(["- light: a sized light's shape as the reference rendered it (docs/soft.md); reference noise % = the "
           "Cycles reference's own noise in soft error %'s unit, measured from two halves of its samples"]
          if any("reference_noise_pct" in r for r in rows) else []),
        *_scene_notes(rows),
        "",
        markdown_table(rows),
    ]
    work = list_table(rows)
    if work:
        text += ["The `exact` rows' work (one untimed frame each, `count_work`):", "", work]
    path.write_text("\n".join(text), encoding="utf-8")


def _point_label(row: Row) -> str:
    """A plot point's label: the map resolution, and for `exact` the list entries its
    triangle pass walked (its work, which is what its time pays for)."""
    label = str(row.get("resolution", ""))
    if "list_entries" in row:
        label += f" ({row['list_entries'] / 1e6:.1f}M entries)"
    return label


def pareto_chart(rows: Sequence[dict]) -> Chart:
    """The error-vs-time plot described once for both painters: error % against total ms
    per frame (plot_time_ms: GPU time where measured), one colour per preset, a marker per
    method, each point labelled (_point_label), and each preset's Pareto front."""
    presets = sorted({r["preset"] for r in rows})
    methods = sorted({row_label(r) for r in rows})
    mixed = any("gpu_ms" in r for r in rows)
    items: list[Series | Line] = []
    for pi, preset in enumerate(presets):
        pts = []
        for mi, method in enumerate(methods):
            sel = [r for r in rows if r["preset"] == preset and row_label(r) == method]
            if not sel:
                continue
            xs = tuple(plot_time_ms(r) for r in sel)
            ys = tuple(float(r["error_pct"]) for r in sel)
            pts += list(zip(xs, ys))
            labels = tuple(_point_label(r) + (" wall" if mixed and "gpu_ms" not in r else "") for r in sel)
            items.append(Series(f"{preset} / {method}", pi, xs, ys, marker=mi, point_labels=labels))
        front = _pareto(pts)
        if len(front) > 1:
            items.append(Line(pi, *(tuple(v) for v in zip(*front))))
    errors = [r["error_pct"] for r in rows if r["error_pct"] > 0]
    # e.g. a uniform sun map at several % next to warped maps at 0.02 %
    log_y = bool(errors) and max(errors) / min(errors) > 30.0
    timed = sum("gpu_ms" in r for r in rows)
    if timed == len(rows):
        xlabel = "GPU time per frame, ms (log; median, all stages; timer queries)"
    elif timed:
        xlabel = ("time per frame, ms (log; median, all stages): GPU time (timer queries) where "
                  "measured, wall time for the rows marked 'wall'")
    else:
        xlabel = "time per frame, ms (log; median, all stages; wall)"
    return Chart("Shadow error against time (lines: Pareto front per preset)", xlabel,
                 "error % of evaluated pixels vs Cycles", tuple(items), log_x=True, log_y=log_y, size=(1210, 715),
                 legend_columns=1 if len(presets) * len(methods) <= 24 else 2)


def write_plot(rows: Sequence[dict], path: Path) -> bool:
    """error_vs_time.png (pareto_chart): with matplotlib where it is installed, else with
    the built-in painter (core/raster_plot.py; a stock Blender's Python has no matplotlib)."""
    return _draw(pareto_chart(rows), path)


def _draw(chart: Chart, path: Path) -> bool:
    """Write the chart to `path` with matplotlib, or where it is missing with raster_plot."""
    try:
        import matplotlib
    except ImportError:
        write_chart(chart, path)
        log.info("matplotlib is not installed: %s drawn by the built-in painter (core/raster_plot.py)", Path(path).name)
        return True
    matplotlib.use("Agg")
    _draw_matplotlib(chart, path)
    return True


def _draw_matplotlib(chart: Chart, path: Path) -> None:
    """The chart as matplotlib draws it: scatter markers s=40 with 7-point labels, 1-point
    lines, a grid and the legend outside the axes."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(chart.size[0] / 110, chart.size[1] / 110), dpi=110)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for item in chart.items:
        colour = colours[item.colour % len(colours)]
        if isinstance(item, Line):
            ax.plot(item.xs, item.ys, color=colour, linewidth=1, alpha=item.alpha)
        elif item.joined:
            ax.plot(item.xs, item.ys, color=colour, marker="o", markersize=3, linewidth=1, label=item.label)
        else:
            ax.scatter(item.xs, item.ys, color=colour, marker=MARKERS[item.marker % len(MARKERS)], s=40,
                       label=item.label)
        for text, x, y in zip(getattr(item, "point_labels", ()), item.xs, item.ys):
            ax.annotate(text, (x, y), textcoords="offset points", xytext=(4, 3), fontsize=7)
    if chart.log_x:
        ax.set_xscale("log")
    if chart.log_y:
        ax.set_yscale("log")
    ax.set_xlabel(chart.xlabel)
    ax.set_ylabel(chart.ylabel)
    ax.set_title(chart.title)
    if chart.log_x or chart.log_y:
        ax.grid(True, which="both", alpha=0.3)
    else:
        ax.grid(True, alpha=0.3)
    # Outside the axes: with many methods an inside legend hides the points.
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), ncol=chart.legend_columns)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_time_ms(row: Row) -> float:
    """A row's time on the Pareto plot: the GPU's total where timer queries measured it (the
    work itself, not the host's waits), the wall total otherwise."""
    gpu = row.get("gpu_ms")
    return float(gpu["total"]) if gpu else float(row["time_ms"]["total"])


def frame_chart(rows: Sequence[dict]) -> Chart | None:
    """A shot's error % against frame, one line per light and method (as labelled, with its
    resolution); None for rows of fewer than two frames."""
    framed = [r for r in rows if "frame" in r]
    if len({r["frame"] for r in framed}) < 2:
        return None
    lines: dict[tuple, list[tuple[int, float]]] = {}
    for r in framed:
        res = f" @{r['resolution']}" if "resolution" in r else ""
        name = (r["preset"], r.get("light", ""), r.get("camera", ""), row_label(r) + res)
        lines.setdefault(name, []).append((r["frame"], r["error_pct"]))
    several = {k: len({name[k] for name in lines}) > 1 for k in range(3)}
    items = []
    for i, (name, points) in enumerate(sorted(lines.items())):
        points.sort()
        label = " / ".join(part for k, part in enumerate(name) if part and (k == 3 or several[k]))
        items.append(Series(label, i, tuple(f for f, _ in points), tuple(float(e) for _, e in points), joined=True))
    return Chart("Shadow error over the shot (one line per light and method)", "frame",
                 "error % of evaluated pixels vs Cycles", tuple(items), size=(1210, 660),
                 legend_columns=1 if len(lines) <= 24 else 2)


def write_frame_plot(rows: Sequence[dict], path: Path) -> bool:
    """error_vs_frame.png (frame_chart), with matplotlib or the built-in painter. Drawn only
    for rows of two frames or more; False otherwise."""
    chart = frame_chart(rows)
    return chart is not None and _draw(chart, path)
