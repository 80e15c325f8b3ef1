"""The reference cache through the command line: `reference` fills exactly what
`compare` reads (one Cycles render for both), and a damaged cache file is named in
one warning line, rendered again and replaced, so the run succeeds."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from addon.reference.data import ReferenceData

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
from cli_run import env_with, omniwarp, stderr_lines  # noqa: E402

pytest.importorskip("bpy", reason="rendering a reference needs bpy (scripts/setup_env.sh installs it)")
pytestmark = [pytest.mark.blender, pytest.mark.gl, pytest.mark.slow]

PRESET = "room_hemi"
SIZE = "160x120"
COMPARE = ("compare", "--preset", PRESET, "--size", SIZE, "--methods", "dpsm", "--resolutions", "512",
           "--frames", "1", "--no-images")
RENDERING = f"rendering Cycles reference of {PRESET}"


def _cache_files(cache: Path) -> list[Path]:
    return sorted(cache.iterdir())


def test_reference_then_compare_renders_once_and_a_damaged_file_heals(tmp_path):
    cache = tmp_path / "cache"
    env = env_with(OMNIWARP_CACHE=cache)
    made = omniwarp("reference", "--preset", PRESET, "--size", SIZE, env=env)
    assert made.returncode == 0, made.stderr[-3000:]
    assert made.stderr.count(RENDERING) == 1 and made.stdout.startswith(f"{PRESET}: {SIZE}")
    (cached,) = _cache_files(cache)  # one file, no temporary beside it

    first = omniwarp(*COMPARE, "--out", tmp_path / "out", env=env)
    assert first.returncode == 0, first.stderr[-3000:]
    assert RENDERING not in first.stderr  # the reference command filled the key compare reads

    for damage in (lambda data: data[: len(data) // 2], lambda data: b""):  # cut short, then empty
        cached.write_bytes(damage(cached.read_bytes()))
        healed = omniwarp(*COMPARE, "--out", tmp_path / "out", env=env)
        assert healed.returncode == 0 and "Traceback" not in healed.stderr, healed.stderr[-3000:]
        warnings = [line for line in stderr_lines(healed.stderr) if line.startswith("WARNING")]
        assert len(warnings) == 1 and cached.name in warnings[0] and "rendering it again" in warnings[0], warnings
        assert healed.stderr.count(RENDERING) == 1
        assert _cache_files(cache) == [cached]
        assert ReferenceData.load(cached).resolution == (160, 120)  # rebuilt whole
