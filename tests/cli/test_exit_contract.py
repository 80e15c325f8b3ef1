"""The exit contract, through the command line as a user runs it: bad input or a bad
environment exits with status 2 and ONE line naming the problem, before any long work
starts, and leaves the user's files as they were; result lines alone go to stdout."""
from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from addon.core.errors import EXIT_BAD_INPUT, InputError, one_line, report_error
from addon.core.scene import LightSpec, translation
from addon.render.pipeline import BiasSettings, ShadowSettings

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
from cli_run import env_with, make_blend, omniwarp, staging_left, tree_digest  # noqa: E402
from cli_run import one_line as refused  # noqa: E402

SMALL = ("--size", "160x120", "--frames", "1", "--no-images", "--resolutions", "512")
# A row's line; moderngl's rows end with the GPU's own ms (timer queries).
ROW = re.compile(r"^\S+\s+\S+\s+\d+\s+error\s+[\d.]+ %\s+total\s+[\d.]+ ms\s+passes \d+(\s+GPU\s+[\d.]+ ms)?$")
FLT_MAX = float(np.finfo(np.float32).max)


@pytest.fixture
def earlier_results(tmp_path: Path) -> Path:
    """An output folder holding an earlier run's files (which no refused run may touch)."""
    out = tmp_path / "out"
    (out / "images").mkdir(parents=True)
    (out / "results.json").write_text("[]\n")
    (out / "report.md").write_text("# earlier report\n")
    (out / "images" / "old_mismatch.png").write_bytes(b"old")
    return out


def test_help_states_the_exit_contract():
    for args in ((), ("compare",), ("preview",), ("reference",)):
        proc = omniwarp(*args, "--help")
        assert proc.returncode == 0
        text = " ".join(proc.stdout.split())
        for phrase in ("0 done", "2 bad input or environment", "130 interrupted", "1 a bug"):
            assert phrase in text, (args, phrase)


def test_a_usage_error_is_one_line():
    line = refused(omniwarp("compare", "--methods", "dpsm"))
    assert line.startswith("omniwarp compare: error:") and "--preset --blend is required" in line


def _probe_text_blend(tmp: Path) -> tuple[list[str], str]:
    (tmp / "notes.blend").write_text("these are my notes, not a scene\n")
    return ["--blend", str(tmp / "notes.blend")], "is not a .blend file"


def _probe_out_is_a_file(tmp: Path) -> tuple[list[str], str]:
    (tmp / "afile").write_text("keep me\n")
    return ["--preset", "room_omni", "--out", str(tmp / "afile")], "that is a file, not a folder"


def _probe_out_under_a_file(tmp: Path) -> tuple[list[str], str]:
    (tmp / "afile").write_text("keep me\n")
    return ["--preset", "room_omni", "--out", str(tmp / "afile" / "sub")], "is a file, so no folder can be made"


def _probe_frames(tmp: Path) -> tuple[list[str], str]:
    return ["--preset", "room_omni", "--frames", "0"], "bad --frames 0"


def _probe_methods_misfit(tmp: Path) -> tuple[list[str], str]:
    return ["--preset", "sun_field", "--methods", "dpsm,cube"], "no requested method fits the light of sun_field"


@pytest.mark.parametrize("probe", [_probe_text_blend, _probe_out_is_a_file, _probe_out_under_a_file,
                                   _probe_frames, _probe_methods_misfit])
def test_bad_compare_input_is_one_line_before_any_work(probe, tmp_path, earlier_results):
    """No Blender needed: each is refused with one line, nothing rendered (an empty
    cache stays empty), and the files named stay as they were."""
    cache = tmp_path / "cache"
    args, needle = probe(tmp_path)
    before = tree_digest(tmp_path)
    defaults = {"--out": str(earlier_results), "--size": "160x120", "--frames": "1", "--resolutions": "512"}
    args += [item for key, value in defaults.items() if key not in args for item in (key, value)]
    proc = omniwarp("compare", *args, "--no-images", env=env_with(OMNIWARP_CACHE=cache))
    line = refused(proc)
    assert line.startswith("omniwarp: error:") and needle in line, line
    assert tree_digest(tmp_path) == before
    assert not cache.exists() and staging_left(tmp_path) == []


def test_an_unwritable_cache_is_one_line(tmp_path):
    """OMNIWARP_CACHE under a file: refused before the render, naming the variable."""
    (tmp_path / "afile").write_text("")
    proc = omniwarp("reference", "--preset", "room_hemi", "--size", "40x30",
                    env=env_with(OMNIWARP_CACHE=tmp_path / "afile" / "cache"))
    line = refused(proc)
    assert "reference cache folder" in line and "OMNIWARP_CACHE" in line


def _read_only_prefix(folder: Path) -> tuple[str, ...]:
    """Run the command with `folder` read-only: a read-only bind mount for root (who may
    write anywhere), else the folder's mode. Skips where neither can be arranged."""
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return ()
    script = 'mount --bind "$0" "$0" && mount -o remount,ro,bind "$0" "$0" && shift && exec "$@"'
    prefix = ("unshare", "-m", "--propagation", "private", "sh", "-c", script, str(folder), "_")
    if shutil.which("unshare") is None or subprocess.run([*prefix, "true"], capture_output=True).returncode != 0:
        pytest.skip("running as root and no mount namespace for a read-only folder")
    return prefix


def test_a_read_only_out_folder_is_refused_before_any_row(tmp_path, earlier_results):
    """The folder is checked first: no row is measured, no results.json appears beside
    the old report.md, and nothing is rendered (the empty cache stays empty)."""
    before = tree_digest(earlier_results)
    prefix = _read_only_prefix(earlier_results)
    try:
        proc = omniwarp("compare", "--preset", "room_omni", *SMALL, "--out", earlier_results, prefix=prefix,
                        env=env_with(OMNIWARP_CACHE=tmp_path / "cache"))
    finally:
        earlier_results.chmod(0o755)
    line = refused(proc)
    assert "no write permission" in line and str(earlier_results) in line
    assert tree_digest(earlier_results) == before and not (tmp_path / "cache").exists()


def test_the_pipeline_entry_refuses_settings_that_cannot_be_drawn():
    """NaN, inf and Blender's FLT_MAX (what it stores for inf) in a bias or a light
    position are refused by name, where every caller passes."""
    for value in (float("nan"), float("inf"), FLT_MAX, -1.0):
        with pytest.raises(InputError, match="bias normal"):
            ShadowSettings("dpsm", 512, bias=BiasSettings(normal=value))
    with pytest.raises(InputError, match="light's transform"):
        LightSpec("omni", translation((float("nan"), 0.0, 3.0)))
    with pytest.raises(InputError, match="light's energy"):
        LightSpec("omni", np.eye(4), energy=float("inf"))
    assert BiasSettings(constant=0.0, slope=4.0, normal=1.5).slope == 4.0


def test_report_error_prints_one_line(capsys):
    assert report_error("omniwarp", InputError("first\nsecond")) == EXIT_BAD_INPUT
    assert capsys.readouterr().err == "omniwarp: error: first; second\n"
    assert one_line("a\n\n b ") == "a; b"


# ----------------------------------------------------------------------------
# with Blender: a user's .blend
# ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def blends(tmp_path_factory) -> dict[str, Path]:
    """A good .blend, one cut short, one with a NaN light and one whose light has a
    NaN bias saved in its OmniWarp settings."""
    pytest.importorskip("bpy", reason="--blend needs bpy (scripts/setup_env.sh installs it)")
    folder = tmp_path_factory.mktemp("blends")
    good = make_blend(folder / "good.blend")
    (folder / "cut.blend").write_bytes(good.read_bytes()[:20000])
    return {
        "good": good,
        "cut": folder / "cut.blend",
        "nan_light": make_blend(folder / "nan_light.blend", "--light-location", "nan,0,3"),
        "nan_bias": make_blend(folder / "nan_bias.blend", "--omniwarp", "dpsm:512", "--bias-constant", "nan"),
    }


@pytest.mark.blender
@pytest.mark.slow
@pytest.mark.parametrize("command,blend,needle", [
    ("compare", "cut", "Blender cannot load it (Missing DNA block)"),
    ("compare", "nan_light", "its transform is not finite (location nan, 0, 3)"),
    ("preview", "nan_light", "its transform is not finite (location nan, 0, 3)"),
    ("preview", "nan_bias", "bias constant is nan"),
])
def test_a_bad_blend_is_one_line_before_the_render(blends, tmp_path, earlier_results, command, blend, needle):
    """A truncated file, a NaN light position or a NaN bias: status 2, one line, no
    Cycles render (the line comes before it), earlier results untouched."""
    before = tree_digest(earlier_results)
    extra = SMALL if command == "compare" else ("--size", "160x120")
    proc = omniwarp(command, "--blend", blends[blend], *extra, "--out", earlier_results,
                    env=env_with(OMNIWARP_CACHE=tmp_path / "cache"))
    line = refused(proc)
    assert needle in line and "rendering" not in proc.stderr
    assert tree_digest(earlier_results) == before and staging_left(tmp_path) == []


@pytest.mark.blender
@pytest.mark.gl
@pytest.mark.slow
def test_stdout_holds_the_result_rows_only(blends, tmp_path):
    """`omniwarp compare --blend F > rows.txt`: Blender's "Read blend" and "Saved:" lines
    (written from C to fd 1) go to stderr's side, never between the rows."""
    out = tmp_path / "out"
    proc = omniwarp("compare", "--blend", blends["good"], "--methods", "dpsm,cube", *SMALL, "--out", out,
                    env=env_with(OMNIWARP_CACHE=tmp_path / "cache"))
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = proc.stdout.splitlines()
    assert len(rows) == 2 and all(ROW.match(line) for line in rows), rows
    assert "Saved:" not in proc.stdout and "Read blend" not in proc.stdout
    results = json.loads((out / "results.json").read_text())
    assert [r["method"] for r in results] == ["dpsm", "cube"]
    assert all(math.isfinite(r["error_pct"]) and r["evaluated_pixels"] > 1000 for r in results)
