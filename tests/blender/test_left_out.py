"""Nothing Cycles draws is left out in silence (issue 42): the render depsgraph's geometry
that no method draws is named in the log, in every OmniWarp row's note and in report.md;
hair and points, which the methods draw as pieces, are kept and not named.

tests/support/make_left_out_blend.py builds the file (hair curves from geometry nodes,
particle hair, points from a mesh's geometry nodes, a volume, a fog box, true
displacement, a holdout, and decoys that Cycles does not render or that do not block
the light); `omniwarp compare --blend` runs on it in a child process.
"""
from __future__ import annotations

import json

import pytest

pytest.importorskip("bpy", reason="the file and its reference need bpy")

from tests.support.cli_run import SUPPORT, run_python  # noqa: E402

pytestmark = pytest.mark.blender

# Each kind's note must name exactly these objects, for every light and for the light.
from addon.compat.blender import grid_nodes_available  # noqa: E402

# Wisp's grid is read where this line has the grid nodes (5.0 on); elsewhere it is named too.
NAMED = {"volumes that": {"Cloud"} if grid_nodes_available() else {"Cloud", "Wisp"},
         "volume materials": {"Fog"}, "true displacement": {"Bumps"}}
# Rendered and drawn (Ivy's hair is instanced leaves, Mist a homogeneous medium, Wisp a
# volume whose grid is read), not
# rendered by Cycles (Wire's curves from a mesh's geometry nodes) or not rendered at all (Hidden).
NEVER = ("Ivy", "Wire", "Hidden", "Leaf", "Ground", "Mist") + (("Wisp",) if grid_nodes_available() else ())


def _named(notes: list[str]) -> dict[str, set[str]]:
    out = {}
    for note in notes:
        (kind,) = [k for k in NAMED if note.startswith(k)]
        out[kind] = set(note.rsplit(": ", 1)[1].split(", "))
    return out


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    folder = tmp_path_factory.mktemp("left_out")
    blend, notes = folder / "left_out.blend", folder / "notes.json"
    proc = run_python(SUPPORT / "make_left_out_blend.py", blend, "--notes", notes)
    assert proc.returncode == 0, proc.stderr[-3000:]
    run = run_python("-m", "addon.cli", "compare", "--blend", blend, "--methods", "dpsm+notw,exact,unfold",
                     "--resolutions", "256", "--repeats", "1", "--no-images", "--out", folder / "out",
                     "--cache-dir", folder / "cache")
    assert run.returncode == 0, run.stderr[-3000:]
    return (json.loads(notes.read_text()), json.loads((folder / "out" / "results.json").read_text()),
            (folder / "out" / "report.md").read_text(), run.stderr)


def test_the_walk_names_each_kind_and_nothing_else(made):
    notes, _, _, _ = made
    assert _named(notes["all"]) == NAMED and _named(notes["light"]) == NAMED
    # A medium not followed says why (Smoke's density is a noise texture of an attribute).
    (volume,) = [note for note in notes["all"] if note.startswith("volume materials")]
    assert "(Smoke: density varies in space (heterogeneous): not followed): Fog" in volume
    # A volume whose grid is not read says why (Cloud's is inside geometry-nodes instances;
    # on a line without the grid nodes, every volume is named for that).
    (grid,) = [note for note in notes["all"] if note.startswith("volumes that")]
    if grid_nodes_available():
        assert "(a volume inside geometry-nodes instances: not read): Cloud" in grid
        assert notes["grids"] == ["Wisp"]  # read: a grid medium, not named
    else:
        from addon.readers.volume_grids import NO_GRID_NODES

        assert NO_GRID_NODES in grid and notes["grids"] == []
    assert not any(name in note.rsplit(": ", 1)[1].split(", ") for note in notes["all"] for name in NEVER)
    # Hair and points are kept, to be drawn; Unseen casts no shadow (visible_shadow off).
    assert notes["kept"] == {"points": ["Pebbles"], "strands": ["Groom", "Strands", "Unseen"],
                             "light_strands": ["Groom", "Strands"]}
    # A view layer with Strands off renders no hair: none is kept.
    assert _named(notes["no_strands"]) == NAMED
    assert notes["strands"][0] > 0 and notes["strands"][1] == 0


def test_every_row_the_report_and_the_log_name_what_is_not_drawn(made):
    notes, rows, report, stderr = made
    from addon.compare import MEDIA_NOTE, UNFOLD_PIECES_NOTE

    assert {row["method"] for row in rows} == {"dpsm+notw", "exact", "unfold"}
    for row in rows:
        # unfold alone draws no hair and points, nor Mist's homogeneous medium, and says so.
        own = [UNFOLD_PIECES_NOTE, MEDIA_NOTE] if row["method"] == "unfold" else []
        assert row["note"].split("; ") == notes["light"] + own, row["note"]
        assert any("holdout" in note and "Cutout" in note for note in row["scene_notes"])
    for note in notes["light"]:
        assert report.count(f"(every OmniWarp row): {note}") == 1
        assert note in stderr  # the capture's warning
