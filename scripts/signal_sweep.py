"""How soon `omniwarp compare` ends on a signal sent at any moment of its start.

    python scripts/signal_sweep.py [--signal SIGINT|SIGTERM] [--from 0.25] [--to 4] [--step 0.25]
                                   [--rounds 1] [-- COMPARE ARGS...]

Each run: `omniwarp compare --preset all --methods dpsm --resolutions 256` (or the
arguments after `--`) with an empty reference cache and a fresh --out, the signal sent
t seconds after the start, t from --from to --to by --step. Prints a markdown table: t,
the exit status, the seconds from the signal to the end, the stderr lines after the
signal's, whether a traceback appeared, what --out holds, and the last line.
"""
from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def one_run(delay: float, sig: signal.Signals, args: list[str]) -> dict:
    work = Path(tempfile.mkdtemp(prefix="signal_sweep_"))
    try:
        env = dict(os.environ, OMNIWARP_CACHE=str(work / "cache"))
        out = work / "out"
        proc = subprocess.Popen([sys.executable, "-c", "import sys; from addon.launch import main; sys.exit(main())",
                                 "compare", *args, "--out", str(out)], cwd=REPO, env=env, text=True,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        time.sleep(delay)
        sent = time.perf_counter()
        proc.send_signal(sig)
        try:
            _, stderr = proc.communicate(timeout=300)
            took = time.perf_counter() - sent
        except subprocess.TimeoutExpired:
            proc.kill()
            _, stderr = proc.communicate()
            took = float("inf")
        lines = [line for line in stderr.splitlines() if line.strip() and "EGL" not in line and " | " not in line]
        return {"t": delay, "status": proc.returncode, "took": took, "traceback": "Traceback" in stderr,
                "out": sorted(p.name for p in out.iterdir()) if out.exists() else [],
                "last": lines[-1] if lines else ""}
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--signal", default="SIGINT", choices=("SIGINT", "SIGTERM"))
    parser.add_argument("--from", dest="start", type=float, default=0.25)
    parser.add_argument("--to", dest="stop", type=float, default=4.0)
    parser.add_argument("--step", type=float, default=0.25)
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args(argv)
    compare_args = extra or ["--preset", "all", "--methods", "dpsm", "--resolutions", "256"]
    sig = signal.Signals[args.signal]
    print("| t (s) | status | s to the end | traceback | --out holds | last line |")
    print("|---|---|---|---|---|---|")
    worst = 0.0
    for _ in range(args.rounds):
        steps = int(round((args.stop - args.start) / args.step)) + 1
        for index in range(steps):
            run = one_run(args.start + index * args.step, sig, compare_args)
            worst = max(worst, run["took"])
            print(f"| {run['t']:.2f} | {run['status']} | {run['took']:.2f} | {'yes' if run['traceback'] else 'no'} | "
                  f"{', '.join(run['out']) or 'nothing'} | `{run['last']}` |", flush=True)
    print(f"\nslowest end: {worst:.2f} s after the signal")
    return 0


if __name__ == "__main__":
    sys.exit(main())
