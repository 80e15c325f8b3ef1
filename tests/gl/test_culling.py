"""Culling (sides, faces, triangles) leaves out only what cannot change a shadow."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import plan as P
from addon.core.presets import build_preset
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


@pytest.fixture(scope="module", params=["room_omni", "room_hemi", "courtyard"])
def preset_case(request):
    scene = build_preset(request.param, (128, 96))
    return scene, *view_samples(scene)


@pytest.mark.parametrize("param", ["dpsm", "cube", "ipsm"])
def test_culling_changes_no_shadow(gl_backend, preset_case, param):
    """Same resolution with and without culling: every evaluated pixel gets the same
    visibility (ipsm changes the parameterization, so it is only checked to cull)."""
    scene, samples, _, evaluable = preset_case
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
    planes = P.occluder_region(scene.light, scene.camera, samples.positions, samples.hit)
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
    strict = P.truncated_frustum(scene.camera, samples.positions, samples.hit)
    robust = P.truncated_frustum(scene.camera, samples.positions, samples.hit, percentile=5.0)
    cam = scene.camera.matrix_world[:3, 3]
    assert np.linalg.norm(robust[4:] - cam, axis=1).max() < np.linalg.norm(strict[4:] - cam, axis=1).max()
