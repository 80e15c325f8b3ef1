"""scripts/regression_table.py: the row-by-row bound between two compare runs."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

from tests.support.cli_run import REPO, run_python

SCRIPT = REPO / "scripts" / "regression_table.py"


def _row(method: str, error: float, total: float = 10.0) -> dict:
    return {"preset": "room_omni", "method": method, "resolution": 1024, "cull": True, "error_pct": error,
            "time_ms": {"total": total, "prepare": 1.0, "shadow_maps": 5.0}}


def _table(tmp_path: Path, before: list[dict], after: list[dict], *flags: str) -> subprocess.CompletedProcess:
    (tmp_path / "before.json").write_text(json.dumps(before))
    (tmp_path / "after.json").write_text(json.dumps(after))
    return run_python(SCRIPT, tmp_path / "before.json", tmp_path / "after.json", *flags)


def test_rows_within_the_bound_pass_and_one_over_fails(tmp_path):
    before = [_row("dpsm", 0.100), _row("cube", 0.040)]
    ok = _table(tmp_path, before, [_row("dpsm", 0.107), _row("cube", 0.030)])
    assert ok.returncode == 0, ok.stdout
    assert "0 over the bound" in ok.stdout and "1 lower, 1 higher" in ok.stdout
    over = _table(tmp_path, before, [_row("dpsm", 0.109), _row("cube", 0.040)])  # bound 1.05 * 0.1 + 0.003 = 0.108
    assert over.returncode == 1
    assert "| room_omni | dpsm | 1024 | 0.1000 | 0.1090 | 0.1080 | NO |" in over.stdout


def test_times_table_and_no_shared_rows(tmp_path):
    times = _table(tmp_path, [_row("dpsm", 0.1, total=200.0)], [_row("dpsm", 0.1, total=50.0)], "--times")
    assert times.returncode == 0 and "| room_omni | dpsm | 1024 | 200 | 50 |" in times.stdout
    none = _table(tmp_path, [_row("dpsm", 0.1)], [_row("cube", 0.1)])
    assert none.returncode == 2 and "share no row" in none.stderr


def test_a_missing_file_is_one_line(tmp_path):
    proc = run_python(SCRIPT, tmp_path / "none.json", tmp_path / "none.json")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "not a compare results.json" in proc.stderr
