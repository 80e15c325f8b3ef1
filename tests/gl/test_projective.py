"""Spot and sun maps (sm, psm) through the whole pipeline against an exact ray caster."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.errors import InputError
from addon.core.metrics import error_figure
from addon.core.scene import LightSpec, SceneBuilder
from addon.render.pipeline import ShadowPipeline, ShadowSettings, count_statistics
from addon.render.frame import Measure
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl

SIZE = (96, 72)


def _street(light: str, camera_behind_light: bool = False):
    """A ground strip with posts near and far; a spot or a sun."""
    b = SceneBuilder(f"mini_{light}", SIZE)
    b.plane("ground", (0.0, 20.0, 0.0), 20.0, 50.0, subdivisions=4)
    for i, y in enumerate((1.0, 4.0, 10.0, 22.0, 38.0)):
        b.box(f"post_{i}", (-1.5 + 0.7 * i, y, 0.6), (0.4, 0.4, 1.2))
    b.box("wall", (4.0, 12.0, 1.0), (0.3, 10.0, 2.0))
    if light == "spot":
        position = (7.0, -8.0, 5.0) if camera_behind_light else (6.0, 30.0, 12.0)
        b.spot_light(position, (0.0, 15.0, 0.0), spot_size_deg=90.0)
    else:
        b.sun_light((-0.6, 0.3, -0.75))
    b.camera((0.0, -4.0, 1.8), (0.0, 30.0, 0.0), fov_deg=60.0)
    return b.finish()


@pytest.mark.parametrize("method", ["sm", "psm"])
@pytest.mark.parametrize("light,behind", [("spot", False), ("spot", True), ("sun", False)])
def test_projective_maps_match_ray_caster(gl_backend, method, light, behind):
    """Finite maps, every evaluable sample inside the map, visibility within 2.5 % of exact."""
    scene = _street(light, behind)
    samples, lit, evaluable = view_samples(scene)
    assert evaluable.sum() > 500 and 0.02 < 1.0 - lit[evaluable].mean() < 0.9
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples,
                                               ShadowSettings(method, 1024), measure=Measure(keep_atlas=True))
    assert result.passes == 1 and np.all(np.isfinite(result.atlas))
    assert not np.any(result.flags[evaluable] == 3), "an evaluable sample fell outside the map"
    figure = error_figure(result.visibility > 0.5, lit, evaluable)
    assert figure.error_pct < 2.5, figure
    counts = count_statistics(ShadowPipeline(gl_backend), scene.light, ShadowSettings(method, 1024), result, samples)
    assert counts.max_count_before > 0


def test_psm_spends_more_texels_near_the_camera(gl_backend):
    """PSM's point: samples near the camera get more texels than in a uniform map, so
    the peak count (samples per texel) drops."""
    scene = _street("sun")
    samples, _, _ = view_samples(scene)
    peaks = {}
    for method in ("sm", "psm"):
        settings = ShadowSettings(method, 256)
        pipe = ShadowPipeline(gl_backend)
        result = pipe.render(scene.light, scene.world_triangles(), samples, settings)
        peaks[method] = count_statistics(pipe, scene.light, settings, result, samples).max_count_before
    assert peaks["psm"] < peaks["sm"]


def test_spot_cone_outside_is_unlit_and_flagged(gl_backend):
    scene = _street("spot")
    samples, _, _ = view_samples(scene)
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples,
                                               ShadowSettings("sm", 256))
    pos = samples.positions[samples.hit] - scene.light.position
    cosines = (pos / np.linalg.norm(pos, axis=1, keepdims=True)) @ scene.light.axis
    outside = cosines < np.cos(scene.light.spot_size / 2.0) - 1e-4
    assert outside.any()
    assert np.all(result.flags[samples.hit][outside] == 2)
    assert np.all(result.visibility[samples.hit][outside] == 0.0)


@pytest.mark.parametrize("method,emission", [("sm", "omni"), ("psm", "hemi"), ("dpsm", "spot"), ("unfold", "sun")])
def test_methods_refuse_lights_they_do_not_fit(gl_backend, method, emission):
    scene = _street("spot")
    samples, _, _ = view_samples(scene)
    light = LightSpec(emission, scene.light.matrix_world, spot_size=np.radians(60.0))
    with pytest.raises(InputError, match="needs a"):
        ShadowPipeline(gl_backend).render(light, scene.world_triangles(), samples, ShadowSettings(method, 64))
