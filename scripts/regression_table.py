"""Row-by-row error (or times) of two `omniwarp compare` runs, against a regression bound.

    python scripts/regression_table.py BEFORE/results.json AFTER/results.json [--factor 1.05] [--points 0.003]
    python scripts/regression_table.py BEFORE/results.json AFTER/results.json --times

Prints a markdown table of every row both runs have (preset, method, resolution): the
error % before and after, the bound factor * before + points, and whether the row keeps
to it; then a summary line. Exit status 1 when any row exceeds its bound. Both runs must
use the same Cycles references for the figures to be comparable. `--times` prints the
stage times (total, prepare, maps) and the error before and after instead.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.core.rows import row_key  # noqa: E402  (what tells two rows of one run apart)


class TableError(Exception):
    """A results file that cannot be read as compare's rows."""


def _rows(path: Path) -> dict[tuple, dict]:
    try:
        rows = json.loads(path.read_text())
        return {row_key(r): r for r in rows}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise TableError(f"{path}: not a compare results.json ({exc.__class__.__name__}: {exc})") from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--factor", type=float, default=1.05)
    parser.add_argument("--points", type=float, default=0.003)
    parser.add_argument("--times", action="store_true", help="print stage times instead of the bound")
    args = parser.parse_args(argv)
    try:
        before, after = _rows(args.before), _rows(args.after)
    except TableError as exc:
        print(f"regression_table: {exc}", file=sys.stderr)
        return 2
    shared = [key for key in after if key in before]  # in the after run's order
    if not shared:
        print(f"regression_table: {args.before} and {args.after} share no row", file=sys.stderr)
        return 2
    if args.times:
        _times(before, after, shared)
        return 0
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
        print(f"| {key[0]} | {key[1]} | {_res(key)} | {old:.4f} | {new:.4f} | {bound:.4f} | {'yes' if kept else 'NO'} |")
    print(f"\n{len(shared)} rows: {better} lower, {worse} higher, {len(shared) - better - worse} equal; "
          f"{over} over the bound {args.factor:g} x before + {args.points:g} points.")
    return 1 if over else 0


def _times(before: dict, after: dict, shared: list) -> None:
    print("| preset | method | res | total ms before | total ms after | prepare ms before | prepare ms after "
          "| maps ms before | maps ms after | error % before | error % after |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for key in shared:
        old, new = before[key], after[key]
        t0, t1 = old["time_ms"], new["time_ms"]
        print(f"| {key[0]} | {key[1]} | {_res(key)} | {t0['total']:.0f} | {t1['total']:.0f} | {_ms(t0, 'prepare', '.1f')} "
              f"| {_ms(t1, 'prepare', '.1f')} | {_ms(t0, 'shadow_maps', '.0f')} | {_ms(t1, 'shadow_maps', '.0f')} "
              f"| {old['error_pct']:.3f} | {new['error_pct']:.3f} |")


def _res(key: tuple) -> str:
    """The row's map resolution, blank for an EEVEE row (it has none)."""
    return "" if key[2] is None else str(key[2])


def _ms(times: dict, stage: str, spec: str) -> str:
    """A stage's time, blank where the row has no such stage (an EEVEE row)."""
    return format(times[stage], spec) if stage in times else ""


if __name__ == "__main__":
    sys.exit(main())
