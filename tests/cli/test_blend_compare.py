"""`omniwarp compare --blend FILE` on a saved scene that was never a preset."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("bpy", reason="--blend needs bpy (scripts/setup_env.sh installs it)")
pytestmark = [pytest.mark.blender, pytest.mark.gl]

SUPPORT = Path(__file__).resolve().parents[1] / "support"
REPO = Path(__file__).resolve().parents[2]


def _run(*args: str, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=600, cwd=REPO, env=env)


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    folder = tmp_path_factory.mktemp("blends")
    with_light, no_light = folder / "user.blend", folder / "dark.blend"
    for path, extra in ((with_light, []), (no_light, ["--no-light"])):
        proc = _run(str(SUPPORT / "make_blend.py"), str(path), *extra)
        assert proc.returncode == 0 and path.is_file(), proc.stderr[-2000:]
    return with_light, no_light


def test_compare_runs_on_a_saved_blend(blends, tmp_path):
    """Every schema field filled, finite; the .blend itself is left untouched on disk."""
    path = blends[0]
    before = path.read_bytes()
    out = tmp_path / "out"
    proc = _run("-m", "addon", "compare", "--blend", str(path), "--methods", "dpsm,cube", "--resolutions", "512",
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
    proc = _run("-m", "addon", "compare", "--blend", str(blends[1]), "--methods", "dpsm", "--resolutions", "256",
                "--out", str(tmp_path / "out"))
    assert proc.returncode != 0
    assert "light" in proc.stderr.lower()
    assert not (tmp_path / "out" / "results.json").exists()


def test_compare_names_a_missing_camera_or_light(blends, tmp_path):
    proc = _run("-m", "addon", "compare", "--blend", str(blends[0]), "--camera", "NoSuchCamera",
                "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and "NoSuchCamera" in proc.stderr
    proc = _run("-m", "addon", "compare", "--blend", str(blends[0]), "--light", "NoSuchLamp",
                "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and "NoSuchLamp" in proc.stderr
