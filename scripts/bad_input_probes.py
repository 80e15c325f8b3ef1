"""Run the bad-input, damaged-cache and Ctrl-C probes of docs/stability.md through the
command line, and print their table (probe, exit status, the line printed).

Everything happens in a temporary folder with its own OMNIWARP_CACHE and TMPDIR; the
repository and the shared cache are not touched. Needs bpy (scripts/setup_env.sh).

Run: .venv/bin/python scripts/bad_input_probes.py
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SMALL = ["--size", "160x120", "--repeats", "1", "--no-images", "--resolutions", "512"]


def _env(root: Path) -> dict[str, str]:
    env = dict(os.environ, OMNIWARP_CACHE=str(root / "cache"), TMPDIR=str(root / "tmp"))
    (root / "tmp").mkdir(exist_ok=True)
    return env


def _run(root: Path, *args: str, prefix: tuple[str, ...] = ()) -> tuple[int, str, str]:
    proc = subprocess.run([*prefix, sys.executable, "-m", "addon", *args], capture_output=True, text=True,
                          cwd=REPO, env=_env(root), timeout=900)
    return proc.returncode, proc.stdout, proc.stderr


def _interrupted(root: Path, marker: str, *args: str, settle_s: float = 0.2) -> tuple[int, str, str]:
    """Start a run, send SIGINT once `marker` is on stderr (after `settle_s`)."""
    proc = subprocess.Popen([sys.executable, "-m", "addon", *args], cwd=REPO, env=_env(root), text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    seen = []
    for line in proc.stderr:
        seen.append(line)
        if marker in line:
            break
    time.sleep(settle_s)
    proc.send_signal(signal.SIGINT)
    out, rest = proc.communicate(timeout=300)
    return proc.returncode, out, "".join(seen) + rest


def _last(stderr: str, needle: str = "") -> str:
    lines = [line for line in stderr.splitlines() if line.strip() and "EGL_BAD" not in line]
    picked = [line for line in lines if needle in line] if needle else lines
    text = (picked or ["(nothing)"])[-1]
    return text.replace(str(Path(tempfile.gettempdir())), "/tmp").replace("|", "\\|")


def _blend(root: Path, name: str, *flags: str) -> Path:
    path = root / f"{name}.blend"
    subprocess.run([sys.executable, str(REPO / "tests" / "support" / "make_blend.py"), str(path), *flags],
                   capture_output=True, check=True, cwd=REPO, timeout=600)
    return path


def _read_only(folder: Path) -> tuple[str, ...]:
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return ()
    script = 'mount --bind "$0" "$0" && mount -o remount,ro,bind "$0" "$0" && shift && exec "$@"'
    return ("unshare", "-m", "--propagation", "private", "sh", "-c", script, str(folder), "_")


def probes(root: Path) -> list[tuple[str, int, str]]:
    good = _blend(root, "scene")
    (root / "notes.blend").write_text("not a scene\n")
    (root / "cut.blend").write_bytes(good.read_bytes()[:20000])
    nan_light = _blend(root, "nan_light", "--light-location", "nan,0,3")
    nan_bias = _blend(root, "nan_bias", "--omniwarp", "dpsm:512", "--bias-constant", "nan")
    (root / "afile").write_text("")
    earlier = root / "earlier"
    earlier.mkdir()
    (earlier / "report.md").write_text("earlier\n")
    rows: list[tuple[str, int, str]] = []

    def add(probe: str, result: tuple[int, str, str], needle: str = "") -> None:
        rows.append((probe, result[0], _last(result[2], needle)))

    add("text file as --blend", _run(root, "compare", "--blend", str(root / "notes.blend"), *SMALL))
    add("truncated .blend as --blend", _run(root, "compare", "--blend", str(root / "cut.blend"), *SMALL))
    add("--out names a file", _run(root, "compare", "--preset", "room_omni", *SMALL, "--out", str(root / "afile")))
    add("--out under a file", _run(root, "compare", "--preset", "room_omni", *SMALL,
                                   "--out", str(root / "afile" / "sub")))
    add("--out read-only folder (checked before any row)",
        _run(root, "compare", "--preset", "room_omni", *SMALL, "--out", str(earlier), prefix=_read_only(earlier)))
    earlier.chmod(0o755)
    add("NaN light position in the .blend", _run(root, "compare", "--blend", str(nan_light), *SMALL))
    add("NaN bias saved on the light (preview)", _run(root, "preview", "--blend", str(nan_bias), "--size", "160x120",
                                                      "--out", str(root / "preview")))
    add("--frames 0", _run(root, "compare", "--preset", "room_omni", *SMALL[:2], "--frames", "0"))
    add("methods that fit no light", _run(root, "compare", "--preset", "sun_field", "--methods", "dpsm", *SMALL))
    add("usage error (no --preset or --blend)", _run(root, "compare", "--methods", "dpsm"))
    add("OMNIWARP_CACHE names a file", (lambda env_root: _run(env_root, "reference", "--preset", "room_hemi",
                                                               "--size", "40x30"))(_cache_under_file(root)))
    reference = _run(root, "reference", "--preset", "room_hemi", "--size", "160x120")
    after = _run(root, "compare", "--preset", "room_hemi", *SMALL, "--out", str(root / "out"))
    rows.append(("`reference` then `compare` (one render)", after[0],
                 f"Cycles renders: reference {reference[2].count('rendering Cycles')}, "
                 f"compare {after[2].count('rendering Cycles')}"))
    cached = next((root / "cache").glob("room_hemi_160x120_*.npz"))
    cached.write_bytes(cached.read_bytes()[:5000])
    add("truncated .npz in the cache (healed, run succeeds)",
        _run(root, "compare", "--preset", "room_hemi", *SMALL, "--out", str(root / "out")), "WARNING")
    for preset in ("room_omni", "room_hemi"):  # the second run's images replace the first's
        second = _run(root, "compare", "--preset", preset, "--size", "160x120", "--frames", "1", "--methods", "dpsm",
                      "--resolutions", "128", "--out", str(root / "twice"))
    names = sorted(p.name for p in (root / "twice" / "images").iterdir())
    rows.append(("a second run into the same --out", second[0],
                 f"images/: {len(names)} files, all room_hemi: {all(n.startswith('room_hemi') for n in names)}"))
    add("Ctrl-C inside the Cycles render",
        _interrupted(root / "fresh", "Cycles render 1/2", "compare", "--preset", "room_omni", "--size", "2560x1920",
                     "--methods", "dpsm", "--frames", "1", "--no-images", "--out", str(root / "out")))
    add("Ctrl-C while the rows are measured",
        _interrupted(root, "[1/2]", "compare", "--preset", "room_hemi", "--size", "160x120", "--methods",
                     "dpsm,cube", "--resolutions", "4096", "--frames", "30", "--out", str(root / "out")))
    add("Ctrl-C in the preview's child process",
        _interrupted(root, "drawing the preview", "preview", "--preset", "room_hemi", "--size", "160x120",
                     "--out", str(root / "preview"), settle_s=0.5))
    return rows


def _cache_under_file(root: Path) -> Path:
    """A root whose OMNIWARP_CACHE lies under a file (see _env)."""
    other = root / "badcache"
    other.mkdir(exist_ok=True)
    (other / "cache").write_text("")  # _env puts the cache at other/cache: a file
    return other


def main() -> int:
    root = Path(tempfile.mkdtemp(prefix="omniwarp_probes_"))
    try:
        (root / "fresh").mkdir()
        rows = probes(root)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print("| probe | exit | the line printed |")
    print("|---|---|---|")
    for probe, code, line in rows:
        print(f"| {probe} | {code} | `{line.replace(str(root), '…')}` |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
