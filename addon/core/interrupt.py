"""Ctrl-C (SIGINT) and SIGTERM for the commands: stop, remove temporaries, exit 130.

What bpy 5.2.3 does (probed by sending SIGINT to a process inside
`bpy.ops.render.render`): Blender leaves the C-level SIGINT handler alone, but
Python runs a signal handler only between bytecodes of the main thread, so nothing
happens until the render returns; then Python's default handler raises
KeyboardInterrupt inside the `bpy.ops` call, and the operator wrapper loses it: the
run went on and exited 0. A handler of our own that raises another exception does
propagate out of the call. Cycles releases the GIL while it renders, so a Python
thread can run at once; Blender's own break flag (what Esc sets in the UI) is not
reachable from Python, and a 1-sample Cycles render checks it only after its one
sample anyway.

So `handling()` installs a handler that records the signal and raises `Interrupted`
at the next bytecode, and wakes a watcher thread through `signal.set_wakeup_fd`.
Around a blocking C call (`blocking("Cycles render 1/2")`) the handler only records;
if the process is the command's own (`exit_at_once`), the watcher removes the
registered temporaries, prints the one line and ends the process with status 130 at
once; otherwise (main() called from Python, e.g. a test) `Interrupted` is raised as
soon as the call returns. `deferred()` keeps an interrupt out of a few lines that
must not be cut in two (moving finished outputs into place).
"""
from __future__ import annotations

import logging
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from .errors import Interrupted, report_interrupt

log = logging.getLogger(__name__)

SIGNALS = (signal.SIGINT, signal.SIGTERM)


@dataclass
class _State:
    installed: bool = False
    program: str = "omniwarp"
    exit_at_once: bool = False  # the process is the command's own: the watcher may end it
    signals: int = 0  # signals the Python handler saw
    requested: bool = False  # a signal arrived (set by the handler or the watcher)
    raised: bool = False  # Interrupted was raised once already
    deferred: int = 0  # depth of deferred() / blocking() sections
    blocking: str | None = None  # the blocking C call the main thread is in, if any
    temporaries: list[Path] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)


_STATE = _State()


def _handler(signum: int, _frame) -> None:
    """Python-level handler (main thread, between bytecodes)."""
    _STATE.signals += 1
    if _STATE.signals > 1 and _STATE.raised:
        if _STATE.exit_at_once:
            # A second Ctrl-C while the first one is being cleaned up: the user insists.
            _exit_now(f"interrupted again ({signal.Signals(signum).name})")
        raise Interrupted(f"interrupted again ({signal.Signals(signum).name})")
    _STATE.requested = True
    if _STATE.deferred or _STATE.raised:
        return
    _STATE.raised = True
    raise Interrupted(f"interrupted ({signal.Signals(signum).name})")


def _watch(fd: int) -> None:
    """Watcher thread: woken by the C-level handler's byte, even while the main
    thread is inside a render (Cycles releases the GIL)."""
    while True:
        try:
            data = os.read(fd, 64)
        except OSError:
            return
        if not data:
            return  # handling() closed the pipe
        if not any(byte in SIGNALS for byte in data):
            continue
        _STATE.requested = True
        with _STATE.lock:
            if _STATE.blocking is not None and _STATE.exit_at_once:
                _exit_now(f"interrupted during the {_STATE.blocking}; stopped at once")


def _exit_now(message: str) -> None:
    """Remove the registered temporaries, print the one line and end the process (130)."""
    for path in list(_STATE.temporaries):
        _remove(path)
    try:
        sys.stdout.flush()
    except (OSError, ValueError):
        pass  # a closed or broken stdout must not keep the process alive
    code = report_interrupt(_STATE.program, Interrupted(message))
    os._exit(code)


def _remove(path: Path) -> None:
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)
    except OSError as exc:
        log.warning("could not remove temporary %s: %s", path, exc)


@contextmanager
def handling(program: str = "omniwarp", exit_at_once: bool = False) -> Iterator[None]:
    """Install the SIGINT/SIGTERM handling for one command (main thread only; nested
    calls and other threads get a no-op). Restores the previous handlers on exit."""
    if _STATE.installed or threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.getsignal(sig) for sig in SIGNALS}
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)
    old_wakeup = signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    _STATE.__init__(installed=True, program=program, exit_at_once=exit_at_once)
    watcher = threading.Thread(target=_watch, args=(read_fd,), name="omniwarp-interrupt", daemon=True)
    try:
        for sig in SIGNALS:
            signal.signal(sig, _handler)
        watcher.start()
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old if old is not None else signal.SIG_DFL)
        signal.set_wakeup_fd(old_wakeup)
        os.close(write_fd)  # the watcher reads EOF and ends
        watcher.join(timeout=5.0)
        os.close(read_fd)
        _STATE.__init__()


def requested() -> bool:
    """True once a signal arrived during this command."""
    return _STATE.requested


def check(where: str = "interrupted") -> None:
    """Raise `Interrupted` if a signal arrived and was not raised yet."""
    if _STATE.requested and not _STATE.raised:
        _STATE.raised = True
        raise Interrupted(where)


@contextmanager
def deferred() -> Iterator[None]:
    """A section a signal must not cut in two: it is raised when the section ends."""
    _STATE.deferred += 1
    try:
        yield
    finally:
        _STATE.deferred -= 1
    if not _STATE.deferred:
        check()


@contextmanager
def blocking(what: str) -> Iterator[None]:
    """A blocking C call (a render) that Python cannot interrupt: see the module notes."""
    with _STATE.lock:
        _STATE.blocking = what
        _STATE.deferred += 1
    try:
        yield
    finally:
        with _STATE.lock:
            _STATE.blocking = None
            _STATE.deferred -= 1
    if not _STATE.deferred:
        check(f"interrupted during the {what}; stopped when it returned")


@contextmanager
def temporary_dir(prefix: str, parent: Path | None = None) -> Iterator[Path]:
    """A new folder (in `parent`, else the system's temp folder), removed on exit, and
    on an immediate exit by the watcher."""
    path = Path(tempfile.mkdtemp(prefix=prefix, dir=None if parent is None else str(parent)))
    _STATE.temporaries.append(path)
    try:
        yield path
    finally:
        with deferred():  # a second Ctrl-C must not leave it half removed
            _remove(path)
            if path in _STATE.temporaries:
                _STATE.temporaries.remove(path)


def register_temporary(path: Path) -> None:
    """Also remove `path` on an immediate exit (its owner removes it otherwise, e.g.
    Blender its session folder when the process ends normally)."""
    path = Path(path)
    if path not in _STATE.temporaries:
        _STATE.temporaries.append(path)


def stop_child(proc: subprocess.Popen, grace_s: float = 3.0) -> None:
    """End a child process on an interrupt (or any failure of the parent): SIGTERM,
    then SIGKILL after `grace_s`; waits so that no zombie is left."""
    if proc.poll() is not None:
        return
    proc.terminate()
    try:
        proc.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
