"""Ctrl-C (SIGINT) and SIGTERM for the commands: stop, remove temporaries, exit 130 (143).

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

Before a command's `handling()` is in place, `hold_until_handled()` (the command line's
first call, addon/launch.py) records a signal, and `handling()` then ends the command with
its one line: the seconds spent importing numpy, moderngl and the project's modules no
longer end in a KeyboardInterrupt traceback from inside an import. `hold_imports("bpy")`
holds a signal while bpy starts: its C start-up registers Cycles and the bundled add-ons
(a signal raised there left Cycles unregistered, "enum CYCLES not found", or crashed the
process), and the interrupt is raised once the import is done.
"""
from __future__ import annotations

import importlib.abc
import logging
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from .errors import Interrupted, report_interrupt

log = logging.getLogger(__name__)

SIGNALS = (signal.SIGINT, signal.SIGTERM)
GRACE_S = 1.0  # how long the command's own process has to end on a signal before the watchdog ends it


@dataclass
class _State:
    installed: bool = False
    program: str = "omniwarp"
    exit_at_once: bool = False  # the process is the command's own: the watcher may end it
    signals: int = 0  # signals the Python handler saw
    requested: bool = False  # a signal arrived (set by the handler or the watcher)
    name: str = ""  # the first signal's name, for the one line
    signum: int = 0  # the first signal's number, for the exit status (128 + it)
    raised: bool = False  # Interrupted was raised once already
    deferred: int = 0  # depth of deferred() / blocking() / held-import sections
    critical: int = 0  # depth of deferred() sections alone: what the watchdog must not cut
    done: bool = False  # the command's handling() has ended
    blocking: str | None = None  # the blocking C call the main thread is in, if any
    temporaries: list[Path] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)


_STATE = _State()
_EARLY: list[int] = []  # signals recorded by hold_until_handled() before handling()
# Session folders of held imports (bpy's /tmp/blender_*): an immediate exit removes them
# too, whenever the import happened (its owner removes them on a normal exit).
_SESSION_DIRS: list[Path] = []
# Child processes running now (child.run_module): an immediate exit kills them first, so
# that none outlives the command.
_CHILDREN: set[subprocess.Popen] = set()
# What an interrupted run keeps (outputs.FinishedRows), for its one line; outlives handling().
_KEPT = {"note": ""}


def set_kept(note: str) -> None:
    """Say what an interruption now would keep ("" for nothing)."""
    _KEPT["note"] = note


def kept_note() -> str:
    return _KEPT["note"]


def _record_early(signum: int, _frame) -> None:
    _EARLY.append(signum)


def hold_until_handled() -> None:
    """Record SIGINT and SIGTERM until a command's `handling()` takes over (main thread only)."""
    if threading.current_thread() is threading.main_thread():
        for sig in SIGNALS:
            signal.signal(sig, _record_early)


def _handler(signum: int, _frame) -> None:
    """Python-level handler (main thread, between bytecodes)."""
    _STATE.signals += 1
    _STATE.name = _STATE.name or signal.Signals(signum).name
    _STATE.signum = _STATE.signum or signum
    if _STATE.signals > 1 and _STATE.raised:
        if _STATE.exit_at_once:
            # A second Ctrl-C while the first one is being cleaned up: the user insists.
            _exit_now(f"interrupted again ({signal.Signals(signum).name})")
        raise Interrupted(f"interrupted again ({signal.Signals(signum).name})", _STATE.signum)
    _STATE.requested = True
    if _STATE.deferred or _STATE.raised:
        return
    _STATE.raised = True
    raise Interrupted(f"interrupted ({signal.Signals(signum).name})", signum)


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
        first = next(byte for byte in data if byte in SIGNALS)
        _STATE.signum = _STATE.signum or first
        _STATE.requested = True
        with _STATE.lock:
            if _STATE.blocking is not None and _STATE.exit_at_once:
                _exit_now(f"interrupted during the {_STATE.blocking}; stopped at once")
        if _STATE.exit_at_once:
            _watchdog(signal.Signals(first).name)


def _watchdog(name: str) -> None:
    """The command's own process, GRACE_S after a signal the main thread has not ended on
    (an interrupt lost inside a `bpy.ops` call, a long C call that released the GIL): end
    it now, unless it is inside a section that must not be cut (moving outputs)."""
    deadline = time.monotonic() + GRACE_S
    while not _STATE.done:
        if time.monotonic() >= deadline:
            with _STATE.lock:  # deferred() enters and leaves under the same lock
                if not _STATE.done and not _STATE.critical:
                    _exit_now(f"interrupted ({name}); stopped after {GRACE_S:g} s")
        time.sleep(0.02)


def _exit_now(message: str) -> None:
    """Remove the registered temporaries, print the one line and end the process (130)."""
    for proc in list(_CHILDREN):
        try:
            proc.kill()
        except OSError:
            pass  # it has ended already
    for path in [*_STATE.temporaries, *_SESSION_DIRS]:
        _remove(path)
    try:
        sys.stdout.flush()
    except (OSError, ValueError):
        pass  # a closed or broken stdout must not keep the process alive
    try:  # the main thread may be half-way through a progress line: start the one line anew
        sys.stderr.write("\n")
    except (OSError, ValueError):
        pass
    code = report_interrupt(_STATE.program, Interrupted(message, _STATE.signum or signal.SIGINT), kept_note())
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
    set_kept("")
    watcher = threading.Thread(target=_watch, args=(read_fd,), name="omniwarp-interrupt", daemon=True)
    try:
        for sig in SIGNALS:
            signal.signal(sig, _handler)
        watcher.start()
        if _EARLY:  # a signal came while the command line was starting
            name = signal.Signals(_EARLY[0]).name
            _STATE.requested = _STATE.raised = True
            _STATE.signum = _EARLY[0]
            _EARLY.clear()
            raise Interrupted(f"interrupted ({name}) while starting", _STATE.signum)
        yield
    finally:
        with _STATE.lock:
            _STATE.done = True  # the watchdog stands down: main() reports the interrupt itself
        for sig, old in previous.items():
            signal.signal(sig, old if old is not None else signal.SIG_DFL)
        signal.set_wakeup_fd(old_wakeup)
        os.close(write_fd)  # the watcher reads EOF and ends
        watcher.join(timeout=5.0)
        os.close(read_fd)
        _STATE.__init__()


def watching() -> bool:
    """True while a command's handling() is in place (so a signal may come and be acted on)."""
    return _STATE.installed


def requested() -> bool:
    """True once a signal arrived during this command."""
    return _STATE.requested


def check(where: str = "") -> None:
    """Raise `Interrupted` if a signal arrived and was not raised yet."""
    if _STATE.requested and not _STATE.raised:
        _STATE.raised = True
        raise Interrupted(where or f"interrupted ({_STATE.name or 'signal'})", _STATE.signum or signal.SIGINT)


@contextmanager
def deferred() -> Iterator[None]:
    """A section a signal must not cut in two: it is raised when the section ends."""
    with _STATE.lock:
        _STATE.deferred += 1
        _STATE.critical += 1
    try:
        yield
    finally:
        with _STATE.lock:  # `deferred` last: a signal handled in between sees it still held
            _STATE.critical -= 1
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


class _HeldLoader(importlib.abc.Loader):
    """A module's own loader, run with signals held (`deferred`): the interrupt is raised
    when the module's start-up is done, not inside it."""

    def __init__(self, loader) -> None:
        self.loader = loader

    def create_module(self, spec):
        with _held():
            return self.loader.create_module(spec)

    def exec_module(self, module) -> None:
        with deferred():
            self.loader.exec_module(module)
            tempdir = getattr(getattr(module, "app", None), "tempdir", "")  # bpy's session folder
            if tempdir:
                _SESSION_DIRS.append(Path(tempdir))


@contextmanager
def _held() -> Iterator[None]:
    """`deferred` without the check at its end (the check comes in exec_module)."""
    _STATE.deferred += 1
    try:
        yield
    finally:
        _STATE.deferred -= 1


class _HeldImports(importlib.abc.MetaPathFinder):
    """Finds the named modules through the other finders and hands them a _HeldLoader."""

    def __init__(self, names: frozenset[str]) -> None:
        self.names = names

    def find_spec(self, fullname, path, target=None):
        if fullname not in self.names:
            return None
        for finder in sys.meta_path:
            find = getattr(finder, "find_spec", None)
            if finder is self or find is None:
                continue
            spec = find(fullname, path, target)
            if spec is not None:
                if spec.loader is not None:
                    spec.loader = _HeldLoader(spec.loader)
                return spec
        return None


def hold_imports(*names: str) -> None:
    """Hold signals while any of `names` is first imported (idempotent)."""
    wanted = frozenset(names)
    if not any(isinstance(f, _HeldImports) and f.names == wanted for f in sys.meta_path):
        sys.meta_path.insert(0, _HeldImports(wanted))


@contextmanager
def temporary_dir(prefix: str, parent: Path | None = None) -> Iterator[Path]:
    """A new folder (in `parent`, else the system's temp folder), removed on exit, and
    on an immediate exit by the watcher."""
    path: Path | None = None
    try:
        # Made and registered in one step: neither the handler (held) nor the watcher's
        # immediate exit (the lock) can come between the folder and its registration.
        with _STATE.lock, _held():
            path = Path(tempfile.mkdtemp(prefix=prefix, dir=None if parent is None else str(parent)))
            _STATE.temporaries.append(path)
        if not _STATE.deferred:
            check()
        yield path
    finally:
        if path is not None:
            with deferred():  # a second Ctrl-C must not leave it half removed
                _remove(path)
                if path in _STATE.temporaries:
                    _STATE.temporaries.remove(path)


def register_temporary(path: Path) -> None:
    """Also remove `path` on an immediate exit (its owner removes it otherwise, e.g.
    Blender its session folder when the process ends normally). Nothing to do outside a
    command's handling (inside Blender's UI no immediate exit happens)."""
    path = Path(path)
    if _STATE.installed and path not in _STATE.temporaries:
        _STATE.temporaries.append(path)


def track_child(proc: subprocess.Popen) -> None:
    """Kill `proc` on an immediate exit, until `forget_child`."""
    _CHILDREN.add(proc)


def forget_child(proc: subprocess.Popen) -> None:
    _CHILDREN.discard(proc)


def stop_child(proc: subprocess.Popen, grace_s: float = 0.5) -> None:
    """End a child process on an interrupt (or any failure of the parent): SIGTERM,
    then SIGKILL after `grace_s` (well inside the watchdog's GRACE_S: the command ends
    within about a second); waits so that no zombie is left."""
    if proc.poll() is not None:
        return
    proc.terminate()
    try:
        proc.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
