"""The `omniwarp` console script and `python -m addon`: signals are held from the first
line, before the command line's imports (numpy, moderngl, the project's modules), and
while bpy starts; `cli.main` then honours them with its one line (core/interrupt.py)."""
from __future__ import annotations

from .core import interrupt


def main() -> int:
    interrupt.hold_until_handled()
    interrupt.hold_imports("bpy")
    from .cli import main as cli_main

    return cli_main()
