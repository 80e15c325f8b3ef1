"""The cost of a sweep's job at 1920x1080, and jobs per minute on 1 and 2 local Dask workers,
measured in one run (docs/sweeps.md). Writes OUT/bench.md and OUT/bench.json.

    python scripts/sweep_bench.py [--out docs/results/sweeps] [--jobs 6] [--workers 1,2]

The shot is tests/support/make_shot_blend.py at 1920x1080 (two boxes on a ground, the key
light and the crate animated). Each job is one frame with the key light: its Cycles
reference (2 renders, 1 sample) and the rows `dpsm,exact` at 1024, 1 timed repeat. Every
measurement starts from an empty reference cache, so each job renders Cycles, as the
first sweep of a shot does. The serial run of one job gives the cost of a job; each
cluster run is timed from the command's start to its end (the cluster's start included).
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SIZE = "1920x1080"
ROWS = ["--light", "key", "--methods", "dpsm,exact", "--resolutions", "1024", "--repeats", "1", "--no-images"]
SHOT_FRAMES = 250
SHOT_LIGHTS = 3


def _compare(blend: Path, frames: str, out: Path, cache: Path, extra: list[str]) -> tuple[float, list[dict], str]:
    env = {**__import__("os").environ, "OMNIWARP_CACHE": str(cache), "PYTHONPATH": str(REPO)}
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "addon", "compare", "--blend", str(blend), "--frame-range", frames,
                           *ROWS, *extra, "--out", str(out)], cwd=REPO, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"sweep_bench: compare failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    return seconds, json.loads((out / "results.json").read_text()), proc.stderr


def markdown(result: dict) -> list[str]:
    """bench.md's lines from bench.json's measurements."""
    job, runs = result["job"], result["runs"]
    per_worker = runs[0]["jobs_per_minute"] / runs[0]["workers"]
    return [
        "# A sweep's job at 1920x1080, and jobs per minute on local Dask workers",
        "",
        f"- measured: {result['measured']}, by `{result['command']}`",
        f"- renderer: {job['renderer']}; Cycles on the CPU (2 cores, shared)",
        f"- job: one frame of tests/support/make_shot_blend.py at {result['size']}, the key light; its Cycles "
        "reference (2 renders, 1 sample, from an empty cache) and the rows dpsm and exact at 1024 (1 repeat)",
        "",
        "| one job, serially | seconds |",
        "|---|---|",
        f"| whole command (start, Blender load, reference, rows, outputs) | {job['wall_s']:.1f} |",
        f"| Cycles reference (2 renders) | {job['cycles_reference_s']:.1f} |",
        *(f"| row {method} @1024 (median frame) | {ms / 1000:.2f} |" for method, ms in job["rows_ms"].items()),
        "",
        "| local workers | jobs | seconds, command start to end | jobs per minute |",
        "|---|---|---|---|",
        *(f"| {r['workers']} | {r['jobs']} | {r['wall_s']:.1f} | {r['jobs_per_minute']:.2f} |" for r in runs),
        "",
        f"A {SHOT_FRAMES}-frame shot with {SHOT_LIGHTS} lights is {result['shot_jobs']} jobs. At the rate of one "
        f"worker alone on this machine ({per_worker:.2f} jobs per minute), an hour takes "
        f"{result['workers_for_an_hour']} such workers, each on a machine like this one.",
        "",
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/results/sweeps")
    parser.add_argument("--jobs", type=int, default=6, help="jobs (frames) per cluster run")
    parser.add_argument("--workers", default="1,2")
    parser.add_argument("--rewrite", action="store_true", help="write OUT/bench.md again from OUT/bench.json")
    args = parser.parse_args()
    if args.rewrite:
        result = json.loads((Path(args.out) / "bench.json").read_text())
        (Path(args.out) / "bench.md").write_text("\n".join(markdown(result)), encoding="utf-8")
        return 0
    counts = [int(v) for v in args.workers.split(",")]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="omniwarp_sweep_bench_") as tmp:
        tmp = Path(tmp)
        blend = tmp / "shot.blend"
        subprocess.run([sys.executable, str(REPO / "tests" / "support" / "make_shot_blend.py"), str(blend),
                        "--size", SIZE], cwd=REPO, check=True, capture_output=True)
        # One job, serially: the cost of a job and its parts.
        seconds, rows, stderr = _compare(blend, "1-1", tmp / "one", tmp / "cache_one", [])
        cycles = float(re.search(r"cached in ([0-9.]+) s", stderr)[1])
        job = {"wall_s": round(seconds, 1), "cycles_reference_s": cycles,
               "rows_ms": {r["method"]: round(r["time_ms"]["total"], 1) for r in rows},
               "renderer": rows[0]["renderer"]}
        runs = []
        frames = f"1-{args.jobs}"
        for n in counts:
            seconds, rows, _ = _compare(blend, frames, tmp / f"w{n}", tmp / f"cache_w{n}", ["--workers", str(n)])
            runs.append({"workers": n, "jobs": args.jobs, "rows": len(rows), "wall_s": round(seconds, 1),
                         "jobs_per_minute": round(60.0 * args.jobs / seconds, 2)})
    per_worker = runs[0]["jobs_per_minute"] / runs[0]["workers"]
    shot_jobs = SHOT_FRAMES * SHOT_LIGHTS
    needed = -(-shot_jobs // int(60 * per_worker))  # ceil(750 / jobs one worker does in an hour)
    stamp = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    result = {"measured": stamp, "size": SIZE, "rows_per_job": "dpsm,exact @1024, 1 repeat", "job": job,
              "runs": runs, "shot_jobs": shot_jobs, "workers_for_an_hour": needed, "command":
              "python scripts/sweep_bench.py " + " ".join(sys.argv[1:])}
    (out / "bench.json").write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    lines = markdown(result)
    (out / "bench.md").write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
