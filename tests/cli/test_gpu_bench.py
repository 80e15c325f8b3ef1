"""`scripts/gpu_bench.sh`: references prepared with bpy here, then measured with numpy and moderngl only."""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

pytest.importorskip("bpy", reason="preparing the references renders them with Cycles")
pytestmark = [pytest.mark.blender, pytest.mark.gl, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
# Makes bpy, matplotlib and OpenEXR unimportable, as on a bare GPU machine.
BARE_SITE = """import sys
for name in ("bpy", "matplotlib", "OpenEXR"):
    sys.modules[name] = None
"""


def test_the_bench_runs_bare_from_prepared_references(tmp_path):
    env = dict(os.environ, OMNIWARP_CACHE=str(tmp_path / "refs"), PRESETS="room_omni", METHODS="dpsm,cube+notw",
               RESOLUTIONS="512", FRAMES="1", SIZE="160x120", FLOOR_FRAMES="3", OUT=str(tmp_path / "out"))
    prepared = subprocess.run(["bash", "scripts/gpu_bench.sh", "prepare"], cwd=REPO, env=env,
                              capture_output=True, text=True, timeout=600)
    assert prepared.returncode == 0, prepared.stderr[-2000:]
    assert len(list((tmp_path / "refs").glob("room_omni_160x120_*.npz"))) == 1
    site = tmp_path / "bare"
    site.mkdir()
    (site / "sitecustomize.py").write_text(BARE_SITE)
    env["PYTHONPATH"] = str(site)
    measured = subprocess.run(["bash", "scripts/gpu_bench.sh"], cwd=REPO, env=env, capture_output=True, text=True,
                              timeout=600)
    assert measured.returncode == 0, measured.stderr[-2000:]
    rows = json.loads((tmp_path / "out" / "results.json").read_text())
    assert [(r["preset"], r["method"], r["resolution"]) for r in rows] == [("room_omni", "dpsm", 512),
                                                                            ("room_omni", "cube+notw", 512)]
    assert all(0.0 <= r["error_pct"] < 5.0 for r in rows)
    # The bare run drew its plot with the built-in painter (matplotlib's PNGs name it).
    plot = (tmp_path / "out" / "error_vs_time.png").read_bytes()
    assert plot.startswith(b"\x89PNG") and b"matplotlib" not in plot.lower()
    assert "| room_omni | cube+notw | 512 |" in (tmp_path / "out" / "report.md").read_text()
    # The floor benchmark and the steady frame's traffic ran bare too.
    assert "| cube+notw |" in (tmp_path / "out" / "floor.md").read_text()
    assert "| room_omni | cube+notw | 1 |" in (tmp_path / "out" / "traffic.md").read_text()
