"""Fixtures shared by every test directory (tests/core, tests/gl, tests/blender, ...).

Nothing here is autouse; tests ask for what they need.
"""
from __future__ import annotations

import re
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
def reference_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One Cycles reference cache for the whole test run ($OMNIWARP_CACHE or a cache_dir).

    The cache keys a preset's reference by its builder's source, the size, the samples and
    the Blender version (addon/reference/cache.py), so every test that hands it this folder
    renders a given preset and size once per run, whichever test asks first. A test that
    watches a render happen (a cache miss, a damaged file, a render interrupted) keeps a
    fresh folder of its own instead.
    """
    return tmp_path_factory.mktemp("reference_cache")


@pytest.fixture(scope="session")
def gl_backend():
    """One standalone moderngl (EGL) backend for the session.

    A missing context is a failure, not a skip: the shaders are the product, and
    CI installs Mesa EGL.
    """
    from addon.render.backends.moderngl.backend import ModernGLBackend

    backend = ModernGLBackend()
    yield backend
    backend.release()


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """A test asking for `preset_case` runs once per preset in its module's PRESET_CASES."""
    if "preset_case" in metafunc.fixturenames:
        metafunc.parametrize("preset_case", metafunc.module.PRESET_CASES, indirect=True, scope="module")


@pytest.fixture(scope="module")
def preset_case(request: pytest.FixtureRequest):
    """oracle.PresetCase (name, scene, samples, lit, evaluable) of one preset of the module's
    PRESET_CASES at its PRESET_CASE_SIZE; made once per test run."""
    from tests.support.oracle import preset_case_of

    return preset_case_of(request.param, tuple(request.module.PRESET_CASE_SIZE))


# A test module that imports bpy anywhere (at the top, inside a test, or via importorskip).
_IMPORTS_BPY = re.compile(r"^\s*(?:import bpy\b|from bpy\b|.*importorskip\(\s*[\"']bpy[\"'])", re.MULTILINE)


@pytest.hookimpl(tryfirst=True)  # before `-m` deselects by marker
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Every test of a module that imports bpy gets the `blender` marker, so the LTS lines
    (`-m blender`, scripts/test.sh) run it even where a test forgot its mark."""
    imports_bpy: dict[Path, bool] = {}
    for item in items:
        path = Path(str(item.fspath))
        if path not in imports_bpy:
            imports_bpy[path] = bool(_IMPORTS_BPY.search(path.read_text(encoding="utf-8")))
        if imports_bpy[path] and item.get_closest_marker("blender") is None:
            item.add_marker(pytest.mark.blender)
