"""Culling (sides, faces, triangles) leaves out only what cannot change a shadow."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import plan as P
from addon.core import samples as SS
from addon.core.presets import build_preset
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from addon.render.frame import Measure
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


PRESET_CASES, PRESET_CASE_SIZE = ["room_omni", "room_hemi", "courtyard"], (128, 96)  # conftest.preset_case


@pytest.mark.parametrize("param", ["dpsm", "cube", "ipsm"])
def test_culling_changes_no_shadow(gl_backend, preset_case, param):
    """Same resolution with and without culling: every evaluated pixel gets the same
    visibility (ipsm changes the parameterization, so it is only checked to cull)."""
    _, scene, samples, _, evaluable = preset_case
    pipe = ShadowPipeline(gl_backend)
    culled = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings(param, 512))
    full = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings(param, 512, cull=False))
    assert culled.passes <= full.passes
    if param != "ipsm":  # IPSM zooms, so its tessellation may add triangles
        assert culled.geometry.triangles_drawn <= full.geometry.triangles_drawn
    if param != "ipsm":
        differ = (culled.visibility != full.visibility)[evaluable].mean()
        assert differ <= 1e-4
        assert not np.any(culled.flags[evaluable] == 3)  # no sample lands in an undrawn layer


def test_occluder_region_contains_every_segment():
    """Points on segments from the light to random receivers in the view are inside the hull."""
    scene = build_preset("courtyard", (64, 48))
    samples, _, _ = view_samples(scene)
    stats = SS.measure(scene.camera, scene.light, samples.positions, samples.hit)
    planes = P.plan_frame(scene.light, "dpsm", scene.camera, stats, far=100.0).occluder_planes
    assert planes is not None and len(planes) >= 5
    rng = np.random.default_rng(0)
    receivers = samples.positions[samples.hit]
    picks = receivers[rng.integers(0, len(receivers), 500)]
    t = rng.random((500, 1))
    points = scene.light.position + t * (picks - scene.light.position)
    inside = points @ planes[:, :3].T - planes[:, 3] <= 1e-6 * (np.abs(planes[:, 3]).max() + 1)
    assert inside.all()
    # A triangle far behind the light cannot shadow anything in view.
    behind = scene.light.position + np.array([[[30, 0, 0], [30, 1, 0], [30, 0, 1]]], float)
    assert P.outside_region(behind, planes).all()


def test_percentile_frustum_is_tighter_than_strict():
    scene = build_preset("courtyard", (64, 48))
    samples, _, _ = view_samples(scene)
    strict = P.truncated_frustum(scene.camera, SS.measure(scene.camera, None, samples.positions, samples.hit))
    robust = P.truncated_frustum(scene.camera, SS.measure(scene.camera, None, samples.positions, samples.hit, percentile=5.0), cut=True)
    cam = scene.camera.matrix_world[:3, 3]
    assert np.linalg.norm(robust[4:] - cam, axis=1).max() < np.linalg.norm(strict[4:] - cam, axis=1).max()


def test_texels_outside_the_readable_box_are_never_read():
    """Culled plain layers clear and draw only their readable box. A frame that follows
    one filling the same atlas layout (ipsm draws its whole tile) must not see its stale
    texels: visibility equals a fresh backend's, and the read-back shows them empty."""
    from addon.render.backends.moderngl.backend import ModernGLBackend

    scene = build_preset("courtyard", (128, 96))
    samples, _, _ = view_samples(scene)
    tris = scene.world_triangles()
    culled = ShadowSettings("dpsm", 256)
    fresh_backend = ModernGLBackend()
    try:
        expected = ShadowPipeline(fresh_backend).render(scene.light, tris, samples, culled, measure=Measure(keep_atlas=True))
    finally:
        fresh_backend.release()
    (slot, box), = expected.boxes.items()  # the one side drawn, with its box
    x0, y0, x1, y1 = box
    assert 0 < (x1 - x0) * (y1 - y0) < 0.5 * 256 * 256  # the box leaves most of the tile out
    backend = ModernGLBackend()
    try:
        pipe = ShadowPipeline(backend)
        stale = pipe.render(scene.light, tris, samples, ShadowSettings("ipsm", 256), measure=Measure(keep_atlas=True))
        assert stale.layout == expected.layout and not stale.boxes
        assert np.count_nonzero(stale.atlas < 1.0) > 4 * np.count_nonzero(expected.atlas < 1.0)
        again = pipe.render(scene.light, tris, samples, culled, measure=Measure(keep_atlas=True))
    finally:
        backend.release()
    assert np.array_equal(again.visibility, expected.visibility)
    assert np.array_equal(again.atlas, expected.atlas)
    tile = again.atlas[:, :256] if again.layout.columns == 1 else again.atlas[:256, :256]
    outside = np.ones((256, 256), dtype=bool)
    outside[y0:y1, x0:x1] = False
    assert np.all(tile[outside] == 1.0)


def test_a_lookup_outside_the_box_reads_empty(monkeypatch):
    """The shadow test's guard: a lookup outside a layer's readable box counts as lit (an
    empty texel), never as whatever a previous frame left there. A deliberately wrong
    1x1 box puts every lookup outside it."""
    from addon.render import parameterizations
    from addon.render.backends.moderngl.backend import ModernGLBackend

    scene = build_preset("courtyard", (128, 96))
    samples, _, _ = view_samples(scene)
    tris = scene.world_triangles()
    backend = ModernGLBackend()
    try:
        pipe = ShadowPipeline(backend)
        stale = pipe.render(scene.light, tris, samples, ShadowSettings("ipsm", 256))
        assert np.any(stale.visibility[stale.flags == 0] < 0.5)  # the stale map shadows something
        real = parameterizations.scissor_boxes
        monkeypatch.setattr(parameterizations, "scissor_boxes",
                            lambda *a: {slot: (0, 0, 1, 1) for slot in real(*a)})
        result = pipe.render(scene.light, tris, samples, ShadowSettings("dpsm", 256))
    finally:
        backend.release()
    tested = result.flags == 0
    assert tested.sum() > 1000
    assert np.all(result.visibility[tested] == 1.0)
