"""The sweep options of `compare` refused as bad input: one line, exit 2, before any work
(no Blender and no Dask needed for these), and --frames as the deprecated --repeats."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pytest

from addon.cli import _repeats
from addon.core.errors import InputError
from addon.shots import parse_frame_range, parse_names

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
from cli_run import omniwarp, one_line  # noqa: E402


def test_frame_ranges():
    assert parse_frame_range("1-24:8") == [1, 9, 17]
    assert parse_frame_range("5-5") == [5]
    assert parse_frame_range(" -2-2:2 ") == [-2, 0, 2]
    assert parse_frame_range(None) is None
    for bad in ("24-1", "1-24:0", "1:24", "a-b", "1-2-3", ""):
        with pytest.raises(InputError, match="bad --frame-range"):
            parse_frame_range(bad)


def test_name_lists():
    assert parse_names("key, rim", "--lights") == ["key", "rim"]
    assert parse_names("all", "--lights") == ["all"] and parse_names(None, "--lights") is None
    for bad, match in ((",", "is empty"), ("all,key", "'all' stands alone")):
        with pytest.raises(InputError, match=match):
            parse_names(bad, "--cameras")


def test_frames_is_the_deprecated_repeats():
    assert _repeats(argparse.Namespace(frames=None, repeats=None)) == (3, "")
    assert _repeats(argparse.Namespace(frames=None, repeats=5)) == (5, "")
    value, warning = _repeats(argparse.Namespace(frames=2, repeats=None))
    assert value == 2 and warning.startswith("warning: --frames is deprecated: use --repeats")
    assert "\n" not in warning
    with pytest.raises(InputError, match="give --repeats only"):
        _repeats(argparse.Namespace(frames=2, repeats=2))


@pytest.mark.parametrize("args, expected", [
    (["--frame-range", "1-3"], "--frame-range apply to --blend only"),
    (["--lights", "all"], "--lights apply to --blend only"),
    (["--repeats", "0"], "bad --repeats 0"),
    (["--frames", "0"], "bad --frames 0"),
    (["--workers", "0"], "bad --workers 0"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not allowed with argument"),
    (["--exact-samples", "32"], "bad --exact-samples 32: must be a square number"),
], ids=["frame-range", "lights", "repeats", "frames", "workers", "workers-and-scheduler", "exact-samples"])
def test_sweep_options_refused_on_a_preset(tmp_path, args, expected):
    line = one_line(omniwarp("compare", "--preset", "room_omni", *args, "--out", tmp_path / "out"))
    assert expected in line, line
    assert not (tmp_path / "out" / "results.json").exists()
