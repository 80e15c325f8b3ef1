"""A shot swept by `compare --blend F --lights ... --frame-range ...`, serially and on a real
Dask cluster of two workers (docs/sweeps.md): the same rows either way, also when a
worker is killed in the middle of the run, and Ctrl-C leaves nothing behind.

The .blend is tiny and animated (tests/support/make_shot_blend.py); each run that must
render Cycles gets a fresh cache, so there is work in flight to kill or interrupt."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("bpy", reason="--blend needs bpy (scripts/setup_env.sh installs it)")
pytest.importorskip("distributed", reason="the cluster runs need the dask extra (scripts/setup_env.sh installs it)")
pytestmark = [pytest.mark.blender, pytest.mark.gl, pytest.mark.dask, pytest.mark.slow]

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
from cli_run import (  # noqa: E402
    REPO,
    SUPPORT,
    env_with,
    omniwarp,
    one_line,
    python_ok,
    run_python,
    staging_left,
    start_python,
    stderr_lines,
)

SWEEP = ("--lights", "key,rim", "--frame-range", "1-24:8", "--methods", "dpsm,exact", "--resolutions", "256",
         "--repeats", "1")
EXIT_INTERRUPTED = 130


@pytest.fixture(scope="module")
def shot(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("shot") / "shot.blend"
    python_ok(SUPPORT / "make_shot_blend.py", path, timeout=300)
    assert path.is_file()
    return path


@pytest.fixture(scope="module")
def serial(shot, tmp_path_factory) -> list[dict]:
    """The serial run of the sweep: 3 frames x 2 lights x 2 methods."""
    folder = tmp_path_factory.mktemp("serial")
    proc = omniwarp("compare", "--blend", shot, *SWEEP, "--out", folder / "out",
                    env=env_with(OMNIWARP_CACHE=folder / "cache"))
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads((folder / "out" / "results.json").read_text())


def _errors(rows: list[dict]) -> list[tuple]:
    return [(r["frame"], r["light"], r["camera"], r["method"], r["resolution"], r["error_pct"], r["evaluated_pixels"])
            for r in rows]


def test_a_sweep_has_a_row_per_frame_light_and_method(serial):
    assert len(serial) == 12
    assert {(r["frame"], r["light"]) for r in serial} == {(f, light) for f in (1, 9, 17) for light in ("key", "rim")}
    assert all(r["preset"] == "shot" and r["camera"] for r in serial)
    # The animation is evaluated per frame: the crate and the key light move, so do the shadows.
    dpsm_key = {r["frame"]: r["evaluated_pixels"] for r in serial if r["method"] == "dpsm" and r["light"] == "key"}
    assert len(set(dpsm_key.values())) > 1, dpsm_key
    assert all(r["error_pct"] == 0.0 for r in serial if r["method"] == "exact")


def test_two_local_workers_give_the_serial_rows(shot, serial, tmp_path):
    out = tmp_path / "out"
    proc = omniwarp("compare", "--blend", shot, *SWEEP, "--workers", "2", "--out", out,
                    env=env_with(OMNIWARP_CACHE=tmp_path / "cache"))
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = json.loads((out / "results.json").read_text())
    assert _errors(rows) == _errors(serial)
    assert "[6/6 jobs]" in proc.stderr and "Traceback" not in proc.stderr
    # The images came back from the workers, one set per job, and the plot over the frames.
    images = {p.name for p in (out / "images").iterdir()}
    assert {f"shot_f{f:04d}_{light}_dpsm_256_mismatch.png" for f in (1, 9, 17) for light in ("key", "rim")} <= images
    assert (out / "error_vs_frame.png").is_file()
    # The references the workers rendered came back into this run's cache: a serial run finds them all.
    again = omniwarp("compare", "--blend", shot, *SWEEP, "--no-images", "--out", tmp_path / "again",
                     env=env_with(OMNIWARP_CACHE=tmp_path / "cache"))
    assert again.returncode == 0 and "rendering Cycles reference" not in again.stderr, again.stderr[-3000:]


def test_without_workers_dask_is_not_imported(shot, tmp_path):
    """The serial path runs without importing dask or distributed (they may be absent)."""
    code = ("import sys; from addon.cli import main; "
            f"rc = main(['compare', '--blend', {str(shot)!r}, '--lights', 'key', '--methods', 'dpsm', "
            f"'--resolutions', '256', '--repeats', '1', '--no-images', '--out', {str(tmp_path / 'out')!r}]); "
            "print('RESULT', rc, sorted(m for m in ('dask', 'distributed') if m in sys.modules))")
    proc = run_python("-c", code, env=env_with(OMNIWARP_CACHE=tmp_path / "cache"), timeout=300)
    assert "RESULT 0 []" in proc.stdout, (proc.stdout[-2000:], proc.stderr[-2000:])


def _dask(*args: str, env: dict[str, str]) -> subprocess.Popen:
    return subprocess.Popen([str(Path(sys.executable).parent / "dask"), *args], cwd=REPO, env=env, text=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def test_a_killed_worker_s_job_is_run_again(shot, serial, tmp_path):
    """`dask scheduler` and two `dask worker`s started by hand (no nanny: a killed worker
    stays dead); one is SIGKILLed once the first job is done: the run completes with
    the serial run's errors."""
    env = env_with(PYTHONPATH=REPO, OMNIWARP_CACHE=tmp_path / "cache")
    address_file = tmp_path / "scheduler.json"
    procs = [_dask("scheduler", "--scheduler-file", str(address_file), "--no-dashboard", "--port", "0", env=env)]
    try:
        for _ in range(600):  # a guard against a hang, not a timing assertion
            if address_file.is_file() and address_file.stat().st_size:
                break
            time.sleep(0.1)
        address = json.loads(address_file.read_text())["address"]
        procs += [_dask("worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                        "--local-directory", str(tmp_path / f"w{i}"), env=env) for i in range(2)]
        run = start_python("-m", "addon", "compare", "--blend", shot, *SWEEP, "--scheduler", address, "--no-images",
                           "--out", tmp_path / "out", env=env)
        seen = []
        try:
            for line in run.stderr:
                seen.append(line)
                if "[1/6 jobs]" in line:
                    os.kill(procs[1].pid, signal.SIGKILL)  # its next job is in flight by now
                    break
            stdout, rest = run.communicate(timeout=600)
        finally:
            _stop(run)
        stderr = "".join(seen) + rest
        assert procs[1].wait(timeout=60) == -signal.SIGKILL
        assert run.returncode == 0, stderr[-3000:]
        assert "[6/6 jobs]" in stderr
        rows = json.loads((tmp_path / "out" / "results.json").read_text())
        assert _errors(rows) == _errors(serial)
    finally:
        for proc in procs:
            _stop(proc)


def _descendants(pid: int) -> list[int]:
    found, todo = [], [pid]
    while todo:
        current = todo.pop()
        children = []
        # Every thread's children: the local cluster starts its workers from its own thread.
        for task in Path(f"/proc/{current}/task").glob("*"):
            try:
                children += [int(v) for v in (task / "children").read_text().split()]
            except OSError:
                continue
        found += children
        todo += children
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def test_ctrl_c_on_a_cluster_run_exits_130_and_leaves_nothing(shot, tmp_path):
    tmpdir, cache, out = tmp_path / "tmp", tmp_path / "cache", tmp_path / "out"
    tmpdir.mkdir()
    proc = start_python("-m", "addon", "compare", "--blend", shot, *SWEEP, "--workers", "2", "--out", out,
                        env=env_with(OMNIWARP_CACHE=cache, TMPDIR=tmpdir))
    seen, workers = [], []
    try:
        for line in proc.stderr:
            seen.append(line)
            if "running 6 jobs" in line:
                break
        workers = _descendants(proc.pid)
        proc.send_signal(signal.SIGINT)
        stdout, rest = proc.communicate(timeout=120)  # a guard against a hang
    finally:
        _stop(proc)
    stderr = "".join(seen) + rest
    assert proc.returncode == EXIT_INTERRUPTED, (proc.returncode, stderr[-3000:])
    assert "Traceback" not in stderr and stdout == ""
    assert stderr_lines(stderr)[-1].startswith("omniwarp: interrupted"), stderr[-2000:]
    assert workers, "the local cluster had no worker processes when interrupted"
    for _ in range(100):  # worker processes may take a moment to be reaped
        if not any(_alive(pid) for pid in workers):
            break
        time.sleep(0.1)
    assert not [pid for pid in workers if _alive(pid)]
    assert list(tmpdir.iterdir()) == [] and not (out / "results.json").exists() and staging_left(tmp_path) == []


@pytest.mark.parametrize("where", [[], ["--workers", "2"]], ids=["serial", "workers"])
def test_a_job_on_bad_input_ends_the_run_with_its_one_line(tmp_path, where):
    """The key light is dark from frame 17 on: the file passes the checks at its current
    frame, and the job of frame 17 refuses it. The run ends with exit 2 and that one line
    (naming the job), and writes nothing."""
    path = tmp_path / "dark.blend"
    python_ok(SUPPORT / "make_shot_blend.py", path, "--dark-key-at", "17", timeout=300)
    out = tmp_path / "out"
    proc = omniwarp("compare", "--blend", path, *SWEEP, *where, "--out", out,
                    env=env_with(OMNIWARP_CACHE=tmp_path / "cache"))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    errors = [line for line in stderr_lines(proc.stderr) if line.startswith("omniwarp: error:")]
    assert errors == stderr_lines(proc.stderr)[-1:]
    assert "dark frame 17 light key" in errors[0] and "emits nothing" in errors[0], errors
    assert not (out / "results.json").exists() and staging_left(tmp_path) == []


@pytest.mark.parametrize("args, expected", [
    (["--lights", "key,nosuch"], "--lights 'nosuch': no rendered point, spot, sun or area light of that name in shot.blend"),
    (["--cameras", "side,nosuch"], "--cameras 'nosuch': no perspective or orthographic camera"),
    (["--light", "key", "--lights", "rim"], "--light and --lights: give one of them"),
    ([], "has several point, spot, sun or area lights (key, rim); name one with --light, or several with --lights"),
    (["--frame-range", "9-1"], "bad --frame-range '9-1'"),
], ids=["light", "camera", "light-and-lights", "several-lights", "frame-range"])
def test_a_shot_s_names_are_checked_before_any_render(shot, tmp_path, args, expected):
    cache = tmp_path / "cache"
    line = one_line(omniwarp("compare", "--blend", shot, *args, "--out", tmp_path / "out",
                             env=env_with(OMNIWARP_CACHE=cache)))
    assert expected in line, line
    assert not cache.exists() or list(cache.iterdir()) == []


def test_no_scheduler_at_the_address_is_one_line(tmp_path):
    line = one_line(omniwarp("compare", "--preset", "room_omni", "--scheduler", "tcp://127.0.0.1:1",
                             "--out", tmp_path / "out"))
    assert "--scheduler tcp://127.0.0.1:1: no Dask scheduler answered" in line and "dask scheduler" in line, line


def test_lights_and_cameras_all(shot, tmp_path):
    """`all` takes every rendered light and every camera: 2 x 2 jobs at one frame."""
    out = tmp_path / "out"
    proc = omniwarp("compare", "--blend", shot, "--lights", "all", "--cameras", "all", "--methods", "dpsm",
                    "--resolutions", "256", "--frames", "1", "--no-images", "--out", out,
                    env=env_with(OMNIWARP_CACHE=tmp_path / "cache"))
    assert proc.returncode == 0, proc.stderr[-3000:]
    # --frames is the deprecated --repeats: one warning line, and it still counts the repeats.
    assert len([line for line in proc.stderr.splitlines() if "--frames is deprecated" in line]) == 1
    rows = json.loads((out / "results.json").read_text())
    assert sorted((r["light"], r["camera"]) for r in rows) == sorted(
        (light, camera) for light in ("key", "rim") for camera in ("shot_scene_camera", "side"))
    assert {r["frame"] for r in rows} == {1}  # the file's current frame
    assert all(r["frames"] == 1 for r in rows)
    # The result lines say the light and camera, which vary; the frame does not.
    assert all(" light " in line and " camera " in line and " frame " not in line
               for line in proc.stdout.splitlines()), proc.stdout
