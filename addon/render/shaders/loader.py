"""The GLSL loader: a stage file and the `lib/*.glsl` files it includes, inlined.

Stage files hold only functions and `main()`; they pull helpers in with
`#include "lib/name.glsl"`. An include is looked up under the shader folder first, then
under each folder of the include path, so a test can load a small shader of its own
that includes the shipped `lib/` files without copying them.
"""
from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from ...core.errors import BackendError

SHADER_DIR = Path(__file__).resolve().parents[3] / "gpu_shaders"
GLSL_VERSION = "430 core"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


def _find(name: str, folders: Sequence[Path]) -> Path:
    """The first folder's `name` that exists, else the first folder's (reported missing)."""
    for folder in folders:
        if (folder / name).is_file():
            return folder / name
    return folders[0] / name


def expand_source(text: str, shader_dir: Path = SHADER_DIR, include_path: Sequence[Path] = (),
                  origin: Path | None = None) -> str:
    """`text` with its `#include`s inlined, each file at most once.

    Includes are looked up under `shader_dir`, then under each folder of `include_path`.
    `origin` is the file `text` was read from (it counts as included). Raises
    BackendError for a missing file or an include cycle.
    """
    folders = (Path(shader_dir), *(Path(folder) for folder in include_path))
    seen: set[Path] = set()

    def expand(body: str, stack: tuple[Path, ...]) -> str:
        def replace(match: re.Match) -> str:
            path = _find(match.group(1), folders)
            resolved = path.resolve()
            if resolved in stack:
                chain = " -> ".join(p.name for p in stack + (resolved,))
                raise BackendError(f"GLSL include cycle: {chain}")
            if not resolved.is_file():
                looked = ", ".join(str(folder) for folder in folders)
                raise BackendError(f"GLSL file not found: {path} (looked under {looked})")
            if resolved in seen:
                return f"// (already included: {path.name})\n"
            seen.add(resolved)
            return expand(resolved.read_text(encoding="utf-8"), stack + (resolved,))

        return _INCLUDE.sub(replace, body)

    root: tuple[Path, ...] = ()
    if origin is not None:
        root = (origin.resolve(),)
        seen.add(root[0])
    return expand(text, root)


def load_source(relative: str, shader_dir: Path = SHADER_DIR, include_path: Sequence[Path] = ()) -> str:
    """Read a GLSL file of `shader_dir` and inline its `#include`s (`expand_source`)."""
    path = Path(shader_dir) / relative
    if not path.is_file():
        raise BackendError(f"GLSL file not found: {path} (looked under {shader_dir})")
    return expand_source(path.read_text(encoding="utf-8"), shader_dir, include_path, origin=path)
