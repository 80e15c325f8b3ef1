"""Sized lights in an artist's foliage file, measured as the issue measures them (issue 27).

tests/support/make_foliage_blend.py --sized builds the file: collection-instanced leaf
cards with a packed PNG alpha, a chain-link fence, a net curtain of alpha 0.4, a lens
shift, and lights an artist sizes: a 3 degree sun, an ellipse area light on a scaled
object and a blended spot keyed to move between frames 1 and 3. `omniwarp compare` runs
on frame 2 in a child process (moderngl and bpy each own their GL), and every light's
`exact` row must err by at most 2 x its reference's measured noise + 0.05 points, and the
filtered map (dpsm+notw, or sm for the spot and the sun) more than exact but within a few
points (on this file 0.5-2.2 %, EEVEE 4.4-9.2 %: docs/soft.md).
"""
from __future__ import annotations

import json

import pytest

pytest.importorskip("bpy", reason="the file and its reference need bpy")

from tests.support.cli_run import SUPPORT, python_ok  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.slow]

LIGHTS = ("Sun", "Oval", "Key")
# The bound: exact's soft error % <= 2 x reference noise % + 0.05.
NOISE_FACTOR, NOISE_SLACK = 2.0, 0.05


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    folder = tmp_path_factory.mktemp("foliage_sized")
    blend = folder / "foliage_sized.blend"
    python_ok(SUPPORT / "make_foliage_blend.py", blend, "--sized")
    python_ok("-m", "addon.cli", "compare", "--blend", blend, "--lights", ",".join(LIGHTS), "--frame-range", "2-2",
              "--methods", "exact,dpsm+notw,sm", "--resolutions", "1024", "--repeats", "1", "--no-images",
              "--out", folder / "out", "--cache-dir", folder / "cache")
    return json.loads((folder / "out" / "results.json").read_text())


def _row(rows: list[dict], light: str, method: str) -> dict:
    (row,) = [r for r in rows if r["light"] == light and r["method"] == method]
    return row


@pytest.mark.parametrize("light", LIGHTS)
def test_exact_is_within_the_references_noise(rows, light):
    row = _row(rows, light, "exact")
    assert row["frame"] == 2 and row["reference_noise_pct"] > 0.0, row
    bound = NOISE_FACTOR * row["reference_noise_pct"] + NOISE_SLACK
    assert row["soft_error_pct"] <= bound, (row["soft_error_pct"], bound)


@pytest.mark.parametrize("light", LIGHTS)
def test_the_filtered_map_errs_more_than_exact_but_within_reason(rows, light):
    """The filter is an estimate: above exact, and within a few points of Cycles."""
    exact = _row(rows, light, "exact")
    (filtered,) = [r for r in rows if r["light"] == light and r["method"] in ("dpsm+notw", "sm")]
    assert exact["soft_error_pct"] < filtered["soft_error_pct"] < 5.0, (exact, filtered)
