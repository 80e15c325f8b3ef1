"""The layering contract of docs/design.md section 2.

* `addon.core` and `addon.render` import without bpy / gpu / mathutils / bmesh
  (checked at run time in a clean subprocess where those imports raise).
* `addon.core` never imports `addon.render`, `addon.reference` or `addon.blender`,
  nor bpy or a GL binding, not even inside a function (static check).
* `addon.render` never imports `addon.blender` (static check).
* No import cycle among the modules of addon/, imports inside functions included,
  and no hidden edge through `importlib.import_module` or a `sys.modules` lookup.
* Code under `addon/` that Blender loads uses relative imports only: inside
  Blender the package is `bl_ext.<repo>.omniwarp_shadows.addon`, so
  `import addon...` would fail there.

Modules are discovered from the source tree, so new modules are covered and
missing packages (not written yet) are simply empty.
"""
from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent
ADDON = REPO_ROOT / "addon"

# Blender-only modules; importing any of them (or a submodule) must not be needed.
BLENDER_MODULES = (
    "bpy", "_bpy", "bpy_extras", "bpy_types", "bl_math", "bmesh",
    "gpu", "gpu_extras", "mathutils", "idprop", "aud",
)
GL_MODULES = ("moderngl", "glcontext", "OpenGL")

# Runs in a fresh interpreter: block Blender modules, then import everything.
_IMPORT_ALL = r"""
import importlib, importlib.abc, json, pkgutil, sys, traceback

repo_root, blocked, packages = sys.argv[1], set(sys.argv[2].split(",")), sys.argv[3].split(",")
sys.path.insert(0, repo_root)

class BlockBlender(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in blocked:
            raise ImportError(f"{name!r} is blocked: addon.core/addon.render must import without Blender")
        return None

sys.meta_path.insert(0, BlockBlender())
for name in list(sys.modules):
    if name.partition(".")[0] in blocked:
        del sys.modules[name]

imported, failed = [], {}

def record_failure(name):
    failed[name] = traceback.format_exc()

for pkg_name in packages:
    try:
        pkg = importlib.import_module(pkg_name)
    except BaseException:
        record_failure(pkg_name)
        continue
    imported.append(pkg_name)
    names = [info.name for info in pkgutil.walk_packages(pkg.__path__, pkg_name + ".", onerror=record_failure)]
    for name in names:
        if name in failed:
            continue
        try:
            importlib.import_module(name)
            imported.append(name)
        except BaseException:
            record_failure(name)

leaked = sorted(n for n in sys.modules if n.partition(".")[0] in blocked)
print(json.dumps({"imported": imported, "failed": failed, "leaked": leaked}))
"""


def _existing_packages(*names: str) -> list[str]:
    """Dotted names of the given `addon` sub-packages that exist on disk."""
    return [f"addon.{n}" for n in names if (ADDON / n).is_dir()]


def test_the_lower_layers_import_without_blender() -> None:
    """Every module under addon/core, compat, render and readers imports with bpy & co. blocked
    (compat and the readers import bpy inside the calls that need it)."""
    packages = _existing_packages("core", "compat", "render", "readers")
    if not packages:
        pytest.skip("neither addon/core nor addon/render exists yet")
    proc = subprocess.run(
        [sys.executable, "-c", _IMPORT_ALL, str(REPO_ROOT), ",".join(BLENDER_MODULES), ",".join(packages)],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, f"import subprocess crashed:\n{proc.stdout}\n{proc.stderr}"
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    failures = "\n".join(f"--- {name}\n{tb}" for name, tb in result["failed"].items())
    assert not result["failed"], f"modules that need Blender (or fail to import):\n{failures}"
    assert not result["leaked"], f"Blender modules got imported anyway: {result['leaked']}"
    assert set(packages) <= set(result["imported"])


@dataclass(frozen=True)
class ImportRef:
    """One imported module name, resolved to an absolute dotted name."""

    source: Path
    line: int
    target: str
    relative: bool

    def where(self) -> str:
        return f"{self.source.relative_to(REPO_ROOT)}:{self.line} imports {self.target}"


def _module_name(path: Path) -> tuple[str, bool]:
    """Dotted module name of a source file under the repo root, and whether it is a package."""
    parts = list(path.relative_to(REPO_ROOT).with_suffix("").parts)
    is_package = parts[-1] == "__init__"
    if is_package:
        parts.pop()
    return ".".join(parts), is_package


def _imports(path: Path) -> list[ImportRef]:
    """All imports in a source file under the repo, resolved to absolute names."""
    module, is_package = _module_name(path)
    return _resolve_imports(path.read_text(encoding="utf-8"), module, is_package, path)


def _resolve_imports(source: str, module: str, is_package: bool, path: Path) -> list[ImportRef]:
    """All imports in `source` (including ones inside functions), resolved to absolute names.

    `from . import x` yields both the package and `package.x`, since x may be a module.
    """
    package = module if is_package else module.rpartition(".")[0]
    tree = ast.parse(source, filename=str(path))
    refs: list[ImportRef] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            refs.extend(ImportRef(path, node.lineno, alias.name, False) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                base = node.module or ""
            else:
                parts = package.split(".")
                up = node.level - 1
                if up >= len(parts):
                    base = "<beyond top package>"
                else:
                    base = ".".join(parts[: len(parts) - up] + ([node.module] if node.module else []))
            relative = node.level > 0
            refs.append(ImportRef(path, node.lineno, base, relative))
            refs.extend(
                ImportRef(path, node.lineno, f"{base}.{alias.name}", relative)
                for alias in node.names
                if alias.name != "*"
            )
    return refs


def _sources(*subdirs: str) -> list[Path]:
    return sorted(p for d in subdirs for p in (ADDON / d).rglob("*.py") if "__pycache__" not in p.parts)


def _hits(refs: list[ImportRef], forbidden: tuple[str, ...]) -> list[str]:
    return sorted(
        {r.where() for r in refs if any(r.target == f or r.target.startswith(f + ".") for f in forbidden)}
    )


def test_core_imports_only_downward() -> None:
    """addon/core never imports the render, reference or blender layers."""
    refs = [ref for path in _sources("core") for ref in _imports(path)]
    bad = _hits(refs, ("addon.render", "addon.reference", "addon.blender", "addon.cli"))
    assert not bad, "addon/core must stay at the ground floor:\n" + "\n".join(bad)


def test_core_has_no_blender_or_gl_imports() -> None:
    """addon/core is numpy only: no bpy family and no GL binding, not even lazily."""
    refs = [ref for path in _sources("core") for ref in _imports(path) if not ref.relative]
    bad = _hits(refs, BLENDER_MODULES + GL_MODULES)
    assert not bad, "addon/core must not touch Blender or GL:\n" + "\n".join(bad)


def test_render_never_imports_blender_layer() -> None:
    """addon/render may use Blender's gpu module (lazily) but never the addon.blender UI layer."""
    refs = [ref for path in _sources("render") for ref in _imports(path)]
    bad = _hits(refs, ("addon.blender", "addon.cli"))
    assert not bad, "addon/render must not import addon.blender:\n" + "\n".join(bad)


def test_blender_loaded_code_uses_relative_imports() -> None:
    """Inside Blender `addon` is a sub-package of the extension, so `import addon.x` breaks there."""
    refs = [
        ref
        for path in _sources("core", "render", "reference", "blender")
        for ref in _imports(path)
        if not ref.relative
    ]
    bad = _hits(refs, ("addon",))
    assert not bad, "use relative imports inside addon/ (the extension renames the package):\n" + "\n".join(bad)


def test_import_resolution_helper() -> None:
    """The static resolver maps relative imports to the right absolute names."""
    src = (
        "from ..render import pipeline\n"
        "from . import scene\n"
        "def f():\n"
        "    from .. import blender\n"
        "import numpy as np\n"
        "from addon.reference import cache\n"
    )
    fake = ADDON / "core" / "probe.py"
    assert _module_name(fake) == ("addon.core.probe", False)
    refs = _resolve_imports(src, "addon.core.probe", False, fake)
    names = {r.target for r in refs}
    assert {"addon.render.pipeline", "addon.core.scene", "addon.blender", "numpy", "addon.reference.cache"} <= names
    assert _hits(refs, ("addon.render", "addon.blender")) == [
        "addon/core/probe.py:1 imports addon.render",
        "addon/core/probe.py:1 imports addon.render.pipeline",
        "addon/core/probe.py:4 imports addon.blender",
    ]
    assert _hits([r for r in refs if not r.relative], ("addon",)) == [
        "addon/core/probe.py:6 imports addon.reference",
        "addon/core/probe.py:6 imports addon.reference.cache",
    ]
    # In a package __init__, `.` is the package itself.
    init_refs = _resolve_imports("from .frames import Frame\n", "addon.core", True, ADDON / "core" / "__init__.py")
    assert "addon.core.frames.Frame" in {r.target for r in init_refs}


def _module_graph() -> dict[str, set[str]]:
    """Module -> the modules of addon/ it imports (anywhere in the file)."""
    paths = {_module_name(p)[0]: p for p in sorted(ADDON.rglob("*.py")) if "__pycache__" not in p.parts}
    return {name: {ref.target for ref in _imports(path) if ref.target in paths and ref.target != name}
            for name, path in paths.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(graph[node]):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_cycle_finder_finds_a_cycle() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles_in_addon() -> None:
    """A module never imports, at any depth and even inside a function, one that imports it."""
    cycles = _cycles(_module_graph())
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_no_hidden_imports_of_siblings() -> None:
    """Sibling modules are imported by name, never found through importlib or sys.modules,
    so the cycle check above sees every edge."""
    bad = []
    for path in sorted(ADDON.rglob("*.py")):
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if "import_module(" in line or "sys.modules.get(f" in line or "__package__}." in line:
                bad.append(f"{path.relative_to(REPO_ROOT)}:{number}: {line.strip()}")
    assert not bad, "hidden imports:\n" + "\n".join(bad)


MAX_MODULE_LINES = 700


def test_modules_are_small_enough_to_read_in_one_sitting() -> None:
    long = [f"{p.relative_to(REPO_ROOT)}: {n} lines" for p in sorted(ADDON.rglob("*.py"))
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES]
    assert not long, f"modules over {MAX_MODULE_LINES} lines:\n" + "\n".join(long)


def test_the_code_names_no_issue_numbers() -> None:
    """Comments and docstrings say why in words: an issue's number means nothing to a
    reader of the code (the history is in the notebook and the log)."""
    pattern = re.compile(r"\bissues? \d+\b", re.IGNORECASE)
    files = [*ADDON.rglob("*.py"), *(REPO_ROOT / "gpu_shaders").rglob("*.*")]
    named = [f"{p.relative_to(REPO_ROOT)}:{i}" for p in sorted(files)
             for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if pattern.search(line)]
    assert not named, "issue numbers in the code:\n" + "\n".join(named)


# docs/design.md section 2: a package imports only those of a lower rank (the top-level
# modules and the UI share the top rank and may import each other).
RANKS = {"core": 1, "compat": 2, "render": 3, "readers": 4, "reference": 5, "blender": 6}
TOP_RANK = 6


def _rank(module: str) -> tuple[str, int]:
    """The unit a dotted `addon...` name belongs to (a package of addon/, or the top
    level) and its rank."""
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in RANKS:
        return parts[1], RANKS[parts[1]]
    return "addon", TOP_RANK


def test_packages_import_only_downward() -> None:
    """Every import between two packages of addon/ runs to a lower rank, as design.md
    section 2's table says; the packages there are the ones on disk."""
    assert set(RANKS) == {p.name for p in ADDON.iterdir() if p.is_dir() and any(p.glob("*.py"))}
    bad = []
    for path in sorted(ADDON.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        source, rank = _rank(_module_name(path)[0])
        for ref in _imports(path):
            if not ref.target.startswith("addon."):
                continue
            target, target_rank = _rank(ref.target)
            if target != source and target_rank >= rank and not (rank == TOP_RANK and target_rank == TOP_RANK):
                bad.append(ref.where())
    assert not bad, "imports that run up or sideways:\n" + "\n".join(sorted(set(bad)))


def _private_uses(path: Path) -> list[str]:
    """`from x import _name` and `module._name` where `module` is an import of this file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    modules: set[str] = set()
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            for alias in node.names:
                if alias.name.startswith("_") and not alias.name.startswith("__"):
                    found.append(f"{path.relative_to(REPO_ROOT)}:{node.lineno} imports {alias.name}")
                if (node.level and not node.module) or alias.name.islower():  # a module, or a function
                    modules.add(alias.asname or alias.name)
        elif isinstance(node, ast.Import):
            modules.update((alias.asname or alias.name).partition(".")[0] for alias in node.names)
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in modules
                and node.attr.startswith("_") and not node.attr.startswith("__")):
            found.append(f"{path.relative_to(REPO_ROOT)}:{node.lineno} uses {node.value.id}.{node.attr}")
    return found


def test_no_module_uses_another_modules_private_names() -> None:
    """A name starting with `_` is its module's own: another module that needs it needs a
    public name (or the code belongs with it)."""
    own = {"os": {"_exit"}, "sys": {"_getframe"}}  # the standard library's own public-by-use names
    bad = [use for path in sorted(ADDON.rglob("*.py")) if "__pycache__" not in path.parts
           for use in _private_uses(path)
           if not any(f" uses {mod}.{name}" in use for mod, names in own.items() for name in names)]
    assert not bad, "private names used across modules:\n" + "\n".join(bad)
