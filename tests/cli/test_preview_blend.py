"""`omniwarp preview --blend FILE`, and the preview's method handling (the registry of
`addon/core/methods.py`): the light's saved OmniWarp settings, the default method,
cut and edge AA reaching the pipeline, refusals in the parent, and the help texts."""
from __future__ import annotations

import importlib.util
import json
import math
import re
import subprocess
from pathlib import Path

import pytest

from addon.cli import main
from addon.core import methods as method_registry
from tests.support.cli_run import make_blend, run_python

# Saved on the light of the first test file; differs from the preview's default
# (dpsm+notw at --resolution) in method and resolution, so the test sees which was used.
SAVED_METHOD, SAVED_RESOLUTION = "cube+notw", 512
PREVIEW_RESOLUTION = "256"  # for the lights without settings: small keeps CI quick

needs_blender = [
    pytest.mark.blender,
    pytest.mark.gl,
    pytest.mark.slow,
    pytest.mark.skipif(importlib.util.find_spec("bpy") is None,
                       reason="--blend needs bpy (scripts/setup_env.sh installs it)"),
]


def _preview(blend: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return run_python("-m", "addon", "preview", "--blend", str(blend), "--out", str(out),
                      "--resolution", PREVIEW_RESOLUTION, *extra)


@pytest.fixture(scope="module")
def blends(tmp_path_factory) -> dict[str, Path]:
    """Two small saved scenes (160x120 camera): one whose light has OmniWarp settings, one without."""
    folder = tmp_path_factory.mktemp("preview_blends")
    paths = {"settings": folder / "with_settings.blend", "plain": folder / "plain.blend"}
    flags = {"settings": ["--omniwarp", f"{SAVED_METHOD}:{SAVED_RESOLUTION}"], "plain": []}
    for kind, path in paths.items():
        make_blend(path, *flags[kind])
    return paths


def _report(out: Path) -> dict:
    """preview.json, after checking that the three files exist and the error is measured."""
    for name in ("preview.png", "overlay.png", "preview.json"):
        assert (out / name).is_file(), name
    report = json.loads((out / "preview.json").read_text())
    assert math.isfinite(report["error_pct"]) and report["evaluated_pixels"] > 0
    assert len(report["lights"]) == 1
    return report


def blender_test(fn):
    """Apply the bpy/GL marks to a test."""
    for mark in needs_blender:
        fn = mark(fn)
    return fn


@blender_test
def test_preview_uses_the_lights_saved_settings(blends, tmp_path):
    """Loading the file reads the light's OmniWarp settings (registered once, after the load)."""
    before = blends["settings"].read_bytes()
    out = tmp_path / "out"
    proc = _preview(blends["settings"], out)
    assert proc.returncode == 0, proc.stderr[-2000:]
    light = _report(out)["lights"][0]
    entry = method_registry.method(SAVED_METHOD)
    assert (light["method"], light["parameterization"], light["warp"], light["resolution"]) == (
        SAVED_METHOD, entry.parameterization, entry.warp, SAVED_RESOLUTION)
    assert blends["settings"].read_bytes() == before  # nothing saved back


@blender_test
def test_preview_of_a_blend_without_settings_uses_the_default(blends, tmp_path):
    out = tmp_path / "out"
    proc = _preview(blends["plain"], out)
    assert proc.returncode == 0, proc.stderr[-2000:]
    light = _report(out)["lights"][0]
    default = method_registry.method(method_registry.default_method(light["emission"]))
    assert (light["method"], light["parameterization"], light["warp"]) == (
        default.name, default.parameterization, default.warp)
    assert light["resolution"] == int(PREVIEW_RESOLUTION)


@blender_test
@pytest.mark.parametrize("method", ["ipsm+cut", "unfold+aa"])
def test_preview_method_options_reach_the_pipeline(blends, tmp_path, method):
    """The skewed cut and edge AA are part of the method, not dropped on the way to the child."""
    out = tmp_path / "out"
    proc = _preview(blends["plain"], out, "--method", method)
    assert proc.returncode == 0, proc.stderr[-2000:]
    light = _report(out)["lights"][0]
    entry = method_registry.method(method)
    assert (light["method"], light["parameterization"], light["cut"], light["edge_aa"]) == (
        method, entry.parameterization, entry.cut, entry.edge_aa)


def _one_line_refusal(proc: subprocess.CompletedProcess, needle: str) -> None:
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()], proc.stderr
    assert needle in proc.stderr


@pytest.mark.parametrize("method,needle", [("eevee", "eevee"), ("bogus", "unknown method 'bogus'"),
                                           ("psm", "does not fit")])
def test_preview_refuses_a_method_before_rendering(tmp_path, method, needle):
    """Unknown, external (eevee) or unfit (psm for room_omni's point light): exit 2 in the
    parent, one line, before any Cycles render (no bpy needed)."""
    out = tmp_path / "out"
    proc = run_python("-m", "addon", "preview", "--preset", "room_omni", "--method", method, "--out", str(out))
    _one_line_refusal(proc, needle)
    assert not (out / "preview.json").exists()


@blender_test
def test_preview_refuses_unfit_methods_for_a_blend(blends, tmp_path):
    """eevee is refused before the file is even loaded; psm for its point light once the
    light is known, before the child process draws anything."""
    out = tmp_path / "out"
    _one_line_refusal(_preview(blends["plain"], out, "--method", "eevee"), "eevee")
    proc = _preview(blends["plain"], out, "--method", "psm")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert "psm does not fit an omni light" in proc.stderr.strip().splitlines()[-1]
    assert not (out / "preview.json").exists()


def _help(command: str, capsys) -> str:
    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    assert stop.value.code == 0
    return " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("command", ["compare", "preview"])
def test_help_names_every_method(command, capsys):
    """The method lists of --help come from the registry, so none is missing."""
    text = _help(command, capsys)
    for name in method_registry.names():
        assert re.search(rf"(?<![\w+]){re.escape(name)}(?![\w+])", text), f"{command} --help lacks {name}"


def test_every_pipeline_method_builds_its_settings():
    """settings_for carries the entry's parameterization and warp for each light it fits (exact:
    sm for spot and sun lights), its cut, edge AA and exact pass; the external methods have none."""
    from addon.core.errors import InputError
    from addon.render.pipeline import settings_for

    for name in method_registry.pipeline_methods():
        entry = method_registry.method(name)
        for emission in entry.emissions:
            settings = settings_for(name, 256, emission, cull=False)
            assert (settings.parameterization, settings.warp, settings.cut, settings.edge_aa, settings.exact,
                    settings.cull) == (entry.parameterization_for(emission), entry.warp_for(emission), entry.cut,
                                       entry.edge_aa, entry.exact, False)
            assert method_registry.label_for(settings.parameterization, settings.warp, settings.cut,
                                             settings.edge_aa, settings.exact) == name
    for name in method_registry.external_methods():
        with pytest.raises(InputError):
            settings_for(name, 256)
