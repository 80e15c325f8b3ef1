"""blender_manifest.toml: parses, has what Blender requires, and builds the right zip.

The structural checks need only tomllib. The last two run Blender's own
extension tool (`blender_ext.py`, shipped inside the PyPI bpy package under
`bpy/<version>/scripts/addons_core/bl_pkg/cli/`), the code behind
`blender --command extension validate|build`, with Blender's list of valid tags.
"""
from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent
MANIFEST = REPO_ROOT / "blender_manifest.toml"
REQUIRED_KEYS = (
    "schema_version", "id", "version", "name", "tagline", "maintainer",
    "type", "blender_version_min", "license",
)


def _version(text: str) -> tuple[int, ...]:
    return tuple(int(p) for p in text.split("."))


def _excludes(patterns: list[str], folder: str) -> bool:
    """True when a pattern excludes the top-level `folder` (as `folder/` or `/folder/`)."""
    return any(p.strip("/") == folder and p.endswith("/") for p in patterns)


@pytest.fixture(scope="module")
def manifest() -> dict:
    with MANIFEST.open("rb") as fh:
        return tomllib.load(fh)


def test_manifest_required_keys(manifest: dict) -> None:
    missing = [k for k in REQUIRED_KEYS if k not in manifest]
    assert not missing, f"blender_manifest.toml lacks {missing}"
    assert manifest["schema_version"] == "1.0.0"
    assert manifest["id"] == "omniwarp_shadows"
    assert re.fullmatch(r"[a-z][a-z0-9_]*", manifest["id"])
    assert manifest["type"] == "add-on"
    assert all(lic.startswith("SPDX:") for lic in manifest["license"])


def test_manifest_tagline(manifest: dict) -> None:
    tagline = manifest["tagline"]
    assert 0 < len(tagline) <= 64
    assert tagline[-1].isalnum(), "Blender rejects a tagline ending in punctuation"


def test_manifest_versions(manifest: dict, repo_root: Path) -> None:
    assert _version(manifest["blender_version_min"]) >= (4, 2, 0)
    with (repo_root / "pyproject.toml").open("rb") as fh:
        project = tomllib.load(fh)["project"]
    assert manifest["version"] == project["version"], "keep the manifest and pyproject versions in step"


def test_manifest_build_excludes_dev_folders(manifest: dict) -> None:
    patterns = manifest["build"]["paths_exclude_pattern"]
    for folder in ("tests", "docs", "scripts", ".ci", ".venv", ".cache", "out"):
        assert _excludes(patterns, folder), f"[build] paths_exclude_pattern must exclude {folder}/"
    assert "__pycache__/" in patterns


def _blender_ext_tool() -> tuple[Path, Path]:
    """Paths of Blender's `blender_ext.py` and its `tags.py`, from the installed bpy package."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        pytest.skip("bpy is not installed")
    for location in spec.submodule_search_locations:
        for tool in sorted(Path(location).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py")):
            scripts = tool.parents[3]
            tags = scripts / "modules" / "_bpy_internal" / "extensions" / "tags.py"
            if tags.is_file():
                return tool, tags
    pytest.skip("this bpy has no bl_pkg/cli/blender_ext.py")


def _run_tool(*args: str) -> subprocess.CompletedProcess[str]:
    tool, tags = _blender_ext_tool()
    return subprocess.run(
        [sys.executable, str(tool), *args, "--valid-tags", str(tags)],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.blender
def test_manifest_passes_blender_validate() -> None:
    """`blender --command extension validate` (strict, with Blender's tag list) accepts the repo."""
    proc = _run_tool("validate", str(REPO_ROOT))
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.blender
def test_extension_build_contents(tmp_path: Path) -> None:
    """`blender --command extension build` ships the add-on and leaves the dev files out."""
    proc = _run_tool("build", "--source-dir", str(REPO_ROOT), "--output-dir", str(tmp_path))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (archive,) = tmp_path.glob("omniwarp_shadows-*.zip")
    names = zipfile.ZipFile(archive).namelist()
    for required in ("blender_manifest.toml", "__init__.py", "addon/__init__.py",
                     "addon/blender/registration.py"):
        assert required in names, f"{required} missing from the extension zip"
    for folder in ("presets", "gpu_shaders"):
        if any((REPO_ROOT / folder).rglob("*.*")):
            assert any(n.startswith(folder + "/") for n in names), f"{folder}/ missing from the zip"
    # Every shader file ships, whatever its extension (.vert, .frag, .comp, .glsl).
    shaders = {p.relative_to(REPO_ROOT).as_posix() for p in (REPO_ROOT / "gpu_shaders").rglob("*") if p.is_file()}
    assert shaders and shaders <= set(names), f"shader files missing from the zip: {sorted(shaders - set(names))}"
    dev = ("tests/", "docs/", "scripts/", ".ci/", ".venv/", ".cache/", "out/", ".git")
    leaked = [n for n in names if n.startswith(dev) or "__pycache__" in n or n.endswith(".pyc")]
    leaked += [n for n in names if n in ("pyproject.toml", "README.md")]
    assert not leaked, f"development files in the extension zip: {leaked}"
