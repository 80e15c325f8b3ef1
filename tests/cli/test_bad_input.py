"""Broken user scenes: each kind gets a clear error, or is skipped and counted in the row."""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from addon.core import tessellate

pytest.importorskip("bpy", reason="--blend needs bpy (scripts/setup_env.sh installs it)")
pytestmark = [pytest.mark.blender, pytest.mark.gl, pytest.mark.slow]

from tests.support import cli_run  # noqa: E402
from tests.support.cli_run import run_python  # noqa: E402

sys.path.insert(0, str(cli_run.SUPPORT))
import make_blend  # noqa: E402


def _blend(tmp_path: Path, name: str, *flags: str) -> Path:
    return cli_run.make_blend(tmp_path / f"{name}.blend", *flags)


def test_broken_geometry_is_skipped_and_counted(tmp_path):
    """NaN and inf vertices and a zero-area triangle are skipped (3 triangles); a
    non-manifold fan and a face-less object draw normally; no map holds NaN or inf."""
    path = _blend(tmp_path, "broken", "--bad-geometry")
    out = tmp_path / "out"
    proc = run_python("-m", "addon", "compare", "--blend", str(path), "--methods", "dpsm,cube,dpsm+notw",
                      "--resolutions", "512", "--frames", "1", "--no-images", "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-2000:]
    expected = make_blend.BAD_NAN_TRIANGLES + make_blend.BAD_ZERO_AREA_TRIANGLES
    for row in json.loads((out / "results.json").read_text()):
        assert row["skipped_triangles"] == expected, row["method"]
        assert row["nonfinite_texels"] == 0
        assert all(math.isfinite(v) for v in row["time_ms"].values())
        assert math.isfinite(row["error_pct"]) and row["error_pct"] < 2.0


@pytest.mark.parametrize("flags,needle", [
    (("--zero-energy",), "emits nothing"),
    (("--light-type", "SUN"), "no requested method fits the light"),  # a sun takes sm and psm, not dpsm
    (("--no-light",), "spot, sun or area light"),
])
def test_unusable_lights_are_named(tmp_path, flags, needle):
    """Status 2 and one line (the exit contract), before the Cycles render starts."""
    path = _blend(tmp_path, "light", *flags)
    proc = run_python("-m", "addon", "compare", "--blend", str(path), "--methods", "dpsm", "--resolutions", "256",
                      "--out", str(tmp_path / "out"))
    lines = [line for line in proc.stderr.splitlines() if line.strip() and "EGL_BAD" not in line]
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert len(lines) == 1 and needle in lines[0], lines
    assert not (tmp_path / "out").exists()


def test_float_max_vertex_counts_as_infinite():
    """Blender stores an inf coordinate as FLT_MAX; it must not set the scene's scale."""
    big = float(np.finfo(np.float32).max)
    tris = np.array([[[0, 0, -1], [1, 0, -1], [0, 1, -1]],
                     [[0, 0, -2], [big, 0, -2], [0, 1, -2]]], dtype=np.float64)
    kept, report = tessellate.sanitize(tris, np.zeros(3), scale=10.0)
    assert len(kept) == 1 and report.nonfinite == 1
