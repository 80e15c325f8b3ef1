"""docs/design.md section 2 lists every module of addon/, and nothing that is gone.

Section 2 has one paragraph a package, which starts with its folder:

    The modules of `core/`: `alpha` (what it is), `camera`, ...
    Those of `render/`: `backend` (the interface), ..., `shaders/` (the GLSL package:
    `loader` (reads the files), `variants`), ...
    Those of `addon/` itself: `cli` (the command), ...

A folder is under addon/ (`addon/` is the package itself; a sub-package may also have
a paragraph of its own, `render/shaders/` for addon/render/shaders). At the top level
of a paragraph (outside parentheses) each name in backticks is a module (`name`, a
`name.py`) or a sub-package (`name/`); a description goes in the parentheses after the
name, so the words in backticks there are not names. A sub-package's parentheses,
right after its name, list its own modules: there the names in backticks one level in
are its modules, and their descriptions go one level further in.

The tree side: every `*.py` of the folder but `__init__.py`, and every sub-folder with
a `*.py` in it (not `__pycache__`); a sub-folder with a paragraph of its own is checked
there.
The failure message says, per folder, which names to add and which to remove.
"""
from __future__ import annotations

import re
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
DESIGN = REPO_ROOT / "docs" / "design.md"
ADDON = REPO_ROOT / "addon"

_LABEL = re.compile(r"^(?:The modules of|Those of) `(?P<folder>\w+(?:/\w+)*)/`(?: itself)?:(?P<body>.*)$", re.DOTALL)
_TOKEN = re.compile(r"`[^`]*`|\(|\)|[^`()]+")

# A folder's entries: module names, and sub-package names ("name/") with their entries.
Entries = dict[str, "Entries | None"]


def section_2(text: str) -> str:
    """The text of section 2 ("## 2. ..." up to the next "## "), without code blocks."""
    match = re.search(r"^## 2\..*?(?=^## )", text, re.MULTILINE | re.DOTALL)
    assert match, "docs/design.md has no section 2"
    return re.sub(r"^```.*?^```[^\n]*$", "", match.group(0), flags=re.MULTILINE | re.DOTALL)


def _entries(body: str) -> Entries:
    """The names of one paragraph's body (after its label), sub-packages with theirs."""
    entries: Entries = {}
    depth = 0
    package: str | None = None  # the sub-package just named, until its parentheses close
    inside = False  # in that sub-package's parentheses
    for token in _TOKEN.findall(body):
        if token == "(":
            depth += 1
            inside = inside or (package is not None and depth == 1)
        elif token == ")":
            depth -= 1
            if depth == 0:
                package, inside = None, False
        elif token.startswith("`"):
            name = token.strip("`").strip()
            if depth == 0:
                package = name if name.endswith("/") else None
                entries[name] = {} if package else None
            elif inside and depth == 1:
                entries[package][name] = None  # type: ignore[index]
        elif depth == 0 and token.strip():
            package = None  # its parentheses must follow the name directly
    return entries


def documented_modules(text: str) -> dict[str, Entries]:
    """Folder (relative to the repository, "addon" or "addon/core") -> its listed entries."""
    lists: dict[str, Entries] = {}
    for paragraph in re.split(r"\n[ \t]*\n", section_2(text)):
        # a paragraph may hold several lists, each starting with its label
        for part in re.split(r"(?=(?:The modules of|Those of) `[\w/]+/`)", " ".join(paragraph.split())):
            match = _LABEL.match(part)
            if match:
                folder = match.group("folder")
                lists["addon" if folder == "addon" else f"addon/{folder}"] = _entries(match.group("body"))
    return lists


def tree_modules(folder: Path, skip: frozenset[str] = frozenset()) -> Entries:
    """The entries of a folder on disk: its modules and sub-packages (those in `skip` left out)."""
    entries: Entries = {}
    for path in sorted(folder.iterdir()):
        if path.is_file() and path.suffix == ".py" and path.stem != "__init__":
            entries[path.stem] = None
        elif (
            path.is_dir()
            and path.name not in skip
            and not path.name.startswith((".", "__"))
            and any(path.rglob("*.py"))
        ):
            entries[path.name + "/"] = tree_modules(path)
    return entries


def _describe(entries: Entries) -> str:
    parts = []
    for name, sub in entries.items():
        parts.append(f"`{name}` ({', '.join(f'`{n}`' for n in sub)})" if sub else f"`{name}`")
    return ", ".join(parts)


def differences(folder: str, documented: Entries, tree: Entries) -> list[str]:
    """What to change in the list of `folder` so that it matches `tree`, one line a change."""
    lines = []
    missing = {name: sub for name, sub in tree.items() if name not in documented}
    stale = [name for name in documented if name not in tree]
    if missing:
        lines.append(f"{folder}/: add {_describe(missing)}")
    if stale:
        lines.append(f"{folder}/: remove {', '.join(f'`{name}`' for name in stale)}")
    for name, sub in tree.items():
        if sub is not None and documented.get(name) is not None:
            lines += differences(f"{folder}/{name.rstrip('/')}", documented[name] or {}, sub)
    return lines


def check(text: str, addon: Path) -> list[str]:
    """Every change section 2 needs so that its lists match the packages under `addon`."""
    lists = documented_modules(text)
    if "addon" not in lists:
        lists["addon"] = {}
    lines = []
    for folder, documented in lists.items():
        path = addon.parent / folder
        if not path.is_dir():
            lines.append(f"{folder}/: remove the whole list (no such folder)")
            continue
        # a sub-folder with a paragraph of its own is checked there
        own = frozenset(Path(other).name for other in lists if Path(other).parent == Path(folder))
        lines += differences(folder, documented, tree_modules(path, skip=own))
    return lines


_SAMPLE = """\
# Design

## 2. Layout

```
addon/
  core/                 not parsed: a code block
```

The modules of `core/`: `alpha` (see-through: a `Surface` and its `AlphaMap`), `camera`,
`gone` and `plan`.

Those of `render/`: `backend` (the interface), `shaders/` (the GLSL package, with
`loader` (reads the files, `#include`), `variants`), `old_pkg/` (`a`), `pipeline`.

Those of `addon/` itself: `cli` (the `omniwarp` command).

## 3. Next

The modules of `nope/`: `x`.
"""


def test_parser_reads_names_and_skips_descriptions() -> None:
    assert documented_modules(_SAMPLE) == {
        "addon/core": {"alpha": None, "camera": None, "gone": None, "plan": None},
        "addon/render": {
            "backend": None,
            "shaders/": {"loader": None, "variants": None},
            "old_pkg/": {"a": None},
            "pipeline": None,
        },
        "addon": {"cli": None},
    }


def test_check_says_what_to_add_and_remove(tmp_path: Path) -> None:
    addon = tmp_path / "addon"
    files = (
        "__init__.py", "__main__.py", "cli.py",
        "core/__init__.py", "core/alpha.py", "core/camera.py", "core/plan.py", "core/light_shape.py",
        "render/backend.py", "render/pipeline.py", "render/soft.py",
        "render/shaders/__init__.py", "render/shaders/loader.py", "render/shaders/defines.py",
        "render/shaders/variants.py",
        "blender/__init__.py", "blender/panels.py",
    )
    for name in files:
        (addon / name).parent.mkdir(parents=True, exist_ok=True)
        (addon / name).write_text("", encoding="utf-8")
    (addon / "core" / "__pycache__").mkdir()
    (addon / "core" / "__pycache__" / "x.py").write_text("", encoding="utf-8")
    assert check(_SAMPLE, addon) == [
        "addon/core/: add `light_shape`",
        "addon/core/: remove `gone`",
        "addon/render/: add `soft`",
        "addon/render/: remove `old_pkg/`",
        "addon/render/shaders/: add `defines`",
        "addon/: add `__main__`, `blender/` (`panels`)",
    ]


def test_a_sub_package_may_have_a_list_of_its_own(tmp_path: Path) -> None:
    addon = tmp_path / "addon"
    for name in ("cli.py", "render/pipeline.py", "render/shaders/__init__.py", "render/shaders/loader.py"):
        (addon / name).parent.mkdir(parents=True, exist_ok=True)
        (addon / name).write_text("", encoding="utf-8")
    text = (
        "## 2. Layout\n\nThose of `render/`: `pipeline`.\n\n"
        "Those of `render/shaders/`: `loader`.\n\n## 3. Next\n"
    )
    assert check(text, addon) == ["addon/: add `cli`"]
    as_module = text.replace("`pipeline`.", "`pipeline`, `shaders` (the loader).").replace(
        "Those of `render/shaders/`: `loader`.", "Nothing else."
    )
    assert check(as_module, addon) == [
        "addon/render/: add `shaders/` (`loader`)",
        "addon/render/: remove `shaders`",
        "addon/: add `cli`",
    ]


def test_design_section_2_lists_every_module() -> None:
    lines = check(DESIGN.read_text(encoding="utf-8"), ADDON)
    assert not lines, (
        "docs/design.md section 2's module lists differ from the tree; change them so:\n  "
        + "\n  ".join(lines)
    )
