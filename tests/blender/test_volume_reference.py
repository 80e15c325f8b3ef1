"""The reference renders volumes as Cycles does (issue 43): a fog box beside a figure
(tests/support/make_fog_blend.py) keeps its Principled Volume in the reference, hidden
from camera rays, so each ground pixel's visibility is the fog's transmittance,
exp(-density x the length inside it) along the pixel's segment to the light; its noise is
measured in two halves; and its hit pixels' mean visibility is that of a plain Cycles
render of the file with its own materials (tests/support/plain_cycles.py)."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("bpy", reason="the reference needs bpy")

from addon.core import metrics  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from tests.support.cli_run import SUPPORT, python_ok  # noqa: E402
from tests.support.make_fog_blend import behind_figure, transmittance  # noqa: E402

pytestmark = pytest.mark.blender


@pytest.fixture(scope="module")
def fog(tmp_path_factory):
    """(reference, rows, the file, its folder)."""
    folder = tmp_path_factory.mktemp("fog")
    blend = folder / "fog.blend"
    python_ok(SUPPORT / "make_fog_blend.py", blend)
    python_ok("-m", "addon.cli", "compare", "--blend", blend, "--methods", "dpsm", "--resolutions", "256",
              "--repeats", "1", "--no-images", "--out", folder / "out", "--cache-dir", folder / "cache")
    (path,) = (folder / "cache").glob("*.npz")
    rows = json.loads((folder / "out" / "results.json").read_text())
    return ReferenceData.load(path), rows, blend, folder


def test_the_fog_lets_its_transmittance_through(fog):
    ref, rows, _, _ = fog
    ratio = metrics.reference_ratio(ref.shadowed, ref.unshadowed)
    ground = ref.hit & (np.abs(ref.position[..., 2]) < 1e-3) & ~behind_figure(ref.position)
    expected = transmittance(ref.position)
    under = ground & (expected < 0.99)
    # The camera sees through the fog: every pixel hits the ground or the figure.
    assert ref.hit.mean() > 0.99 and under.sum() > 1000
    error = np.abs(ratio - expected)[ground]
    assert error.mean() < 1e-3 and error.max() < 0.05, (error.mean(), error.max())
    assert 0.2 < float(expected[under].mean()) < 0.8  # partly shadowed, not white or clear
    # Measured in two halves, as a sized light: a homogeneous medium's shadow is exact.
    assert ref.visibility_noise is not None and float(ref.visibility_noise[ground].mean()) < 1e-3
    assert ref.meta["samples"] > 1
    assert "volume materials" in rows[0]["note"]  # the maps still draw the box opaque


def test_the_reference_matches_a_plain_render(fog):
    """Within 1 point of the plain render's mean visibility over the pixels both hit (its
    camera rays cross the fog, so some of its pixels end there and are left out)."""
    ref, _, blend, folder = fog
    python_ok(SUPPORT / "plain_cycles.py", blend, folder / "plain.npz")
    plain = dict(np.load(folder / "plain.npz"))
    eps = metrics.UNSHADOWED_EPS
    both = ref.hit & (plain["alpha"] > 0.5) & (ref.unshadowed > eps) & (plain["unshadowed"] > eps)
    assert both.sum() > 0.8 * ref.hit.sum()
    ours = metrics.reference_ratio(ref.shadowed, ref.unshadowed)[both].mean()
    theirs = metrics.reference_ratio(plain["shadowed"], plain["unshadowed"])[both].mean()
    assert abs(ours - theirs) < 0.01, (ours, theirs)
