"""`compare --blend` and `preview --blend` on the feature scene (tests/support/feature_scene.py), as a user runs them.

The scene has every case of the shadow rule and of the camera reading. Against the
naive reading the errors here would be several percent (the no-shadow box alone
covers about 1 % of the evaluated pixels, see tests/blender/test_shadow_rule.py).
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("bpy", reason="--blend needs bpy (scripts/setup_env.sh installs it)")
pytestmark = [pytest.mark.blender, pytest.mark.gl, pytest.mark.slow]

from tests.support.cli_run import SUPPORT, run_python  # noqa: E402
SIZE = "160x120"
# Map errors at this tiny size and 512 texels; a reading that ignores a case is far above.
MAX_ERROR_PCT = 1.0


@pytest.fixture(scope="module")
def blend(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("feature") / "features.blend"
    proc = run_python(str(SUPPORT / "feature_scene.py"), str(path), "--size", SIZE)
    assert proc.returncode == 0 and path.is_file(), proc.stderr[-2000:]
    return path


def _compare(blend: Path, out: Path, *extra: str) -> list[dict]:
    proc = run_python("-m", "addon", "compare", "--blend", str(blend), "--frames", "1", "--no-images",
                      "--out", str(out), *extra)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads((out / "results.json").read_text())


PARTIAL_VIEWS = ("ShiftCam", "OrthoCam")  # cameras whose occluder region leaves triangles out


@pytest.mark.parametrize("camera", ["Camera", "ShiftCam", "OrthoCam"])
def test_every_camera_compares_with_safe_culling(blend, tmp_path, camera):
    """50 % of twice the size, pixel aspect 1.2, shift, vertical fit, ortho: culling changes no pixel."""
    rows = _compare(blend, tmp_path / "out", "--light", "LampA", "--camera", camera,
                    "--methods", "dpsm+notw,cube", "--resolutions", "512", "--cull-both")
    assert {tuple(r["camera_size"]) for r in rows} == {(160, 120)}
    for method in ("dpsm+notw", "cube"):
        culled, full = (next(r for r in rows if r["method"] == method and r["cull"] is cull) for cull in (True, False))
        assert culled["error_pct"] == full["error_pct"], (camera, method)
        assert culled["error_pct"] < MAX_ERROR_PCT, (camera, method, culled["error_pct"])
    # Culling leaves out the geometry outside conv(light, frustum) with the shifted and the
    # ortho camera (ortho views were never culled before); the main camera sees all of
    # it. Each cube face always draws only what lies in front of it, culled or not.
    culled, full = (next(r for r in rows if r["method"] == "cube" and r["cull"] is cull) for cull in (True, False))
    counts = (culled["triangles_drawn"], full["triangles_drawn"])
    assert counts[0] < counts[1] if camera in PARTIAL_VIEWS else counts[0] <= counts[1], counts


@pytest.mark.parametrize("light", ["LampA", "LampB"])
def test_preview_agrees_with_compare(blend, tmp_path, light):
    """preview --blend on each light: within 1.5x the compare row of its method (plus 0.05 points at this size)."""
    rows = _compare(blend, tmp_path / "cmp", "--light", light, "--methods", "dpsm+notw", "--resolutions", "1024")
    out = tmp_path / "preview"
    proc = run_python("-m", "addon", "preview", "--blend", str(blend), "--light", light, "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads((out / "preview.json").read_text())
    assert report["lights"][0]["method"] == "dpsm+notw" and report["gbuffer_hit_agreement"] > 0.99
    assert report["error_pct"] <= 1.5 * rows[0]["error_pct"] + 0.05, (report["error_pct"], rows[0]["error_pct"])
    assert rows[0]["error_pct"] < MAX_ERROR_PCT


def test_a_light_without_shadows_is_lit_everywhere(blend, tmp_path):
    rows = _compare(blend, tmp_path / "out", "--light", "LampC", "--methods", "dpsm,cube", "--resolutions", "512")
    assert all(r["error_pct"] == 0.0 and r["triangles_drawn"] == 0 for r in rows), rows
