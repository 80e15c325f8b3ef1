"""The report over a shot (addon/report.py): the table grouped by frame and light, with the
shot's columns, and the plot of error against frame (only for two frames or more)."""
from __future__ import annotations

from types import SimpleNamespace

from addon.report import grouped, markdown_table, write_frame_plot
from addon.core.rows import make_row, row_key


def _row(method: str, frame: int | None = None, light: str | None = None, error: float = 0.1) -> dict:
    figure = SimpleNamespace(error_pct=error, false_shadow_pct=error, false_lit_pct=0.0, evaluated_pixels=100)
    shot = {key: value for key, value in (("frame", frame), ("light", light)) if value is not None}
    return make_row("shot", method, "omni", figure, {"total": 1.0}, "llvmpipe", "moderngl", 1, (16, 12),
                    resolution=256, **shot)


def test_the_table_groups_a_shot_by_frame_and_light():
    rows = [_row("dpsm", 9, "rim"), _row("dpsm", 1, "rim"), _row("exact", 9, "key"), _row("dpsm", 9, "key")]
    assert [(r["frame"], r["light"], r["method"]) for r in grouped(rows)] == [
        (1, "rim", "dpsm"), (9, "key", "exact"), (9, "key", "dpsm"), (9, "rim", "dpsm")]
    table = markdown_table(rows).splitlines()
    assert table[0].startswith("| preset | frame | light | method | res |")
    assert table[2].startswith("| shot | 1 | rim | dpsm | 256 |")
    # A preset's table has no shot columns, and its rows keep their order.
    assert markdown_table([_row("cube"), _row("dpsm")]).splitlines()[0].startswith("| preset | method | res |")


def test_rows_of_a_shot_are_told_apart_by_frame_and_light():
    assert row_key(_row("dpsm", 1, "key")) != row_key(_row("dpsm", 9, "key")) != row_key(_row("dpsm", 9, "rim"))
    assert row_key(_row("dpsm")) == ("shot", "dpsm", 256)  # rows without them keep their old key
    assert row_key(_row("dpsm", 9, "key")) == ("shot", "dpsm", 256, ("frame", 9), ("light", "key"))


def test_the_frame_plot_needs_two_frames(tmp_path):
    assert not write_frame_plot([_row("dpsm", 1, "key"), _row("dpsm", 1, "rim")], tmp_path / "one.png")
    assert not (tmp_path / "one.png").exists()
    assert write_frame_plot([_row("dpsm", 1, "key"), _row("dpsm", 9, "key", 0.2)], tmp_path / "two.png")
    assert (tmp_path / "two.png").stat().st_size > 1000
