"""IPSM (thesis 4.1): one cut paraboloid when the light is outside the view, else both sides."""
from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core import plan as P
from addon.core.metrics import error_figure
from addon.core.presets import build_preset
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from addon.render.frame import Measure
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


def test_cone_covers_every_corner():
    """The cone axis and half-angle enclose all eight corners, and no smaller angle would."""
    rng = np.random.default_rng(2)
    light = np.array([0.0, 0.0, 10.0])
    corners = rng.uniform(-3, 3, (8, 3))
    axis, theta = P.ipsm_cone(light, corners)
    d = corners - light
    angles = np.arccos(np.clip((d / np.linalg.norm(d, axis=1, keepdims=True)) @ axis, -1, 1))
    assert abs(np.linalg.norm(axis) - 1) < 1e-12
    assert angles.max() == pytest.approx(theta)
    assert theta < math.pi / 2


def test_point_in_frustum():
    scene = build_preset("courtyard", (64, 48))
    corners = P.frustum_corners(scene.camera, 1.0, 20.0)
    inside = corners.mean(axis=0)
    assert P.point_in_frustum(inside, corners)
    assert not P.point_in_frustum(scene.light.position, corners)  # courtyard: light behind the camera
    assert not P.point_in_frustum(scene.camera.matrix_world[:3, 3], corners)  # apex side, before the near plane


@pytest.fixture(scope="module")
def courtyard():
    scene = build_preset("courtyard", (160, 120))
    return scene, *view_samples(scene)


def test_ipsm_uses_one_pass_and_beats_dpsm_outside_the_view(gl_backend, courtyard):
    scene, samples, lit, evaluable = courtyard
    pipe = ShadowPipeline(gl_backend)
    ipsm = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("ipsm", 512), measure=Measure(keep_atlas=True))
    dpsm = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("dpsm", 512))
    assert ipsm.plan.parameterization == "ipsm" and ipsm.passes == 1
    assert 0 < ipsm.plan.ipsm_half_angle < P.IPSM_MAX_HALF_ANGLE
    assert np.all(np.isfinite(ipsm.atlas))
    e_ipsm = error_figure(ipsm.visibility > 0.5, lit, evaluable).error_pct
    e_dpsm = error_figure(dpsm.visibility > 0.5, lit, evaluable).error_pct
    assert e_ipsm < e_dpsm  # the cut paraboloid spends its texels on the cone only
    warped = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("ipsm", 512, warp="notw"))
    assert warped.passes == 1 and error_figure(warped.visibility > 0.5, lit, evaluable).error_pct < 1.0


def test_ipsm_falls_back_to_both_sides_when_the_light_is_in_view(gl_backend):
    scene = build_preset("room_omni", (96, 72))
    samples, lit, evaluable = view_samples(scene)
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples, ShadowSettings("ipsm", 512))
    assert result.plan.parameterization == "dpsm" and result.plan.requested == "ipsm" and result.passes == 2
    assert error_figure(result.visibility > 0.5, lit, evaluable).error_pct < 1.0


def test_no_cull_turns_ipsm_into_dpsm(gl_backend, courtyard):
    scene, samples, _, _ = courtyard
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples,
                                               ShadowSettings("ipsm", 256, cull=False))
    assert result.plan.parameterization == "dpsm" and result.passes == 2


def test_skewed_cut_keeps_every_sample_in_the_map(gl_backend, courtyard):
    """The cut's crop holds every view sample, turns towards the camera, and the
    result stays as good as the symmetric IPSM (it usually is better)."""
    from addon.core import frames, projection

    scene, samples, lit, evaluable = courtyard
    pipe = ShadowPipeline(gl_backend)
    cut = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("ipsm", 512, cut=True))
    plain = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("ipsm", 512))
    assert cut.passes == 1
    layer = cut.plan.drawn[0]
    dirs = samples.positions[samples.hit] - scene.light.position
    uv = cut.mappings[0].forward(projection.paraboloid_project(layer.to_local(dirs)))
    assert np.all((uv > 0.0) & (uv < 1.0))
    cam = scene.camera.matrix_world[:3, 3] - scene.light.position
    cam /= np.linalg.norm(cam)
    # The skewed axis leans towards the camera compared with the symmetric cone axis.
    assert layer.rotation[2] @ cam > plain.plan.drawn[0].rotation[2] @ cam
    e_cut = error_figure(cut.visibility > 0.5, lit, evaluable).error_pct
    e_plain = error_figure(plain.visibility > 0.5, lit, evaluable).error_pct
    assert e_cut <= 1.1 * e_plain + 0.05
    assert frames.pick_slot("ipsm", np.ones((3, 3))).tolist() == [0, 0, 0]
