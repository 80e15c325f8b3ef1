"""Ctrl-C through the command line: inside a Cycles render, in the preview's child
process and in the EEVEE child, inside a long `exact` frame (with SIGTERM too: 143),
the run stops with status 130 and one line, no
traceback, no temporary left (TMPDIR stays empty), no cache file and no output
written, and no child process left running."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from addon.core import interrupt
from addon.core.errors import EXIT_INTERRUPTED, EXIT_TERMINATED, Interrupted

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
from cli_run import env_with, omniwarp, staging_left, start_python, stderr_lines, tree_digest  # noqa: E402


def test_a_signal_inside_a_blocking_call_is_raised_when_it_returns():
    """In-process (main() called from Python): the handler only records the signal while
    a blocking call runs, and `Interrupted` comes when it returns; handlers are restored."""
    before = signal.getsignal(signal.SIGINT)
    with interrupt.handling("test"):
        with pytest.raises(Interrupted, match="during the test call; stopped when it returned"):
            with interrupt.blocking("test call"):
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(100):  # bytecodes, for the handler to run in (it only records)
                    time.sleep(0.001)
                assert interrupt.requested()
    assert signal.getsignal(signal.SIGINT) is before and not interrupt.requested()
    with interrupt.handling("test"):
        finished = []
        with pytest.raises(Interrupted, match="interrupted"):
            with interrupt.deferred():  # e.g. moving outputs into place: not cut in two
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(100):
                    time.sleep(0.001)
                finished.append(True)
        assert finished == [True]
    assert signal.getsignal(signal.SIGINT) is before


def _start(args: list[str], env: dict[str, str]) -> subprocess.Popen:
    return start_python("-m", "addon", *args, env=env)


def _interrupt_after(proc: subprocess.Popen, marker: str, settle_s: float = 0.0,
                     child: bool = False) -> tuple[str, str, list[int]]:
    """Read stderr up to the line containing `marker`, wait `settle_s` (to be well inside
    what follows it) or, with `child`, until the process has a child, send SIGINT and
    collect the rest; also return the children the process had when it was interrupted."""
    seen = []
    try:
        for line in proc.stderr:
            seen.append(line)
            if marker in line:
                break
        time.sleep(settle_s)
        children = _children(proc.pid)
        for _ in range(2000):  # the child starts within moments; a bpy import takes far longer
            if children or not child or proc.poll() is not None:
                break
            time.sleep(0.005)
            children = _children(proc.pid)
        proc.send_signal(signal.SIGINT)
        stdout, rest = proc.communicate(timeout=120)  # a guard against a hang, not a timing assertion
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return stdout, "".join(seen) + rest, children


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(v) for v in text.split()]


def _gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return True
    return state in ("Z", "X")


def _assert_interrupted(proc: subprocess.Popen, stdout: str, stderr: str, code: int = EXIT_INTERRUPTED) -> str:
    assert proc.returncode == code, (proc.returncode, stderr[-3000:])
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr[-3000:]
    last = stderr_lines(stderr)[-1]
    assert last.startswith("omniwarp: interrupted") and "temporary files removed" in last, last
    assert [line for line in stderr_lines(stderr) if "interrupted" in line] == [last]
    assert stdout == ""
    return last


@pytest.fixture
def earlier(tmp_path: Path) -> Path:
    out = tmp_path / "out"
    out.mkdir()
    for name in ("results.json", "report.md", "preview.png", "preview.json"):
        (out / name).write_text(f"earlier {name}\n")
    return out


@pytest.mark.blender
@pytest.mark.gl
def test_ctrl_c_inside_a_cycles_render_stops_at_once(tmp_path, earlier):
    """A fresh cache, so the preset must render, at a size that takes seconds even on
    many cores (stopped at once, it costs only the scene set-up here). The run ends
    inside render 1/2 (never reaching 2/2), says so, and leaves no cache file, no
    temporary and the earlier results as they were."""
    pytest.importorskip("bpy", reason="the reference capture needs bpy (scripts/setup_env.sh installs it)")
    tmpdir, cache = tmp_path / "tmp", tmp_path / "cache"
    tmpdir.mkdir()
    before = tree_digest(earlier)
    proc = _start(["compare", "--preset", "room_omni", "--size", "2560x1920", "--methods", "dpsm", "--resolutions",
                   "512", "--frames", "1", "--no-images", "--out", str(earlier)],
                  env_with(OMNIWARP_CACHE=cache, TMPDIR=tmpdir))
    stdout, stderr, _ = _interrupt_after(proc, "Cycles render 1/2", settle_s=0.2)
    last = _assert_interrupted(proc, stdout, stderr)
    assert "during the Cycles render 1/2; stopped at once" in last and "Cycles render 2/2" not in stderr
    assert list(cache.iterdir()) == [] and list(tmpdir.iterdir()) == []
    assert tree_digest(earlier) == before and staging_left(tmp_path) == []


@pytest.mark.blender
@pytest.mark.gl
@pytest.mark.parametrize("args,marker", [
    (["preview", "--preset", "room_hemi", "--size", "160x120"], "drawing the preview"),
    (["compare", "--preset", "room_hemi", "--size", "160x120", "--methods", "eevee", "--frames", "1",
      "--no-images"], "EEVEE renders in a child process"),
], ids=["preview", "eevee"])
def test_ctrl_c_with_a_child_process_ends_the_child_too(tmp_path, earlier, args, marker, reference_cache):
    """The child (Blender's gpu for the preview, EEVEE for its row) is stopped with the
    parent; nothing of it stays behind, not even Blender's session folder."""
    pytest.importorskip("bpy", reason="the children need bpy (scripts/setup_env.sh installs it)")
    tmpdir, cache = tmp_path / "tmp", reference_cache
    tmpdir.mkdir()
    assert omniwarp("reference", "--preset", "room_hemi", "--size", "160x120",
                    env=env_with(OMNIWARP_CACHE=cache)).returncode == 0
    before, cached = tree_digest(earlier), sorted(cache.iterdir())
    proc = _start([*args, "--out", str(earlier)], env_with(OMNIWARP_CACHE=cache, TMPDIR=tmpdir))
    stdout, stderr, children = _interrupt_after(proc, marker, child=True)
    _assert_interrupted(proc, stdout, stderr)
    assert children, "the child process had not started"
    assert all(_gone(pid) for pid in children)
    assert list(tmpdir.iterdir()) == [] and sorted(cache.iterdir()) == cached
    assert tree_digest(earlier) == before and staging_left(tmp_path) == []


@pytest.mark.slow
@pytest.mark.blender
@pytest.mark.gl
def test_ctrl_c_at_any_moment_of_the_start_ends_with_one_line(tmp_path, earlier):
    """SIGINT every 0.25 s from 0.25 to 4 s into `compare --preset all` with an empty cache:
    the imports, bpy's start-up (Cycles and the add-ons registering), the first Cycles
    renders. Each run ends with status 130 and its one line, no traceback and no crash,
    the earlier results as they were and nothing else written but the rows it finished,
    if any (results.partial.json, named in the line; issue 52). How soon it
    ends is measured by scripts/signal_sweep.py (docs/stability.md), not asserted here:
    the bound below only tells an end from a hang (an interrupt lost inside bpy's
    operators once left a run going for minutes)."""
    pytest.importorskip("bpy", reason="the reference capture needs bpy (scripts/setup_env.sh installs it)")
    before = tree_digest(earlier)
    for step in range(1, 17):
        delay = 0.25 * step
        tmpdir, cache = tmp_path / f"tmp{step}", tmp_path / f"cache{step}"
        tmpdir.mkdir()
        # The console script's entry (addon.launch), as a user starts it.
        proc = start_python("-c", "import sys; from addon.launch import main; sys.exit(main())", "compare",
                            "--preset", "all", "--methods", "dpsm", "--resolutions", "256", "--no-images",
                            "--out", str(earlier), env=env_with(OMNIWARP_CACHE=cache, TMPDIR=tmpdir))
        try:
            time.sleep(delay)
            sent = time.perf_counter()
            proc.send_signal(signal.SIGINT)
            stdout, stderr = proc.communicate(timeout=120)  # a guard against a hang
            took = time.perf_counter() - sent
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        assert took < 15.0, (delay, took)
        last = _assert_interrupted(proc, stdout, stderr)
        assert list(tmpdir.iterdir()) == [], (delay, list(tmpdir.iterdir()))
        kept = earlier / "results.partial.json"
        if kept.exists():  # rows finished before the signal: kept, and said so
            count = len(json.loads(kept.read_text()))
            assert f"{count} finished row{'s' if count != 1 else ''} kept in {kept}" in last, (delay, last)
            kept.unlink()
        else:
            assert "kept in" not in last, (delay, last)
        assert not cache.exists() or not [p for p in cache.iterdir() if p.name.endswith(".tmp")], delay
    assert tree_digest(earlier) == before and staging_left(tmp_path) == []


@pytest.mark.slow
@pytest.mark.blender
@pytest.mark.gl
def test_ctrl_c_between_rows_keeps_the_finished_rows(tmp_path, earlier, reference_cache):
    """The rows finished before the signal are kept in results.partial.json, written
    whole after each row; the earlier results stay as they were; the one line says what
    was kept; a finished run then removes the file (issue 52)."""
    pytest.importorskip("bpy", reason="the reference capture needs bpy (scripts/setup_env.sh installs it)")
    args = ["compare", "--preset", "room_omni", "--size", "160x120", "--methods", "dpsm,cube", "--resolutions",
            "256,512", "--repeats", "1", "--no-images", "--out", str(earlier)]
    assert omniwarp(*args[:-2], "--out", str(tmp_path / "warm"), env=env_with(OMNIWARP_CACHE=reference_cache)) \
        .returncode == 0  # the reference cached, so the rows start at once
    before = tree_digest(earlier)
    proc = _start(args, env_with(OMNIWARP_CACHE=reference_cache))
    stdout, stderr, _ = _interrupt_after(proc, "[3/4]")
    last = _assert_interrupted(proc, stdout, stderr)
    kept = earlier / "results.partial.json"
    rows = json.loads(kept.read_text())
    assert [(r["method"], r["resolution"]) for r in rows] == [("dpsm", 256), ("dpsm", 512)]
    assert f"2 finished rows kept in {kept}" in last
    after = tree_digest(earlier)
    assert after.pop("results.partial.json") and after == before  # nothing else touched
    assert omniwarp(*args, env=env_with(OMNIWARP_CACHE=reference_cache)).returncode == 0
    assert not kept.exists() and json.loads((earlier / "results.json").read_text())[0]["method"] == "dpsm"


@pytest.fixture(scope="module")
def groom_sun(tmp_path_factory) -> Path:
    """6,000 hair strands under a sun 11.4 degrees across, 326x183 (issue 52's file): an
    `exact` frame at 1024 takes many minutes on llvmpipe."""
    path = tmp_path_factory.mktemp("groom") / "groom_sun.blend"
    subprocess.run([sys.executable, str(Path(__file__).resolve().parents[1] / "support" / "make_groom_blend.py"),
                    str(path), "--sun-angle", "11.4", "--size", "326", "183"], check=True, capture_output=True)
    return path


@pytest.mark.slow
@pytest.mark.blender
@pytest.mark.gl
@pytest.mark.parametrize("sig,code", [(signal.SIGINT, EXIT_INTERRUPTED), (signal.SIGTERM, EXIT_TERMINATED)],
                         ids=["SIGINT", "SIGTERM"])
def test_a_signal_inside_a_long_exact_frame_ends_the_run(tmp_path, earlier, groom_sun, reference_cache, sig, code):
    """SIGINT or SIGTERM 10 s into an `exact` frame of minutes: the main thread waits on the
    GPU without the GIL (render/backends/moderngl/gl_calls.py, in slices: render/pacing.py),
    so the watchdog ends the run GRACE_S after the signal, with 130 or 143 and its one
    line; nothing written, no temporary left. Before, the signal waited for the frame (a
    SIGINT 2 minutes in: still running 10 minutes later)."""
    pytest.importorskip("bpy", reason="the reference capture needs bpy (scripts/setup_env.sh installs it)")
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    before = tree_digest(earlier)
    proc = _start(["compare", "--blend", str(groom_sun), "--methods", "exact", "--resolutions", "1024",
                   "--repeats", "1", "--soft-samples", "16", "--no-images", "--out", str(earlier)],
                  env_with(OMNIWARP_CACHE=reference_cache, TMPDIR=tmpdir))
    seen = []
    try:
        for line in proc.stderr:
            seen.append(line)
            if "exact @ 1024" in line:
                break
        time.sleep(10.0)
        assert proc.poll() is None, "".join(seen)  # still inside the frame
        sent = time.perf_counter()
        proc.send_signal(sig)
        stdout, rest = proc.communicate(timeout=120)  # a guard against a hang
        took = time.perf_counter() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    last = _assert_interrupted(proc, stdout, "".join(seen) + rest, code)
    assert f"interrupted ({signal.Signals(sig).name})" in last
    # The watchdog's grace, and scheduling slack on a loaded 2-core machine. Where two test
    # runs share the 2 cores (the LTS lines, scripts/test.sh) the watchdog waits for the GIL
    # behind llvmpipe's vertex work in the main thread: 2.6-2.9 s there in CI, 4.7-5.0 s
    # beside four busy loops; that bound shows the run still ends in seconds, not minutes.
    slack = 8.5 if os.environ.get("OMNIWARP_SIDE_BY_SIDE") else 1.5
    assert took < interrupt.GRACE_S + slack, took
    assert list(tmpdir.iterdir()) == [] and tree_digest(earlier) == before and staging_left(tmp_path) == []
