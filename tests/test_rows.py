"""The typed results row (addon/core/rows.py) and how the report shows it."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

from addon import report
from addon.core.rows import make_row, row_key, row_label

FIGURE = SimpleNamespace(error_pct=0.1, false_shadow_pct=0.06, false_lit_pct=0.04, evaluated_pixels=1000)


def _map_row(**columns):
    return make_row("room_omni", "exact", "omni", FIGURE, {"total": 9.0, "prepare": 1.0, "analysis": 2.0,
                                                           "shadow_maps": 5.0, "shadow_test": 1.0},
                    "llvmpipe", "moderngl", 3, (640, 480), resolution=1024, passes=2, **columns)


def test_columns_that_do_not_apply_are_absent():
    eevee = make_row("room_omni", "eevee", "omni", FIGURE, {"total": 1500.0, "warmup": 9000.0}, "EEVEE", "eevee", 1,
                     (640, 480), eevee_setting="fine", passes=None)
    assert "resolution" not in eevee and "passes" not in eevee
    assert row_label(eevee) == "eevee (fine)" and row_key(eevee) == ("room_omni", "eevee (fine)", None)
    line = report.markdown_table([eevee]).splitlines()[-1]
    assert line.startswith("| room_omni | eevee (fine) |  | 0.100 |")  # no map resolution, no placeholder
    with pytest.raises(KeyError, match="not a results column: res"):
        make_row("p", "dpsm", "omni", FIGURE, {"total": 1.0}, "r", "b", 1, (8, 8), res=512)


def test_a_row_keeps_its_method_columns_and_labels_its_work():
    row = _map_row(cull=False, list_entries=2_500_000)
    assert row["resolution"] == 1024 and row["passes"] == 2 and row_label(row) == "exact (no cull)"
    assert report._point_label(row) == "1024 (2.5M entries)"
    assert report._point_label(_map_row()) == "1024"


def test_the_exact_rows_work_gets_its_own_table(tmp_path):
    row = _map_row(list_longest=9361, list_mean=312.5, list_fragments=6_370_739, list_entries=3_686_400,
                   list_cut=420, list_rounds=1, list_moved_entries=1_762_860)
    table = report.list_table([row, _map_row()])
    assert table.splitlines()[-1] == ("| room_omni | exact | 1024 | 9361 | 312.50 | 6,370,739 | 3,686,400 | 420 | 1 "
                                      "| 1,762,860 |")
    assert len(table.splitlines()) == 3  # the row without list columns has no line
    assert report.list_table([_map_row()]) == ""
    report.write_markdown([row], tmp_path / "report.md", "now")
    assert "walks moved on" in (tmp_path / "report.md").read_text()
