"""`omniwarp compare --blend FILE` on a saved scene that was never a preset."""
from __future__ import annotations

import json
import math

import pytest

pytest.importorskip("bpy", reason="--blend needs bpy (scripts/setup_env.sh installs it)")
pytestmark = [pytest.mark.blender, pytest.mark.gl, pytest.mark.slow]

from tests.support.cli_run import make_blend, run_python  # noqa: E402


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    folder = tmp_path_factory.mktemp("blends")
    with_light, no_light = folder / "user.blend", folder / "dark.blend"
    for path, extra in ((with_light, []), (no_light, ["--no-light"])):
        make_blend(path, *extra)
    return with_light, no_light


def test_compare_runs_on_a_saved_blend(blends, tmp_path):
    """Every schema field filled, finite; the .blend itself is left untouched on disk."""
    path = blends[0]
    before = path.read_bytes()
    out = tmp_path / "out"
    proc = run_python("-m", "addon", "compare", "--blend", str(path), "--methods", "dpsm,cube", "--resolutions", "512",
                      "--frames", "1", "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = json.loads((out / "results.json").read_text())
    assert [r["method"] for r in rows] == ["dpsm", "cube"]
    for row in rows:
        assert row["preset"] == "user" and row["evaluated_pixels"] > 3000
        assert all(math.isfinite(v) for v in row["time_ms"].values())
        assert 0.0 <= row["error_pct"] < 3.0
    assert path.read_bytes() == before


def test_compare_refuses_a_blend_without_light(blends, tmp_path):
    proc = run_python("-m", "addon", "compare", "--blend", str(blends[1]), "--methods", "dpsm", "--resolutions", "256",
                      "--out", str(tmp_path / "out"))
    assert proc.returncode != 0
    assert "light" in proc.stderr.lower()
    assert not (tmp_path / "out" / "results.json").exists()


def test_compare_names_a_missing_camera_or_light(blends, tmp_path):
    proc = run_python("-m", "addon", "compare", "--blend", str(blends[0]), "--camera", "NoSuchCamera",
                      "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and "NoSuchCamera" in proc.stderr
    proc = run_python("-m", "addon", "compare", "--blend", str(blends[0]), "--light", "NoSuchLamp",
                      "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and "NoSuchLamp" in proc.stderr
