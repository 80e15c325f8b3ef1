"""Packaging: the built zip installs and enables in Blender, and settings survive .blend files.

Every bpy session runs in a child process (tests/support/extension_worker.py),
so neither bpy state nor Blender's user config leaks into pytest. Each child
gets its own BLENDER_USER_RESOURCES (Blender puts config/, scripts/,
extensions/ and datafiles/ under it), so nothing is installed into the real
~/.config/blender; the worker refuses to run if bpy ignores it.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path
from typing import Any

import pytest

from tests.support.checks import expect

pytest.importorskip("bpy", reason="installing the extension needs bpy (scripts/setup_env.sh installs it)")

pytestmark = pytest.mark.blender

REPO_ROOT = Path(__file__).resolve().parents[2]
WORKER = REPO_ROOT / "tests" / "support" / "extension_worker.py"
BUILD_SCRIPT = REPO_ROOT / "scripts" / "build_extension.sh"
REPORT_MARKER = "OMNIWARP_REPORT "
ADDON_MODULE = "bl_ext.user_default.omniwarp_shadows"
USER_DIR_OVERRIDES = ("BLENDER_USER_CONFIG", "BLENDER_USER_SCRIPTS", "BLENDER_USER_EXTENSIONS",
                      "BLENDER_USER_DATAFILES")


def _manifest() -> dict[str, Any]:
    with (REPO_ROOT / "blender_manifest.toml").open("rb") as fh:
        return tomllib.load(fh)


def _isolated_env(user_root: Path) -> dict[str, str]:
    """This process's environment with Blender's user folders moved under `user_root`."""
    user_root.mkdir(parents=True, exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k not in USER_DIR_OVERRIDES}
    env["BLENDER_USER_RESOURCES"] = str(user_root)
    return env


def _worker(task: str, path: Path, user_root: Path) -> dict[str, Any]:
    """Run one worker task in a fresh interpreter; its JSON report."""
    proc = subprocess.run(
        [sys.executable, str(WORKER), task, str(path)],
        cwd=user_root.parent,  # not the repo: the installed copy must not be shadowed by ./addon
        env=_isolated_env(user_root),
        capture_output=True,
        text=True,
        timeout=120,
    )
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"worker {task} failed ({proc.returncode}):\n{output}"
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(REPORT_MARKER)]
    assert len(lines) == 1, f"worker {task} printed no report:\n{output}"
    return json.loads(lines[0][len(REPORT_MARKER):])


def _close(a: Any, b: Any) -> bool:
    """Equal, with float32 rounding allowed for floats (RNA floats are float32)."""
    if isinstance(a, float) or isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-6)
    return a == b


# ---------------------------------------------------------------------------
# build + install
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def extension_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The zip built by scripts/build_extension.sh, into a temporary folder.

    setup_env.sh is skipped (OMNIWARP_SKIP_SETUP=1): pytest already runs in the
    environment it builds, and the tool is taken from this interpreter's bpy.
    """
    bash = shutil.which("bash")
    if bash is None:
        pytest.skip("bash is needed to run scripts/build_extension.sh")
    dist = tmp_path_factory.mktemp("dist")
    env = dict(os.environ, OMNIWARP_SKIP_SETUP="1", OMNIWARP_DIST_DIR=str(dist), OMNIWARP_EXT_PYTHON=sys.executable)
    proc = subprocess.run([bash, str(BUILD_SCRIPT)], cwd=REPO_ROOT, env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    # stdout is exactly the zip's path; everything else went to stderr.
    assert proc.stdout.count("\n") == 1, proc.stdout
    archive = Path(proc.stdout.strip())
    manifest = _manifest()
    assert archive == dist / f"{manifest['id']}-{manifest['version']}.zip"
    assert archive.is_file()
    return archive


def test_build_script_makes_installable_zip(extension_zip: Path) -> None:
    """The script's zip has the manifest and the package entry point at its top level."""
    names = set(zipfile.ZipFile(extension_zip).namelist())
    assert {"blender_manifest.toml", "__init__.py", "addon/blender/registration.py"} <= names
    assert not any(n.startswith(("tests/", "scripts/")) for n in names)


def test_build_script_reports_missing_tool(tmp_path: Path) -> None:
    """Without bpy the script stops with a clear message instead of a traceback."""
    bash = shutil.which("bash")
    if bash is None:
        pytest.skip("bash is needed to run scripts/build_extension.sh")
    fake_python = tmp_path / "python"
    # An interpreter that cannot find bpy: this one, in isolated mode, without site-packages.
    fake_python.write_text(f'#!/bin/sh\nexec "{sys.executable}" -I -S "$@"\n')
    fake_python.chmod(0o755)
    env = dict(os.environ, OMNIWARP_SKIP_SETUP="1", OMNIWARP_DIST_DIR=str(tmp_path / "dist"),
               OMNIWARP_EXT_PYTHON=str(fake_python))
    proc = subprocess.run([bash, str(BUILD_SCRIPT)], cwd=REPO_ROOT, env=env, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode != 0
    assert proc.stdout == ""
    assert "blender_ext.py" in proc.stderr and "was not found" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr


def test_zip_installs_enables_and_disables(extension_zip: Path, tmp_path: Path) -> None:
    """Install from Disk + enable, use the settings, disable: nothing left registered."""
    user_root = tmp_path / "blender_user"
    report = _worker("install", extension_zip, user_root)

    # Isolation: every user folder, the repository and the installed files are in tmp.
    assert all(Path(p).is_relative_to(user_root.resolve()) for p in report["user_paths"].values()), report
    assert Path(report["repo_directory"]).is_relative_to(user_root.resolve())
    assert report["install_result"] == ["FINISHED"]
    expect(report, "installed_manifest")
    # Blender imported the installed copy, not this checkout.
    assert Path(report["module_file"]).is_relative_to(Path(report["repo_directory"])), report["module_file"]

    enabled = report["after_install"]
    expect(enabled, "enabled", "light_pointer", "scene_pointer", "light_panel", stage="after install",
           module=ADDON_MODULE)

    light = report["light_readback"]
    assert (light["parameterization"], light["warp"], light["resolution"]) == ("CUBE", "NOTW", 2048)
    assert light["enabled"] is False and light["emission"] == "AUTO"  # untouched settings keep defaults
    assert report["resolution_clamped"] == 4096  # RNA clamps to the property's max

    assert report["disable_result"] == ["FINISHED"]
    disabled = report["after_disable"]
    # light_pointer: bpy.types.Light.omniwarp must not survive addon_disable.
    expect(disabled, "not enabled", "not light_pointer", "not scene_pointer", "not light_panel",
           stage="after addon_disable", module=ADDON_MODULE)
    assert disabled["handlers"] == [], f"handlers left after disable: {disabled['handlers']}"

    # Enabling again works, and the light's stored settings come back with the pointer.
    again = report["after_reenable"]
    expect(again, "enabled", "light_pointer", stage="after enabling again", module=ADDON_MODULE)
    assert sorted(again["handlers"]) == sorted(enabled["handlers"])
    assert report["light_after_reenable"] == light
    final = report["after_second_disable"]
    expect(final, "not enabled", "not light_pointer", stage="after the second addon_disable", module=ADDON_MODULE)
    assert final["handlers"] == [], f"handlers left after the second disable: {final['handlers']}"


# ---------------------------------------------------------------------------
# properties round-trip through save and reload of a .blend
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    """A .blend saved with non-default settings, and the save worker's report."""
    folder = tmp_path_factory.mktemp("roundtrip")
    blend = folder / "omniwarp_settings.blend"
    report = _worker("save", blend, folder / "blender_user_save")
    assert blend.is_file()
    return blend, report


def _assert_same_settings(got: dict[str, Any], want: dict[str, Any], where: str) -> None:
    for owner in ("lights", "scenes"):
        assert set(got[owner]) == set(want[owner]), f"{where}: {owner} {sorted(got[owner])} != {sorted(want[owner])}"
        for name, values in want[owner].items():
            lost = {k: (v, got[owner][name].get(k)) for k, v in values.items()
                    if not _close(got[owner][name].get(k), v)}
            assert not lost, f"{where}: {name} changed (wanted, got): {lost}"


def test_properties_round_trip_through_save_and_reload(saved: tuple[Path, dict[str, Any]]) -> None:
    """Every light and scene setting set before saving reads back the same after reopening."""
    _blend, report = saved
    assert report["same_as_default"] == [], "a round trip of default values proves nothing"
    _assert_same_settings(report["before_save"], report["wanted"], "after setting")

    # A different file really replaced the data: no lights, factory scene settings.
    home = report["after_homefile"]
    assert home["lights"] == []
    for name, values in home["scene_settings"].items():
        assert all(_close(values[k], v) for k, v in home["scene_defaults"].items()), (name, values)

    # Exact equality: the same float32 values must come back from the file.
    assert report["after_reopen"] == report["before_save"]

    # Registration stays across file loads: pointers and (persistent) handlers.
    expect(home, "light_pointer", stage="after loading the empty home file")
    assert report["pointers_after_reopen"] == {"light": True, "scene": True}
    assert report["handlers_after_reopen"] == report["handlers_registered"]


def test_blend_opens_without_addon_then_register_restores(saved: tuple[Path, dict[str, Any]], tmp_path: Path) -> None:
    """Opening the file with the add-on unregistered works; registering afterwards shows the stored values."""
    blend, saved_report = saved
    report = _worker("reopen", blend, tmp_path / "blender_user_reopen")
    assert report["pointer_before"] is False
    assert report["open_result"] == ["FINISHED"]
    before = saved_report["before_save"]
    assert set(before["lights"]) <= set(report["lights"])

    # Blender keeps the unregistered group's values as raw ID properties
    # (enums as their integer values): every setting is there.
    raw = report["raw_unregistered"]
    for owner in ("lights", "scenes"):
        for name, values in before[owner].items():
            stored = raw[owner].get(name)
            assert stored is not None, f"{name}: no stored omniwarp settings in the file"
            assert set(stored) == set(values), f"{name}: stored {sorted(stored)}, expected {sorted(values)}"

    assert report["after_register"] == before
