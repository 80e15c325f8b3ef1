"""Outputs are moved into place only when a run has finished: a second run into the
same --out leaves no image of the first, and a run stopped half-way leaves the earlier
results exactly as they were, with no staging folder behind."""
from __future__ import annotations

import json
import signal
import sys
from pathlib import Path

import pytest

from addon.core.errors import EXIT_INTERRUPTED, InputError
from addon.core.outputs import StagedOutput

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
from cli_run import env_with, omniwarp, staging_left, start_python, stderr_lines, tree_digest  # noqa: E402

RUN = ("--size", "160x120", "--methods", "dpsm", "--resolutions", "128", "--frames", "1")


def test_staged_output_moves_everything_at_commit_only(tmp_path):
    """Without Blender: nothing reaches the target before commit(); a folder output is
    replaced whole; `replaces` removes an output the new run did not write."""
    target = tmp_path / "out"
    (target / "images").mkdir(parents=True)
    (target / "images" / "old.png").write_text("old")
    (target / "notes.txt").write_text("the user's own file")
    (target / "extra").mkdir()
    with StagedOutput(target, replaces=("images", "extra")) as stage:
        assert stage.path.parent == tmp_path  # beside the target: every move is a rename
        (stage.path / "images").mkdir()
        (stage.path / "images" / "new.png").write_text("new")
        (stage.path / "results.json").write_text("[]")
        assert not (target / "results.json").exists()
        stage.commit()
    assert sorted(p.name for p in (target / "images").iterdir()) == ["new.png"]
    assert (target / "notes.txt").read_text() == "the user's own file" and not (target / "extra").exists()
    assert staging_left(tmp_path) == []
    with pytest.raises(RuntimeError, match="boom"):
        with StagedOutput(target) as stage:
            (stage.path / "results.json").write_text("half")
            raise RuntimeError("boom")
    assert (target / "results.json").read_text() == "[]" and staging_left(tmp_path) == []
    (tmp_path / "afile").write_text("")
    with pytest.raises(InputError, match="is a file"):
        StagedOutput(tmp_path / "afile" / "out")


@pytest.mark.blender
@pytest.mark.gl
@pytest.mark.slow
def test_a_second_run_replaces_the_images_and_a_stopped_run_changes_nothing(tmp_path, reference_cache):
    pytest.importorskip("bpy", reason="the reference capture needs bpy (scripts/setup_env.sh installs it)")
    out = tmp_path / "out"
    env = env_with(OMNIWARP_CACHE=reference_cache)
    first = omniwarp("compare", "--preset", "room_omni", *RUN, "--out", out, env=env)
    assert first.returncode == 0, first.stderr[-3000:]
    assert any(p.name.startswith("room_omni_dpsm_128") for p in (out / "images").iterdir())

    second = omniwarp("compare", "--preset", "room_hemi", *RUN, "--out", out, env=env)
    assert second.returncode == 0, second.stderr[-3000:]
    images = sorted(p.name for p in (out / "images").iterdir())
    assert images and all(name.startswith("room_hemi_") for name in images), images
    assert [row["preset"] for row in json.loads((out / "results.json").read_text())] == ["room_hemi"]

    third = omniwarp("compare", "--preset", "room_hemi", *RUN, "--no-images", "--out", out, env=env)
    assert third.returncode == 0 and not (out / "images").exists()  # no stale images either

    # Stopped half-way through the rows (Ctrl-C while the maps are drawn): the earlier
    # results stay byte for byte, and the rows measured so far are not kept.
    before = tree_digest(out)
    proc = start_python("-m", "addon", "compare", "--preset", "room_hemi", "--size", "160x120", "--methods", "dpsm,cube",
                        "--resolutions", "4096", "--frames", "30", "--out", out, env=env)
    try:
        for line in proc.stderr:
            if line.startswith("[1/2]"):
                break
        proc.send_signal(signal.SIGINT)
        stdout, rest = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == EXIT_INTERRUPTED and "Traceback" not in rest, rest[-3000:]
    assert stderr_lines(rest)[-1].startswith("omniwarp: interrupted") and stdout == ""
    assert tree_digest(out) == before and staging_left(tmp_path) == []
