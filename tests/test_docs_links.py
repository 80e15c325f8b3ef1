"""Every relative link and image in the Markdown pages points to a file that exists.

Covers README.md and every `*.md` under docs/ (the pages and the reports under
docs/results/). A target is resolved against the folder of the page that names it;
web links (`http:`, `https:`, `mailto:`), bare anchors (`#section`) and links inside
code (fenced blocks and inline backticks) are not checked. A link's own anchor
(`page.md#section`) is dropped before the check: only the file must exist.
"""
from __future__ import annotations

import re
from pathlib import Path
from urllib.parse import unquote

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent

# `[text](target)` and `![alt](target)`; the target may be `<...>` and carry a "title".
_INLINE = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*(<[^>]*>|[^)\s]+)(?:\s+\"[^\"]*\")?\s*\)")
# `[label]: target` reference definitions.
_REFERENCE = re.compile(r"^[ \t]{0,3}\[[^\]]+\]:[ \t]*(<[^>]*>|\S+)", re.MULTILINE)
# `<img src="...">` and `<a href="...">`.
_HTML = re.compile(r"<(?:img|a)\b[^>]*?\b(?:src|href)\s*=\s*[\"']([^\"']+)[\"']", re.IGNORECASE)
_FENCE = re.compile(r"^[ \t]*(`{3,}|~{3,})")
# A code span ends at the same run of backticks, within its paragraph.
_INLINE_CODE = re.compile(r"(`+)(?:(?!\1)(?!\n[ \t]*\n).)+?\1", re.DOTALL)
_EXTERNAL = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def _pages() -> list[Path]:
    pages = [REPO_ROOT / "README.md"]
    pages += sorted((REPO_ROOT / "docs").rglob("*.md"))
    return [page for page in pages if page.is_file()]


def _strip_code(text: str) -> str:
    """The page without fenced code blocks and inline code spans (line count kept)."""
    lines, fence = [], ""
    for line in text.split("\n"):
        match = _FENCE.match(line)
        if fence:
            if match and match.group(1)[0] == fence[0] and len(match.group(1)) >= len(fence):
                fence = ""
            lines.append("")
        elif match:
            fence = match.group(1)
            lines.append("")
        else:
            lines.append(line)
    return _INLINE_CODE.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), "\n".join(lines))


def link_targets(text: str) -> list[tuple[int, str]]:
    """(line number, target) of each relative link or image in a Markdown text."""
    text = _strip_code(text)
    found: list[tuple[int, str]] = []
    for pattern in (_INLINE, _REFERENCE, _HTML):
        for match in pattern.finditer(text):
            target = match.group(1).strip()
            if target.startswith("<") and target.endswith(">"):
                target = target[1:-1].strip()
            if not target or target.startswith("#") or _EXTERNAL.match(target):
                continue
            line = text.count("\n", 0, match.start()) + 1
            found.append((line, target))
    return sorted(found)


def broken_links(page: Path, root: Path = REPO_ROOT) -> list[str]:
    """`page:line: target` for each relative link of `page` whose file is missing.

    A target starting with `/` is taken from the repository root `root`.
    """
    broken = []
    for line, target in link_targets(page.read_text(encoding="utf-8")):
        path = unquote(target.split("#", 1)[0].split("?", 1)[0])
        base = root if path.startswith("/") else page.parent
        if not (base / path.lstrip("/")).exists():
            broken.append(f"{page.relative_to(root)}:{line}: {target}")
    return broken


def test_link_parser_finds_links_and_skips_the_rest() -> None:
    text = (
        "See [the design](design.md#layers) and ![plot](results/a.png) and\n"
        "[web](https://example.org), [anchor](#top), `[code](nope.md)`,\n"
        "\n```bash\n[fenced](nope.md)\n\n```\n"
        '<img src="results/x.png"> [t](<with space.md> "title")\n'
        "[ref]: notes/ref.md\n"
    )
    assert link_targets(text) == [
        (1, "design.md#layers"), (1, "results/a.png"), (8, "results/x.png"),
        (8, "with space.md"), (9, "notes/ref.md"),
    ]


def test_a_missing_file_is_reported(tmp_path: Path) -> None:
    page = tmp_path / "docs" / "page.md"
    page.parent.mkdir()
    (tmp_path / "docs" / "there.png").write_bytes(b"")
    (tmp_path / "README.md").write_text("", encoding="utf-8")
    page.write_text(
        "![ok](there.png) [gone](results/gone.md#x)\n[root](/README.md) [up](../nope.md)\n",
        encoding="utf-8",
    )
    assert broken_links(page, tmp_path) == [
        "docs/page.md:1: results/gone.md#x", "docs/page.md:2: ../nope.md",
    ]


def test_pages_exist() -> None:
    pages = _pages()
    assert REPO_ROOT / "README.md" in pages
    assert any(page.parent == REPO_ROOT / "docs" for page in pages)


@pytest.mark.parametrize("page", _pages(), ids=lambda page: str(page.relative_to(REPO_ROOT)))
def test_relative_links_point_to_existing_files(page: Path) -> None:
    broken = broken_links(page)
    assert not broken, "links to missing files:\n  " + "\n  ".join(broken)


def _github_anchor(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation but `-` and `_` dropped,
    spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_the_notebook_index_links_every_entry() -> None:
    """Each entry (a `## ` heading) of every notebook file is a row of the index, and every
    row's anchor is a heading of its file: an entry nobody can find from the index is lost."""
    notebook = REPO_ROOT / "docs" / "notebook"
    index = (notebook / "README.md").read_text(encoding="utf-8")
    linked = set(re.findall(r"\]\(([^)#/]+\.md)#([^)]+)\)", index))
    entries = {(page.name, _github_anchor(heading)) for page in notebook.glob("20*.md")
               for heading in re.findall(r"^## (.+)$", page.read_text(encoding="utf-8"), re.M)}
    assert sorted(entries - linked) == [], "entries the index does not link"
    assert sorted(linked - entries) == [], "index rows whose anchor is no entry"
