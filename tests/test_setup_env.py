"""scripts/setup_env.sh LINE: its choice of line and its one-line errors, run on a copy of the
script in a scratch repository (nothing is installed; no Python is found on purpose)."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
TOOLS = ("dirname", "cat", "rm", "sha256sum", "cut")


@pytest.fixture()
def scratch(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    """A repository holding only the script, and an environment without any Python."""
    repo = tmp_path / "repo"
    (repo / "scripts").mkdir(parents=True)
    shutil.copy(REPO_ROOT / "scripts" / "setup_env.sh", repo / "scripts")
    shutil.copy(REPO_ROOT / "pyproject.toml", repo)
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for tool in TOOLS:
        (bin_dir / tool).symlink_to(shutil.which(tool))
    env = {"PATH": str(bin_dir), "HOME": str(tmp_path), "PYENV_ROOT": str(tmp_path / "no_pyenv"),
           "OMNIWARP_PYTHON_PREFIXES": str(tmp_path / "empty"), "OMNIWARP_SKIP_APT": "1"}
    return repo, env


def _run(repo: Path, env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([shutil.which("bash"), str(repo / "scripts" / "setup_env.sh"), *args], env=env,
                          capture_output=True, text=True, timeout=60)


def _errors(proc: subprocess.CompletedProcess) -> list[str]:
    return [line for line in proc.stderr.splitlines() if line.startswith("setup_env: error:")]


@pytest.mark.parametrize("line, python", [("5.2", "3.13"), ("4.5", "3.11"), ("4.2", "3.11")])
def test_missing_python_is_one_line_with_the_way_to_get_it(scratch, line, python):
    repo, env = scratch
    proc = _run(repo, env, line)
    assert proc.returncode != 0
    errors = _errors(proc)
    assert len(errors) == 1 and len(proc.stderr.strip().splitlines()) <= 2, proc.stderr
    assert f"Python {python}" in errors[0] and f"pyenv install {python}" in errors[0], errors[0]
    assert not (repo / ".venv").exists() and not (repo / f".venv-bpy{line}").exists()


def test_unknown_line_is_refused(scratch):
    repo, env = scratch
    proc = _run(repo, env, "3.6")
    assert proc.returncode != 0
    assert _errors(proc) == ["setup_env: error: unknown Blender line '3.6'; tested lines: 5.2 4.5 4.2"]


def test_a_bad_override_is_named(scratch, tmp_path):
    repo, env = scratch
    proc = _run(repo, {**env, "OMNIWARP_PYTHON311": str(tmp_path / "python3.11")}, "4.2")
    assert proc.returncode != 0
    errors = _errors(proc)
    assert len(errors) == 1 and "python3.11" in errors[0] and "3.11" in errors[0], proc.stderr


def test_each_line_has_its_extra():
    """The bpy pins live once, in pyproject's extras; the script names each line's extra."""
    import tomllib

    extras = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert extras["blender"] == ["bpy==5.2.3"]
    assert extras["blender45"] == ["bpy==4.5.15"]
    assert extras["blender42"] == ["bpy==4.2.23"]
    script = (REPO_ROOT / "scripts" / "setup_env.sh").read_text()
    for extra in extras:
        if extra.startswith("blender"):
            assert f'EXTRA="{extra}"' in script or f'EXTRA="{extra},' in script, extra
    # The 5.2 line, where the whole suite runs, installs Dask for the cluster tests
    # (docs/sweeps.md); the default install does not.
    assert 'EXTRA="blender,dask"' in script
    assert extras["dask"] == ["dask==2026.8.0", "distributed==2026.8.0"]
    dependencies = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert not [d for d in dependencies if d.startswith(("dask", "distributed"))]
