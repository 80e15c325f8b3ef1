"""Preset registry: finds the builder modules in the top-level `presets/` folder.

Preset modules are loaded by file path, not imported as a package, so the same
files work from the CLI (where `addon` is a top-level package) and inside the
Blender extension (where it is a sub-package). A preset module defines:

    DESCRIPTION: str   one line, what the scene is
    STRESSES: str      what it stresses in a shadow method
    def build(builder: SceneBuilder) -> None
"""
from __future__ import annotations

import hashlib
import importlib.util
import logging
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from .errors import PresetError
from .scene import SceneBuilder, SceneSpec

log = logging.getLogger(__name__)

PRESET_DIR = Path(__file__).resolve().parents[2] / "presets"
DEFAULT_PRESET = "room_omni"
DEFAULT_RESOLUTION = (640, 480)


@dataclass(frozen=True)
class PresetInfo:
    name: str
    description: str
    stresses: str
    path: Path

    @property
    def is_stress(self) -> bool:
        return self.name.startswith("stress_")


def _load_module(path: Path) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"omniwarp_preset_{path.stem}", path)
    if spec is None or spec.loader is None:
        raise PresetError(f"cannot load preset file {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for attr in ("DESCRIPTION", "STRESSES", "build"):
        if not hasattr(module, attr):
            raise PresetError(f"preset file {path.name} lacks {attr}")
    return module


def available_presets(preset_dir: Path = PRESET_DIR) -> dict[str, PresetInfo]:
    """Every preset found, by name, sorted."""
    found: dict[str, PresetInfo] = {}
    for path in sorted(preset_dir.glob("*.py")):
        if path.name.startswith("_"):
            continue
        module = _load_module(path)
        found[path.stem] = PresetInfo(path.stem, module.DESCRIPTION, module.STRESSES, path)
    return found


def select_presets(selection: str, preset_dir: Path = PRESET_DIR) -> list[str]:
    """Resolve SEL: a name, a comma list, `all` (non-stress) or `stress_all`."""
    known = available_presets(preset_dir)
    if selection == "all":
        return [n for n, p in known.items() if not p.is_stress]
    if selection == "stress_all":
        names = [n for n, p in known.items() if p.is_stress]
        if not names:
            raise PresetError("no stress_* presets exist yet")
        return names
    names = [s.strip() for s in selection.split(",") if s.strip()]
    if not names:
        raise PresetError("empty preset selection")
    for name in names:
        if name not in known:
            raise PresetError(
                f"unknown preset {name!r}; known: {', '.join(known)} (or 'all', 'stress_all')"
            )
    return names


def preset_source_hash(name: str, preset_dir: Path = PRESET_DIR) -> str:
    """Hash of the builder file and the core modules a scene is made of (scene.py, camera.py,
    alpha.py, light_shape.py), so a changed builder (or the camera or light it makes)
    refreshes caches."""
    digest = hashlib.sha256()
    digest.update((preset_dir / f"{name}.py").read_bytes())
    for module in ("scene.py", "camera.py", "alpha.py", "light_shape.py"):
        digest.update(Path(__file__).with_name(module).read_bytes())
    return digest.hexdigest()[:16]


def build_preset(name: str, resolution: tuple[int, int] = DEFAULT_RESOLUTION,
                 preset_dir: Path = PRESET_DIR) -> SceneSpec:
    """Run the builder of preset `name` and return its scene."""
    known = available_presets(preset_dir)
    if name not in known:
        raise PresetError(f"unknown preset {name!r}; known: {', '.join(known)}")
    module = _load_module(known[name].path)
    builder = SceneBuilder(name, resolution)
    module.build(builder)
    return builder.finish(module.DESCRIPTION, module.STRESSES)
