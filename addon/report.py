"""Report outputs of `compare`: a markdown table and the error-vs-time Pareto plot."""
from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

from .rows import SHOT_FIELDS, Row, row_label

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
    method draws, reference/left_out.py), else per method (a method's own limit there)."""
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


def write_plot(rows: Sequence[dict], path: Path) -> bool:
    """Error % against total ms per frame (plot_time_ms: GPU time where measured), one colour
    per preset, a marker per method.

    Returns False, with one log line, where matplotlib is missing (a bare GPU machine
    runs `scripts/gpu_bench.sh` with numpy and moderngl only): the table still counts.
    """
    try:
        import matplotlib
    except ImportError:
        log.warning("matplotlib is not installed: %s not drawn (the table and results.json are)", path.name)
        return False

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(11, 6.5), dpi=110)
    presets = sorted({r["preset"] for r in rows})
    methods = sorted({row_label(r) for r in rows})
    markers = "osD^v<>ph*XP8dH"
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for pi, preset in enumerate(presets):
        colour = colours[pi % len(colours)]
        pts = []
        for mi, method in enumerate(methods):
            sel = [r for r in rows if r["preset"] == preset and row_label(r) == method]
            if not sel:
                continue
            xs = [plot_time_ms(r) for r in sel]
            ys = [r["error_pct"] for r in sel]
            pts += list(zip(xs, ys))
            ax.scatter(xs, ys, color=colour, marker=markers[mi % len(markers)], s=40,
                       label=f"{preset} / {method}")
            mixed = any("gpu_ms" in r for r in rows)
            for r, x, y in zip(sel, xs, ys):
                wall = " wall" if mixed and "gpu_ms" not in r else ""
                ax.annotate(_point_label(r) + wall, (x, y), textcoords="offset points", xytext=(4, 3), fontsize=7)
        front = _pareto(pts)
        if len(front) > 1:
            ax.plot(*zip(*front), color=colour, linewidth=1, alpha=0.6)
    ax.set_xscale("log")
    errors = [r["error_pct"] for r in rows if r["error_pct"] > 0]
    if errors and max(errors) / min(errors) > 30.0:
        ax.set_yscale("log")  # e.g. a uniform sun map at several % next to warped maps at 0.02 %
    timed = sum("gpu_ms" in r for r in rows)
    if timed == len(rows):
        ax.set_xlabel("GPU time per frame, ms (log; median, all stages; timer queries)")
    elif timed:
        ax.set_xlabel("time per frame, ms (log; median, all stages): GPU time (timer queries) where "
                      "measured, wall time for the rows marked 'wall'")
    else:
        ax.set_xlabel("time per frame, ms (log; median, all stages; wall)")
    ax.set_ylabel("error % of evaluated pixels vs Cycles")
    ax.set_title("Shadow error against time (lines: Pareto front per preset)")
    ax.grid(True, which="both", alpha=0.3)
    # Outside the axes: with many methods an inside legend hides the points.
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), ncol=1 if len(presets) * len(methods) <= 24 else 2)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return True


def plot_time_ms(row: Row) -> float:
    """A row's time on the Pareto plot: the GPU's total where timer queries measured it (the
    work itself, not the host's waits), the wall total otherwise."""
    gpu = row.get("gpu_ms")
    return float(gpu["total"]) if gpu else float(row["time_ms"]["total"])


def write_frame_plot(rows: Sequence[dict], path: Path) -> bool:
    """A shot's error % against frame, one line per light and method (as labelled, with
    its resolution). Drawn only for rows of two frames or more; False otherwise, or
    where matplotlib is missing."""
    framed = [r for r in rows if "frame" in r]
    if len({r["frame"] for r in framed}) < 2:
        return False
    try:
        import matplotlib
    except ImportError:
        log.warning("matplotlib is not installed: %s not drawn (the table and results.json are)", path.name)
        return False

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lines: dict[tuple, list[tuple[int, float]]] = {}
    for r in framed:
        res = f" @{r['resolution']}" if "resolution" in r else ""
        name = (r["preset"], r.get("light", ""), r.get("camera", ""), row_label(r) + res)
        lines.setdefault(name, []).append((r["frame"], r["error_pct"]))
    several = {k: len({name[k] for name in lines}) > 1 for k in range(3)}
    fig, ax = plt.subplots(figsize=(11, 6.0), dpi=110)
    for name, points in sorted(lines.items()):
        points.sort()
        label = " / ".join(part for k, part in enumerate(name) if part and (k == 3 or several[k]))
        ax.plot([f for f, _ in points], [e for _, e in points], marker="o", markersize=3, linewidth=1, label=label)
    ax.set_xlabel("frame")
    ax.set_ylabel("error % of evaluated pixels vs Cycles")
    ax.set_title("Shadow error over the shot (one line per light and method)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), ncol=1 if len(lines) <= 24 else 2)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return True
