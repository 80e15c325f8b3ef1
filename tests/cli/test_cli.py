"""The `omniwarp` command: bad input and an end-to-end compare at a small size."""
from __future__ import annotations

import json
import math

import pytest

from addon.cli import main
from addon.core.errors import EXIT_BAD_INPUT
from tests.support.cli_run import run_python

ROW_FIELDS = {
    "preset": str, "method": str, "emission": str, "resolution": int, "error_pct": float,
    "false_shadow_pct": float, "false_lit_pct": float, "evaluated_pixels": int, "time_ms": dict,
    "passes": int, "triangles_drawn": int, "texels": int, "renderer": str, "backend": str,
}
TIME_FIELDS = ("total", "analysis", "shadow_maps", "shadow_test")


@pytest.mark.parametrize("argv,needle", [
    (["compare", "--preset", "no_such_room"], "unknown preset 'no_such_room'"),
    (["compare", "--preset", "room_omni", "--resolutions", "1024,abc"], "bad resolution 'abc'"),
    (["compare", "--preset", "room_omni", "--resolutions", "7"], "bad resolution 7"),
    (["compare", "--preset", "room_omni", "--methods", "dpsm,warp9"], "unknown method 'warp9'"),
    (["compare", "--blend", "/nonexistent/scene.blend"], "--blend file not found: /nonexistent/scene.blend"),
    (["compare", "--preset", "room_omni", "--size", "640by480"], "bad size '640by480'"),
    (["compare", "--preset", "room_omni", "--light", "Lamp"], "--light and --camera apply to --blend only"),
    (["reference", "--preset", "nowhere"], "unknown preset 'nowhere'"),
])
def test_bad_input_names_the_problem(argv, needle, capsys, tmp_path):
    """Each bad input exits with status 2 and a one-line message naming it; nothing is written."""
    out = tmp_path / "out"
    code = main(argv + (["--out", str(out)] if argv[0] == "compare" else []))
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT
    assert needle in err
    assert not out.exists()


def test_presets_lists_the_foundation_presets(capsys):
    assert main(["presets"]) == 0
    text = capsys.readouterr().out
    for name in ("room_omni", "room_hemi", "courtyard"):
        assert name in text
    assert "stresses:" in text


def test_console_entry_point_exits_nonzero_on_bad_input():
    """The module entry (`python -m addon`) gives the same non-zero exit as main()."""
    proc = run_python("-m", "addon", "compare", "--preset", "nope", timeout=120)
    assert proc.returncode == EXIT_BAD_INPUT
    assert "unknown preset 'nope'" in proc.stderr


@pytest.mark.blender
@pytest.mark.gl
def test_compare_end_to_end_small(tmp_path, monkeypatch, capsys, reference_cache):
    """Cycles reference + both methods at a small size: every output exists, every field is filled."""
    pytest.importorskip("bpy", reason="the reference capture needs bpy (scripts/setup_env.sh installs it)")
    monkeypatch.setenv("OMNIWARP_CACHE", str(reference_cache))
    out = tmp_path / "report"
    code = main(["compare", "--preset", "room_hemi", "--methods", "dpsm,cube", "--resolutions", "128,512",
                 "--size", "160x120", "--frames", "1", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    rows = json.loads((out / "results.json").read_text())
    assert len(rows) == 4
    for row in rows:
        for key, kind in ROW_FIELDS.items():
            assert isinstance(row[key], kind), (key, row[key])
        for key in TIME_FIELDS:
            assert math.isfinite(row["time_ms"][key]) and row["time_ms"][key] >= 0.0
        for key in ("error_pct", "false_shadow_pct", "false_lit_pct"):
            assert math.isfinite(row[key]) and 0.0 <= row[key] <= 100.0
        assert math.isclose(row["error_pct"], row["false_shadow_pct"] + row["false_lit_pct"], abs_tol=1e-9)
        assert row["evaluated_pixels"] > 1000
        assert (out / row["mismatch_image"]).is_file()
    by_method = {(r["method"], r["resolution"]): r for r in rows}
    # Hemispherical light: one paraboloid side, at most five cube faces.
    assert by_method[("dpsm", 512)]["passes"] == 1
    assert by_method[("cube", 512)]["passes"] <= 5
    # More texels, fewer mismatches (generous: a method-level property).
    for method in ("dpsm", "cube"):
        assert by_method[(method, 512)]["error_pct"] < by_method[(method, 128)]["error_pct"]
    report = (out / "report.md").read_text()
    assert "renderer:" in report and "| room_hemi | dpsm | 512 |" in report
    assert (out / "error_vs_time.png").stat().st_size > 10_000
