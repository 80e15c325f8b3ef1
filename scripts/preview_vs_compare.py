"""`preview --method M` against `compare` for every method that fits a scene's light.

    .venv/bin/python scripts/preview_vs_compare.py (--preset NAME | --blend FILE [--light L])
        [--resolution 1024] [--out DIR]

Runs one `compare` over every fitting pipeline method (moderngl, the Cycles samples)
and one `preview` per method (Blender's gpu, its own G-buffer), then writes
DIR/preview_vs_compare.md with both errors and their ratio.
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from addon.core import methods as registry  # noqa: E402


def _omniwarp(*args: str) -> None:
    proc = subprocess.run([sys.executable, "-m", "addon", *args], cwd=REPO, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"omniwarp {' '.join(args)} failed (exit {proc.returncode}):\n{proc.stderr[-2000:]}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--preset")
    source.add_argument("--blend")
    parser.add_argument("--light")
    parser.add_argument("--emission", default="omni", help="the light's kind: omni, hemi, spot or sun")
    parser.add_argument("--resolution", default="1024")
    parser.add_argument("--out", default="out/preview_vs_compare")
    args = parser.parse_args()
    out = Path(args.out).resolve()
    scene = ["--preset", args.preset] if args.preset else ["--blend", str(Path(args.blend).resolve())]
    scene += ["--light", args.light] if args.light else []
    names = list(registry.fitting(args.emission, pipeline_only=True))
    _omniwarp("compare", *scene, "--methods", ",".join(names), "--resolutions", args.resolution,
              "--no-images", "--out", str(out / "compare"))
    rows = {r["method"]: r for r in json.loads((out / "compare" / "results.json").read_text())}
    lines = [f"# preview against compare ({dt.datetime.now(dt.timezone.utc):%Y-%m-%d %H:%M UTC})", "",
             f"- scene: `{' '.join(scene).replace(str(REPO) + '/', '')}`, maps at {args.resolution}",
             f"- renderer: {next(iter(rows.values()))['renderer']}", "",
             "| method | compare error % | preview error % | preview / compare |", "|---|---|---|---|"]
    for name in names:
        target = out / name.replace("+", "_")
        _omniwarp("preview", *scene, "--method", name, "--resolution", args.resolution, "--out", str(target))
        preview = json.loads((target / "preview.json").read_text())["error_pct"]
        error = rows[name]["error_pct"]
        ratio = f"{preview / error:.2f}" if error > 0 else "-"
        lines.append(f"| {name} | {error:.3f} | {preview:.3f} | {ratio} |")
        print(lines[-1], flush=True)
    (out / "preview_vs_compare.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
