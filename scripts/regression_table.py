"""Row-by-row error of two `omniwarp compare` runs, against a regression bound.

    python scripts/regression_table.py BEFORE/results.json AFTER/results.json [--factor 1.05] [--points 0.003]

Prints a markdown table of every row both runs have (preset, method, resolution): the
error % before and after, the bound factor * before + points, and whether the row keeps
to it; then a summary line. Exit status 1 when any row exceeds its bound. Both runs must
use the same Cycles references for the figures to be comparable.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _rows(path: Path) -> dict[tuple, dict]:
    return {(r["preset"], r["method"], r["resolution"], r.get("cull", True)): r
            for r in json.loads(path.read_text())}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--factor", type=float, default=1.05)
    parser.add_argument("--points", type=float, default=0.003)
    args = parser.parse_args(argv)
    before, after = _rows(args.before), _rows(args.after)
    shared = sorted(set(before) & set(after))
    if not shared:
        print(f"regression_table: {args.before} and {args.after} share no row", file=sys.stderr)
        return 2
    print("| preset | method | res | error % before | error % after | bound | kept |")
    print("|---|---|---|---|---|---|---|")
    over = better = worse = 0
    for key in shared:
        old, new = before[key]["error_pct"], after[key]["error_pct"]
        bound = args.factor * old + args.points
        kept = new <= bound
        over += not kept
        better += new < old
        worse += new > old
        print(f"| {key[0]} | {key[1]} | {key[2]} | {old:.4f} | {new:.4f} | {bound:.4f} | {'yes' if kept else 'NO'} |")
    print(f"\n{len(shared)} rows: {better} lower, {worse} higher, {len(shared) - better - worse} equal; "
          f"{over} over the bound {args.factor:g} x before + {args.points:g} points.")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
