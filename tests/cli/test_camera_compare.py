"""`omniwarp compare --blend` with cameras that are not centred perspective ones: the
reference keeps the file's camera, the pipeline plans with its real frustum, and psm
with an orthographic camera falls back to sm."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("bpy", reason="--blend needs bpy (scripts/setup_env.sh installs it)")
pytestmark = [pytest.mark.blender, pytest.mark.gl, pytest.mark.slow]

from tests.support.cli_run import SUPPORT, run_python  # noqa: E402


def _compare(tmp_path: Path, kind: str, methods: str, resolution: int = 512) -> list[dict]:
    blend = tmp_path / f"{kind}.blend"
    proc = run_python(SUPPORT / "make_camera_blend.py", blend, kind)
    assert proc.returncode == 0 and blend.is_file(), proc.stderr[-2000:]
    out = tmp_path / kind
    proc = run_python("-m", "addon", "compare", "--blend", blend, "--methods", methods, "--resolutions", resolution,
                      "--frames", "1", "--no-images", "--out", out)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads((out / "results.json").read_text())


def test_ortho_camera_compare_falls_back_to_sm_for_psm(tmp_path):
    # A coarse map, so that the error is not zero and telling the rows apart means something.
    rows = {r["method"]: r for r in _compare(tmp_path, "ortho", "sm,psm", resolution=64)}
    assert rows["sm"]["camera_size"] == [80, 96]  # 50 % of 160x192
    for row in rows.values():
        assert row["evaluated_pixels"] > 1000 and 0.0 < row["error_pct"] < 3.0
    assert rows["psm"]["error_pct"] == rows["sm"]["error_pct"]  # the same uniform map


def test_shifted_camera_compare_culls_and_stays_accurate(tmp_path):
    rows = {r["method"]: r for r in _compare(tmp_path, "shifted", "dpsm,cube,ipsm+cut")}
    for row in rows.values():
        assert row["evaluated_pixels"] > 3000 and 0.0 <= row["error_pct"] < 3.0, row
    assert len(rows["cube"]["layers"]) < 6  # the shifted frustum leaves a face out
