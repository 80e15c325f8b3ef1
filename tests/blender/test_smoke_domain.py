"""A smoke simulation's domain is Volume geometry, as Cycles renders it (issue 43).

Quick Smoke on a cube (tests/support/make_smoke_blend.py) makes a gas domain box whose
material is a Principled Volume of density 5 around the light. Mantaflow does not run in
the PyPI bpy, so the domain holds no smoke: Cycles renders it empty and only the emitter and
the figure shadow the ground. Read as a mesh medium, the box put the light in dense fog
(97 % of the pixels wrong); read as the simulation's grids it casts nothing, and every
method meets the reference.
"""
from __future__ import annotations

import pytest

bpy = pytest.importorskip("bpy", reason="the reference needs bpy")

from addon.core import metrics  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from tests.support.cli_run import SUPPORT, compared, python_ok  # noqa: E402

pytestmark = pytest.mark.blender


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """(reference, rows by method)."""
    folder = tmp_path_factory.mktemp("smoke")
    blend = folder / "smoke.blend"
    python_ok(SUPPORT / "make_smoke_blend.py", blend)
    path, rows = compared(blend, folder, "exact,dpsm+notw,cube", "512")
    return ReferenceData.load(path), {row["method"]: row for row in rows}


def test_an_unbaked_domain_casts_nothing(smoke):
    ref, _ = smoke
    # Ground (2), figure (12) and emitter (12): the domain's box is not a surface or a medium.
    assert len(ref.triangles) == 26
    surface = ref.scene_surface()
    assert not surface.media and not ref.grids and not ref.meta["left_out"]
    # Cycles: the emitter and the figure shadow the ground, the domain does not darken it.
    visibility = metrics.reference_ratio(ref.shadowed, ref.unshadowed)[ref.hit]
    shadowed = float((visibility < 0.5).mean())
    assert 0.005 < shadowed < 0.2, shadowed


def test_every_method_meets_the_reference(smoke):
    _, rows = smoke
    assert rows["exact"]["error_pct"] <= 0.01, rows["exact"]["error_pct"]
    for method in ("dpsm+notw", "cube"):
        assert rows[method]["error_pct"] < 1.0, (method, rows[method]["error_pct"])
