"""The Blender `gpu` backend, the viewport's compute path and the headless preview.

Blender's GL and moderngl may not share a process (DESIGN.md section 3), so the
Blender side runs in a child process (tests/support/blender_gpu_worker.py).
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("bpy", reason="the Blender gpu backend needs bpy (scripts/setup_env.sh installs it)")

from addon.cli import main  # noqa: E402
from addon.render.pipeline import ShadowPipeline, ShadowSettings  # noqa: E402
from tests.gl.test_pipeline_extremes import _seam_straddler  # noqa: E402
from tests.support.oracle import view_samples  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.gl]
WORKER = Path(__file__).resolve().parents[1] / "support" / "blender_gpu_worker.py"


def _worker(task: str, out: Path) -> None:
    proc = subprocess.run([sys.executable, str(WORKER), task, str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]


def test_blender_backend_matches_moderngl(gl_backend, tmp_path):
    """Same GLSL, same results: visibility identical, depth maps equal to float32 rounding."""
    out = tmp_path / "blender.npz"
    _worker("backends", out)
    theirs = np.load(out)
    scene = _seam_straddler()
    samples, _, _ = view_samples(scene)
    pipeline = ShadowPipeline(gl_backend)
    for param, warp in (("dpsm", "none"), ("cube", "none"), ("dpsm", "notw"), ("cube", "rtw")):
        ours = pipeline.render(scene.light, scene.world_triangles(), samples, ShadowSettings(param, 256, warp=warp),
                               keep_atlas=True)
        assert np.array_equal(ours.visibility, theirs[f"{param}_{warp}_visibility"]), (param, warp)
        assert np.allclose(ours.atlas, theirs[f"{param}_{warp}_atlas"], atol=1e-6), (param, warp)


def test_viewport_compute_with_explicit_matrices(tmp_path):
    """The viewport's compute path on a registered extension: a cube+NoTW light gives
    shadows, finite maps and an evened count map; unregister removes every handler."""
    out = tmp_path / "viewport.json"
    _worker("viewport", out)
    report = json.loads(out.read_text())
    assert report["lights"] == 1 and report["param"] == "cube" and report["warp"] == "notw"
    assert 1 <= report["passes"] <= 5  # hemispherical light
    assert report["hit_share"] > 0.9 and 0.01 < report["shadowed_share"] < 0.9
    assert report["finite_atlas"]
    assert report["max_after"] <= report["max_before"]
    assert report["handler_installed"] and report["handler_removed"]
    assert report["depsgraph_handlers_restored"] and report["pointer_removed"]


def test_preview_command_writes_images_and_error(tmp_path, monkeypatch, capsys):
    """`omniwarp preview` end to end: the three files, and an error against Cycles like compare's."""
    monkeypatch.setenv("OMNIWARP_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "preview"
    assert main(["preview", "--preset", "room_hemi", "--size", "160x120", "--out", str(out)]) == 0, \
        capsys.readouterr().err
    report = json.loads((out / "preview.json").read_text())
    assert report["backend"] == "blender-gpu" and report["evaluated_pixels"] > 5000
    assert 0.0 <= report["error_pct"] < 2.0
    assert report["gbuffer_hit_agreement"] > 0.99  # the G-buffer sees what Cycles sees
    for key, value in report["time_ms"].items():
        assert math.isfinite(value) and value >= 0.0, key
    light = report["lights"][0]
    assert light["passes"] == 1 and light["parameterization"] == "dpsm"
    import matplotlib.image as mpimg

    preview = mpimg.imread(out / "preview.png")
    overlay = mpimg.imread(out / "overlay.png")
    assert preview.shape[:2] == (120, 160)
    assert preview[..., :3].std() > 0.05  # a shaded picture, not a blank
    assert overlay[..., :3].std() > 0.05


def test_preview_bad_input(tmp_path, capsys):
    assert main(["preview", "--preset", "nope", "--out", str(tmp_path)]) == 2
    assert "unknown preset 'nope'" in capsys.readouterr().err
    assert main(["preview", "--blend", str(tmp_path / "missing.blend"), "--out", str(tmp_path)]) == 2
    assert main(["preview", "--preset", "all", "--out", str(tmp_path)]) == 2
