"""Fixtures shared by every test directory (tests/core, tests/gl, tests/blender, ...).

Nothing here is autouse; tests ask for what they need.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

REPO_ROOT: Path = Path(__file__).resolve().parent.parent

# `import addon` must resolve to this checkout (pyproject's `pythonpath` does the
# same; this also covers running pytest with an explicit `-c`/`--rootdir`).
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))


@pytest.fixture(scope="session")
def repo_root() -> Path:
    """Absolute path of the repository root (where pyproject.toml lives)."""
    return REPO_ROOT


@pytest.fixture(scope="session")
def presets_dir(repo_root: Path) -> Path:
    """The top-level `presets/` folder with the scene builders."""
    return repo_root / "presets"


@pytest.fixture(scope="session")
def shaders_dir(repo_root: Path) -> Path:
    """The top-level `gpu_shaders/` folder with the GLSL shared by both backends."""
    return repo_root / "gpu_shaders"


@pytest.fixture(scope="session")
def gl_backend():
    """One standalone moderngl (EGL) backend for the session.

    A missing context is a failure, not a skip: the shaders are the product, and
    CI installs Mesa EGL.
    """
    from addon.render.moderngl_backend import ModernGLBackend

    backend = ModernGLBackend()
    yield backend
    backend.release()
