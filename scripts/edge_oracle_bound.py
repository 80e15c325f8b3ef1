"""What could a warp give if it knew where the shadow edges are? (study for issue 3)

A count-driven warp spreads texels evenly over the view samples
(`scripts/ideal_warp_bound.py` bounds what that can give). But shadow-map errors sit
on shadow edges only, so an importance that knew the edges could put texels there.
This script gives the warps that knowledge by cheating: it weights the view samples
within R pixels of a shadow edge *of the Cycles reference itself* by K
(`ViewSamples.importance`), and measures the warped methods against plain maps at the
same and at twice the resolution.

No real importance knows the edges this well; a detector would have to find them
from a first, coarser shadow pass, and miss some. So these errors bound from below
what an edge importance could give with the NoTW and RTW warps as built.

Run:
  .venv/bin/python scripts/edge_oracle_bound.py --preset room_omni,courtyard \\
      --resolution 1024 --weights 8,32 --radius 2 --out docs/results/edge_oracle
It writes OUT/results.json and OUT/report.md (with the renderer and the date).
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.compare import light_from_reference, samples_from_reference  # noqa: E402
from addon.core import metrics  # noqa: E402
from addon.core.methods import method as method_entry  # noqa: E402
from addon.reference.cache import load_or_capture  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from addon.render.backends.moderngl.backend import ModernGLBackend  # noqa: E402
from addon.render.pipeline import ShadowPipeline, settings_for  # noqa: E402

WARPED = ("dpsm+notw", "dpsm+rtw", "cube+notw", "cube+rtw")


def shadow_edge_band(lit: np.ndarray, radius: int) -> np.ndarray:
    """Pixels within `radius` (4-neighbour steps) of a change of `lit` between neighbours."""
    band = np.zeros_like(lit)
    across = lit[:, 1:] != lit[:, :-1]
    down = lit[1:] != lit[:-1]
    band[:, 1:] |= across
    band[:, :-1] |= across
    band[1:] |= down
    band[:-1] |= down
    for _ in range(radius):
        grown = band.copy()
        grown[1:] |= band[:-1]
        grown[:-1] |= band[1:]
        grown[:, 1:] |= band[:, :-1]
        grown[:, :-1] |= band[:, 1:]
        band = grown
    return band


def measure(pipeline: ShadowPipeline, ref: ReferenceData, reference_lit: np.ndarray, evaluable: np.ndarray,
            method: str, resolution: int, importance: np.ndarray | None) -> dict:
    """One frame of `method` (the errors are deterministic; no timing is taken here)."""
    samples = replace(samples_from_reference(ref), importance=importance)
    result = pipeline.render(light_from_reference(ref), ref.triangles.astype(np.float64), samples,
                             settings_for(method, resolution))
    figure = metrics.error_figure(result.visibility > 0.5, reference_lit, evaluable)
    return {"method": method, "resolution": resolution, "error_pct": figure.error_pct,
            "false_shadow_pct": figure.false_shadow_pct, "false_lit_pct": figure.false_lit_pct,
            "triangles_drawn": result.geometry.triangles_drawn}


def run(presets: list[str], resolution: int, weights: list[int], radius: int, methods: list[str]) -> tuple[list, str]:
    """Rows for every preset: the plain maps at 1x and 2x, each warped method with
    plain counts and with each edge weight; and the renderer string."""
    rows: list[dict] = []
    backend = ModernGLBackend()
    try:
        pipeline = ShadowPipeline(backend)
        for preset in presets:
            ref = load_or_capture(preset, (640, 480))
            light = light_from_reference(ref)
            evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
            reference_lit = metrics.reference_visibility(ref.shadowed, ref.unshadowed)
            band = shadow_edge_band(reference_lit & evaluable, radius) & ref.hit
            share = float(band.sum() / max(int(ref.hit.sum()), 1))

            def row(method: str, res: int, importance: np.ndarray | None) -> dict:
                return measure(pipeline, ref, reference_lit, evaluable, method, res, importance)

            for plain in sorted({method_entry(m).parameterization for m in methods}):
                for res in (resolution, 2 * resolution):
                    rows.append({"preset": preset, "importance": "counts", **row(plain, res, None)})
            for method in methods:
                rows.append({"preset": preset, "importance": "counts", **row(method, resolution, None)})
                for k in weights:
                    importance = np.where(band, float(k), 1.0)
                    rows.append({"preset": preset, "importance": f"edges x{k}", "edge_share": share,
                                 **row(method, resolution, importance)})
                    print(f"{preset} {method} {resolution} edges x{k}: {rows[-1]['error_pct']:.3f} %", flush=True)
        renderer = backend.renderer()
    finally:
        backend.release()
    return rows, renderer


def report(rows: list[dict], renderer: str, command: str, radius: int) -> str:
    """The markdown table of `rows`, with the date, the renderer and the command."""
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [
        "# Edge-oracle bound for the warps",
        "",
        f"Written by `scripts/edge_oracle_bound.py` on {stamp}, renderer `{renderer}`, 640x480 Cycles references.",
        "",
        f"Command: `{command}`",
        "",
        f"`edges xK`: view samples within {radius} pixels of a shadow edge of the Cycles reference weigh K in",
        "the warp analysis (the oracle); `counts`: the plain count map, as `omniwarp compare` runs it.",
        "One frame per row; error % over the evaluated pixels.",
        "",
        "| preset | method | resolution | importance | edge share | error % | false shadow % | false lit % | triangles |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        share = f"{r['edge_share']:.3f}" if "edge_share" in r else ""
        lines.append(f"| {r['preset']} | {r['method']} | {r['resolution']} | {r['importance']} | {share} | "
                     f"{r['error_pct']:.3f} | {r['false_shadow_pct']:.3f} | {r['false_lit_pct']:.3f} | "
                     f"{r['triangles_drawn']} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="room_omni", help="comma-separated preset names")
    parser.add_argument("--resolution", type=int, default=1024)
    parser.add_argument("--weights", default="8,32", help="comma-separated edge weights K")
    parser.add_argument("--radius", type=int, default=2, help="edge band half-width in pixels")
    parser.add_argument("--methods", default=",".join(WARPED[:3]))
    parser.add_argument("--out", type=Path, default=Path("out/edge_oracle"))
    args = parser.parse_args(argv)
    methods = [m for m in args.methods.split(",") if m]
    unknown = [m for m in methods if m not in WARPED]
    if unknown:
        parser.error(f"not a warped method: {', '.join(unknown)}; choose from {', '.join(WARPED)}")
    weights = [int(k) for k in args.weights.split(",") if k]
    rows, renderer = run([p for p in args.preset.split(",") if p], args.resolution, weights, args.radius, methods)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "results.json").write_text(json.dumps(rows, indent=1))
    command = "scripts/edge_oracle_bound.py " + " ".join(argv if argv is not None else sys.argv[1:])
    (args.out / "report.md").write_text(report(rows, renderer, command, args.radius))
    print(f"wrote {args.out / 'report.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
