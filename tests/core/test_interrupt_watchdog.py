"""The interrupt watchdog (core/interrupt.py) in a process of its own: a signal whose
interrupt is swallowed (as Blender's operator wrapper does) still ends the command, one
GRACE_S later, with status 130 and one line; a section that moves outputs is not cut;
and a signal before the handling is in place ends the command when it starts."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

SWALLOWED = """
import sys, time
from addon.core import interrupt
from addon.core.errors import Interrupted
with interrupt.handling("probe", exit_at_once=True):
    end, ready = time.monotonic() + 30, False
    while time.monotonic() < end:
        try:
            if not ready:
                ready = True
                print("ready", flush=True)
            time.sleep(0.01)
        except Interrupted:
            pass  # lost, as inside bpy.ops
print("ran to the end", flush=True)
"""

CRITICAL = """
import sys, time
from pathlib import Path
from addon.core import interrupt
from addon.core.errors import Interrupted
with interrupt.handling("probe", exit_at_once=True):
    try:
        with interrupt.deferred():
            print("ready", flush=True)
            time.sleep(2.5)  # a move of outputs the watchdog must not cut
            Path(sys.argv[1]).write_text("moved")
        time.sleep(30)
    except Interrupted:
        while True:  # and then lost
            try:
                time.sleep(0.01)
            except Interrupted:
                pass
"""

EARLY = """
import os, signal, sys, time
from addon.core import interrupt
from addon.core.errors import report_interrupt
interrupt.hold_until_handled()
os.kill(os.getpid(), signal.SIGTERM)  # while the command line would still be importing
time.sleep(0.2)
try:
    with interrupt.handling("probe", exit_at_once=True):
        print("the command ran", flush=True)
except KeyboardInterrupt as exc:
    sys.exit(report_interrupt("probe", exc))
"""


def _run(code: str, *args: str, signal_after_ready: bool = True) -> tuple[subprocess.CompletedProcess, float]:
    proc = subprocess.Popen([sys.executable, "-c", code, *args], cwd=REPO, text=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    sent = time.perf_counter()
    if signal_after_ready:
        assert proc.stdout.readline().strip() == "ready"
        sent = time.perf_counter()
        proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr), time.perf_counter() - sent


def test_a_swallowed_interrupt_still_ends_the_command():
    from addon.core.interrupt import GRACE_S

    done, took = _run(SWALLOWED)
    assert done.returncode == 130 and "ran to the end" not in done.stdout
    lines = done.stderr.strip().splitlines()
    assert lines == [f"probe: interrupted (SIGINT); stopped after {GRACE_S:g} s; temporary files removed, "
                     "earlier results untouched"], done.stderr
    assert took >= GRACE_S


def test_the_watchdog_waits_for_a_move_of_outputs(tmp_path):
    marker = tmp_path / "moved"
    done, took = _run(CRITICAL, str(marker))
    assert done.returncode == 130 and marker.read_text() == "moved"  # the section ran to its end
    assert took >= 2.0 and "stopped after" in done.stderr


def test_a_signal_before_the_handling_ends_the_command_when_it_starts():
    done, _ = _run(EARLY, signal_after_ready=False)
    assert done.returncode == 143 and "the command ran" not in done.stdout
    assert done.stderr.strip().splitlines() == [
        "probe: interrupted (SIGTERM) while starting; temporary files removed, earlier results untouched"]


def test_a_signal_while_a_temporary_folder_is_made_removes_it(tmp_path, monkeypatch):
    """SIGINT arriving inside `mkdtemp` (the folder exists, not yet registered) is raised
    once the folder is registered, so the folder is removed as the interrupt leaves."""
    import os
    import tempfile

    import pytest

    from addon.core import interrupt
    from addon.core.errors import Interrupted

    real = tempfile.mkdtemp

    def mkdtemp_then_signal(*args, **kwargs):
        made = real(*args, **kwargs)
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)  # the Python handler runs here, on this thread, before the return
        return made

    monkeypatch.setattr(tempfile, "mkdtemp", mkdtemp_then_signal)
    with interrupt.handling("probe"):
        with pytest.raises(Interrupted):
            with interrupt.temporary_dir("probe_", parent=tmp_path):
                pytest.fail("the interrupt should come before the body")
    assert list(tmp_path.iterdir()) == []
