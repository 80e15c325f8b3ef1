"""The soft filter of a sized light (lib/soft.glsl, issue 27) against the numpy
integration over the light (tests/support/soft_oracle.py): a box on a floor under a
sphere light and under an area light, on the paraboloids and the cube, plain and warped;
under a sized spot and a sun's disk, on their own maps (sm, psm). A hard light keeps the
hard test."""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest

from addon.core.errors import InputError
from addon.core.light_shape import POINT
from addon.core.scene import SceneBuilder, look_at
from addon.render.frame import settings_for
from addon.render.pipeline import ShadowPipeline
from tests.support.oracle import view_samples
from tests.support.soft_oracle import reached as light_reached
from tests.support.soft_oracle import soft_visibility

pytestmark = pytest.mark.gl

SIZE = (96, 72)
METHODS = ("dpsm", "dpsm+notw", "cube", "cube+notw")


def _scene(light: str):
    b = SceneBuilder(f"soft_{light}", SIZE)
    b.plane("floor", (0.0, 0.0, 0.0), 8.0, 8.0)
    b.box("box", (0.0, 0.0, 0.6), (1.2, 1.2, 1.2))
    b.box("post", (1.6, -0.8, 0.9), (0.25, 0.25, 1.8))  # a contact shadow, like a chair leg
    if light == "sphere":
        # The light looks along +X: the paraboloids' seam is the vertical plane x = 0.3
        # through it, which cuts the box's penumbra on the floor.
        b.point_light((0.3, 0.2, 3.0), radius=0.45)
        b._light = dataclasses.replace(b._light, matrix_world=look_at((0.3, 0.2, 3.0), (1.3, 0.2, 3.0)))
    elif light == "spot":
        b.spot_light((0.3, 0.2, 3.0), (0.3, 0.1, 0.0), 120.0, radius=0.45)
    elif light == "spot_blend":
        # A narrower, blended cone whose edge crosses the floor in view: each of the sphere's
        # points lights the receiver by its own cone's weight (Cycles' spot attenuation).
        b.spot_light((0.3, 0.2, 3.0), (0.5, 0.3, 0.0), 70.0, radius=0.45)
        b._light = dataclasses.replace(b._light, spot_blend=0.3)
    elif light == "sun":
        b.sun_light((0.4, 0.3, -1.0), angle_deg=30.0)
    else:
        b.area_light((0.3, 0.2, 3.2), (0.2, 0.0, 0.0), 1.4, 0.9)
        if light == "area_spread":  # a soft box's grid: light leaves within 50 degrees of its normal
            # (a spread of 100 degrees)
            b._light = dataclasses.replace(b._light, shape=dataclasses.replace(b._light.shape,
                                                                               spread=math.radians(100.0)))
    b.camera((0.5, -6.0, 5.0), (0.3, 0.2, 0.3), fov_deg=55.0)
    return b.finish()


@functools.cache
def _case(name: str):
    scene = _scene(name)
    samples, _, evaluable = view_samples(scene)
    points = samples.positions[evaluable]
    normals = samples.normals[evaluable]
    truth = soft_visibility(scene.light, points, normals, scene.world_triangles(), n=256)
    return name, scene, samples, evaluable, truth


@pytest.fixture(params=["sphere", "area"])
def case(request):
    return _case(request.param)


def _visibility(backend, scene, samples, method, light=None, **fields):
    result = ShadowPipeline(backend).render(light or scene.light, scene.world_triangles(), samples,
                                            settings_for(method, 512, **fields))
    return result.visibility


@pytest.mark.slow
@pytest.mark.parametrize("method", (*METHODS, "ipsm+notw", "unfold"))
def test_the_filter_follows_the_light(gl_backend, case, method):
    """The filtered maps' penumbra is within a few percent of the integral, and at most half
    the error of the hard test of the same map."""
    name, scene, samples, evaluable, truth = case
    penumbra = (truth > 0.05) & (truth < 0.95)
    assert penumbra.sum() > 200, name  # the scene has a wide penumbra to measure
    soft = _visibility(gl_backend, scene, samples, method)[evaluable]
    hard = _visibility(gl_backend, scene, samples, method, dataclasses.replace(scene.light, shape=POINT))[evaluable]
    soft_err = float(np.abs(soft - truth).mean())
    hard_err = float(np.abs(hard - truth).mean())
    assert soft_err < 0.5 * hard_err, (name, method, soft_err, hard_err)
    assert soft_err < 0.03, (name, method, soft_err)
    assert float(np.abs(soft - truth)[penumbra].mean()) < 0.2, (name, method)


@pytest.mark.slow
def test_an_area_lights_spread_weighs_the_taps(gl_backend):
    """A spread of 100 degrees narrows what reaches each receiver (the oracle weighs Cycles'
    soft-box grid): the filter follows the narrowed light, nearer the integral with the
    spread than the same taps without it."""
    name, scene, samples, evaluable, truth = _case("area_spread")
    _, _, _, _, wide = _case("area")
    # The receivers the narrowed light still reaches (Cycles leaves the others unevaluated).
    reached = light_reached(scene.light, samples.positions[evaluable], samples.normals[evaluable])
    assert 1000 < reached.sum() < len(reached)
    truth, wide = truth[reached], wide[reached]
    assert float(np.abs(truth - wide).mean()) > 0.01  # the spread changes the answer
    soft = _visibility(gl_backend, scene, samples, "dpsm+notw")[evaluable][reached]
    unspread = _visibility(gl_backend, _scene("area"), samples, "dpsm+notw")[evaluable][reached]
    assert float(np.abs(soft - truth).mean()) < 0.85 * float(np.abs(unspread - truth).mean())
    assert float(np.abs(soft - truth).mean()) < 0.03


@pytest.mark.slow
@pytest.mark.parametrize("name", ["spot", "sun"])
@pytest.mark.parametrize("method", ["sm", "psm"])
def test_a_spot_or_sun_map_follows_the_light(gl_backend, name, method):
    """A sized spot's sphere and a sun's disk through their own maps: as the point lights'
    filter does, at most half the hard test's error, and the penumbra a few percent off."""
    name, scene, samples, evaluable, truth = _case(name)
    penumbra = (truth > 0.05) & (truth < 0.95)
    assert penumbra.sum() > 100, name
    soft = _visibility(gl_backend, scene, samples, method)[evaluable]
    hard = _visibility(gl_backend, scene, samples, method, dataclasses.replace(scene.light, shape=POINT))[evaluable]
    soft_err = float(np.abs(soft - truth).mean())
    hard_err = float(np.abs(hard - truth).mean())
    assert soft_err < 0.5 * hard_err, (name, method, soft_err, hard_err)
    assert float(np.abs(soft - truth)[penumbra].mean()) < 0.12, (name, method)
    assert ((soft > 0.0) & (soft < 1.0)).sum() > 0.5 * penumbra.sum(), (name, method)


def test_the_penumbra_does_not_change_with_the_map(gl_backend, case):
    """The kernel is the light in world space: dual paraboloid (with its seam), cube and
    their warps give one penumbra, up to the maps' own resolution."""
    name, scene, samples, evaluable, truth = case
    fields = {m: _visibility(gl_backend, scene, samples, m)[evaluable] for m in METHODS}
    for method in METHODS[1:]:
        assert float(np.abs(fields[method] - fields["dpsm"]).mean()) < 0.015, (name, method)


def test_the_seam_keeps_the_penumbra(gl_backend):
    """Pixels whose direction from the light lies within 15 degrees of the paraboloids' seam
    err no more than the rest of the image (twice, plus a little, for their fewer pixels).
    The sphere light's scene: an omnidirectional light's map has the seam."""
    name, scene, samples, evaluable, truth = _case("sphere")
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples,
                                               settings_for("dpsm+notw", 512))
    axis = result.plan.drawn[0].rotation[2]  # the paraboloids' axis: the seam is across it
    rel = samples.positions[evaluable] - scene.light.position
    rel /= np.linalg.norm(rel, axis=1, keepdims=True)
    near_seam = np.abs(rel @ axis) < np.sin(np.radians(15.0))
    assert near_seam.sum() > 100 and ((truth > 0.05) & (truth < 0.95) & near_seam).sum() > 20
    err = np.abs(result.visibility[evaluable] - truth)
    assert err[near_seam].mean() <= 2.0 * err[~near_seam].mean() + 0.01


def test_more_light_samples_do_not_move_the_answer_much(gl_backend, case):
    """16 and 64 light points agree on average (the pattern is stratified), 64 no further
    from the integral than 16, and a hard light is the plain test whatever the samples."""
    name, scene, samples, evaluable, truth = case
    few = _visibility(gl_backend, scene, samples, "dpsm+notw", light_samples=16)[evaluable]
    many = _visibility(gl_backend, scene, samples, "dpsm+notw", light_samples=64)[evaluable]
    assert float(np.abs(few - many).mean()) < 0.03
    assert float(np.abs(many - truth).mean()) <= float(np.abs(few - truth).mean()) + 0.002
    hard = dataclasses.replace(scene.light, shape=POINT)
    a = _visibility(gl_backend, scene, samples, "dpsm+notw", hard, light_samples=16)
    b = _visibility(gl_backend, scene, samples, "dpsm+notw", hard, light_samples=64)
    assert np.array_equal(a, b) and set(np.unique(a)) <= {0.0, 1.0}


@pytest.mark.parametrize("fields", [{"light_samples": 0}, {"light_samples": 65}, {"search_samples": 17},
                                    {"light_samples": 2.5}])
def test_bad_sample_counts_are_named(fields):
    with pytest.raises(InputError, match="samples"):
        settings_for("dpsm", 512, **fields)
