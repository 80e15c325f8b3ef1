"""Helpers for the tests that run `omniwarp` as a user does: a subprocess, its exit
status and its stderr (tests/cli/test_exit_contract.py and its neighbours)."""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SUPPORT = REPO / "tests" / "support"


def env_with(**values: str | os.PathLike) -> dict[str, str]:
    """The current environment with some variables set (e.g. OMNIWARP_CACHE, TMPDIR)."""
    env = dict(os.environ)
    env.update({key: str(value) for key, value in values.items()})
    return env


def run_python(*args: str | os.PathLike, env: dict[str, str] | None = None, prefix: tuple[str, ...] = (),
               timeout: float = 600) -> subprocess.CompletedProcess:
    """Run `python ARGS` from the repository root in a child (it may reset bpy, or own a GL
    context) and return it finished, with its text output; `prefix` wraps the command
    (e.g. a mount namespace). Every test's child process starts here."""
    return subprocess.run([*prefix, sys.executable, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=REPO, env=env)


def start_python(*args: str | os.PathLike, env: dict[str, str] | None = None, **popen) -> subprocess.Popen:
    """Start `python ARGS` from the repository root, its stdout and stderr piped as text,
    for a test that reads them as they come or signals the child."""
    return subprocess.Popen([sys.executable, *map(str, args)], cwd=REPO, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **popen)


def omniwarp(*args: str | os.PathLike, env: dict[str, str] | None = None,
             prefix: tuple[str, ...] = (), timeout: float = 600) -> subprocess.CompletedProcess:
    """Run `python -m addon ARGS` from the repository root."""
    return run_python("-m", "addon", *args, env=env, prefix=prefix, timeout=timeout)


def python_ok(*args: str | os.PathLike, env: dict[str, str] | None = None, timeout: float = 1200) -> str:
    """`run_python`, asserting that the child exits 0; its stdout."""
    proc = run_python(*args, env=env, timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


def compared(blend: Path, folder: Path, methods: str, resolutions: str = "256") -> tuple[Path, list[dict]]:
    """`omniwarp compare` of a .blend into `folder` (out/ and cache/, one repeat, no
    images): (the reference .npz it cached, its rows)."""
    import json

    python_ok("-m", "addon.cli", "compare", "--blend", blend, "--methods", methods, "--resolutions", resolutions,
              "--repeats", "1", "--no-images", "--out", folder / "out", "--cache-dir", folder / "cache")
    (path,) = (folder / "cache").glob("*.npz")
    return path, json.loads((folder / "out" / "results.json").read_text())


def checked_arrays(script: Path, folder: Path, blend: str, variant: str) -> dict:
    """The arrays a volume test file's `--check` writes for `variant` (make_fog_blend's
    variant_main), its .blend named `blend` in `folder`."""
    import numpy as np

    python_ok(script, folder / blend, "--variant", variant, "--check", folder / "check.npz")
    with np.load(folder / "check.npz") as npz:
        return {key: npz[key] for key in npz.files}


def stderr_lines(text: str) -> list[str]:
    """Non-empty stderr lines, without Mesa's harmless EGL_BAD_MATCH noise."""
    return [line for line in text.splitlines() if line.strip() and "EGL_BAD" not in line]


def one_line(proc: subprocess.CompletedProcess, code: int = 2) -> str:
    """Assert the exit contract for a refused run: status `code`, exactly one line on
    stderr, no traceback, nothing on stdout; return that line."""
    lines = stderr_lines(proc.stderr)
    assert proc.returncode == code, (proc.returncode, proc.stderr[-3000:])
    assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert len(lines) == 1, lines
    assert proc.stdout == "", proc.stdout
    return lines[0]


def make_blend(path: Path, *flags: str) -> Path:
    """Write a small user .blend with tests/support/make_blend.py (a child: it resets bpy)."""
    proc = run_python(SUPPORT / "make_blend.py", path, *flags)
    assert proc.returncode == 0 and path.is_file(), proc.stderr[-2000:]
    return path


def tree_digest(folder: Path) -> dict[str, str]:
    """Relative path -> sha256 of every file under `folder` (to show it is untouched)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def staging_left(parent: Path) -> list[str]:
    """Staging folders a run left in `parent` (there must be none)."""
    return sorted(p.name for p in parent.iterdir() if p.name.startswith(".omniwarp-staging-"))
