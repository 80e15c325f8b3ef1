"""Run one of this package's modules in a child Python process: `python -m addon.X ARGS`.

The preview draws with Blender's gpu in a child (`cli.py`), and EEVEE renders its
references in one (`reference/eevee.py`): one GL owner per process, docs/design.md
section 3. Both go through `run_module`. The child runs from the repository root, with
the root first on PYTHONPATH and its temporaries (Blender's session folder) in the
folder the caller names, so they go with that folder even when the child is killed. An
interrupt, or any failure of the parent while it waits, stops the child. Its exit
status follows the exit contract of core/errors.py.
"""
from __future__ import annotations

import logging
import os
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable, Sequence
from pathlib import Path

from . import interrupt
from .errors import EXIT_BAD_INPUT, ChildProcessCrash, child_error_line, child_stderr_tail

log = logging.getLogger(__name__)

REPO_ROOT = Path(__file__).resolve().parents[2]
READER_JOIN_S = 5.0  # how long to wait for the last stdout lines once the child has ended


def child_env(tmpdir: Path) -> dict[str, str]:
    """This process's environment with the repository root first on PYTHONPATH and
    TMPDIR set to `tmpdir`."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO_ROOT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env["TMPDIR"] = str(tmpdir)
    return env


def _read_lines(stream, on_stdout: Callable[[str], None] | None) -> None:
    """Read the child's stdout to its end (so that the pipe never fills), passing each
    line on to `on_stdout`."""
    for line in stream:
        if on_stdout is not None:
            on_stdout(line)
    stream.close()


def run_module(module: str, args: Sequence[str], *, what: str, tmpdir: Path,
               refused: Callable[[str], Exception], on_stdout: Callable[[str], None] | None = None,
               timeout_s: float | None = None) -> None:
    """Run `python -m MODULE ARGS` and wait for it to end.

    Exit 0 returns. Exit EXIT_BAD_INPUT with the child's one-line error raises
    `refused(line)`; any other failure raises ChildProcessCrash naming the `what`
    process, with the end of its stderr. Each line the child prints on stdout goes to
    `on_stdout`. After `timeout_s` seconds the child is stopped and
    subprocess.TimeoutExpired raised.
    """
    command = [sys.executable, "-m", module, *map(str, args)]
    log.info("running %s", " ".join(command))
    with tempfile.TemporaryFile(mode="w+", encoding="utf-8", errors="replace") as err:
        proc: subprocess.Popen | None = None
        reader: threading.Thread | None = None
        try:
            with interrupt.deferred():  # a Ctrl-C during the start must not orphan the child
                proc = subprocess.Popen(command, cwd=REPO_ROOT, env=child_env(tmpdir), stdout=subprocess.PIPE,
                                        stderr=err, text=True, errors="replace")
                interrupt.track_child(proc)
                reader = threading.Thread(target=_read_lines, args=(proc.stdout, on_stdout), daemon=True)
                reader.start()
            proc.wait(timeout=timeout_s)
        except BaseException:
            # A timeout, Ctrl-C (Interrupted) or any failure here: the child must not outlive us.
            if proc is not None:
                interrupt.stop_child(proc)
            raise
        finally:
            if proc is not None:
                interrupt.forget_child(proc)
            if reader is not None:
                reader.join(timeout=READER_JOIN_S)
        err.seek(0)
        stderr = err.read()
    line = child_error_line(stderr) if proc.returncode == EXIT_BAD_INPUT else None
    if line:
        raise refused(line)
    if proc.returncode != 0:
        raise ChildProcessCrash(f"the {what} process crashed (exit {proc.returncode}):\n{child_stderr_tail(stderr)}")
