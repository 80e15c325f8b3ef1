"""The exact pass over a spot's or sun's own map (issue 27): the samples are linked into
the lists of the sm map's texels through its matrix, every triangle walks the lists of the
texels its image's box covers, and a sample is shadowed when the triangle crosses its
segment to the spot, or its ray towards the sun. That is the ray caster's answer,
whatever the map's resolution."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from addon.core.presets import build_preset
from addon.core.scene import CameraSpec, LightSpec, SceneSpec, look_at
from addon.render.pipeline import ShadowPipeline, ShadowSettings, projective_counts
from addon.render.resident import ResidentScene
from addon.render.frame import Measure
from tests.gl.test_exact_pass import random_blockers
from tests.gl.test_izb_lists import _walk
from tests.support.oracle import transmittance, view_samples

pytestmark = pytest.mark.gl

# Receivers lit within this cosine of edge-on are left out: there the ray to the light runs
# along the surface, and whether it grazes a neighbour's edge turns on float32's rounding
# of the sample (sun_field's first hay bale is turned to the sun's azimuth: its faces are
# edge-on to the sun, cos 1e-8, and the ray caster's answer there is a coin toss).
GRAZING_COS = 1e-3


def _judged(scene: SceneSpec, samples, evaluable: np.ndarray) -> np.ndarray:
    """The evaluable samples not lit edge-on (GRAZING_COS)."""
    light = scene.light
    to_light = (np.broadcast_to(-light.axis, samples.positions.shape) if light.emission == "sun"
                else light.position - samples.positions)
    to_light = to_light / np.maximum(np.linalg.norm(to_light, axis=-1, keepdims=True), 1e-300)
    return evaluable & (np.abs(np.einsum("...i,...i->...", samples.normals, to_light)) > GRAZING_COS)


def _wrong(result, lit: np.ndarray, judged: np.ndarray) -> int:
    return int((((result.visibility > 0.5) != (lit > 0.5)) & judged).sum())


PRESET_CASES, PRESET_CASE_SIZE = ["spot_street", "sun_field"], (64, 48)  # conftest.preset_case


def test_exact_pass_equals_the_ray_caster(gl_backend, preset_case):
    """At 128^2 the plain map errs at every shadow edge; the lists do not."""
    name, scene, samples, lit, evaluable = preset_case
    judged = _judged(scene, samples, evaluable)
    pipe = ShadowPipeline(gl_backend)
    exact = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("sm", 128, exact=True))
    plain = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("sm", 128))
    assert judged.sum() > 1000 and (lit[judged] < 0.5).sum() > 50
    assert _wrong(exact, lit, judged) <= max(1, int(1e-3 * judged.sum())), (name, _wrong(exact, lit, judged))
    assert _wrong(plain, lit, judged) > 10 * max(_wrong(exact, lit, judged), 1), name
    assert exact.exact_work["cut"] == 0 and exact.plan.parameterization == "sm"


def test_the_map_resolution_does_not_matter(gl_backend, preset_case):
    name, scene, samples, _, evaluable = preset_case
    judged = _judged(scene, samples, evaluable)
    pipe = ShadowPipeline(gl_backend)
    shadowed = [(pipe.render(scene.light, scene.world_triangles(), samples,
                             ShadowSettings("sm", res, exact=True)).visibility < 0.5)[judged] for res in (64, 512)]
    assert np.array_equal(shadowed[0], shadowed[1]) and shadowed[0].any(), name


def test_lists_hold_every_sample_in_the_map_once(gl_backend, preset_case):
    """The lists are the count map of the map's matrix texel for texel (the GPU's scatter,
    the same arithmetic); every hit sample inside the map is in exactly one list, and the
    numpy projection (float64) puts all but a few on a texel border in the same texels."""
    name, scene, samples, _, _ = preset_case
    pipe = ShadowPipeline(gl_backend)
    res = 128
    result = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("sm", res))
    pipe.link_lists(scene.light, result.plan, result.mappings, res)
    heads, links = gl_backend.read_links()
    lengths, met = _walk(heads, links)
    counts = pipe.count_maps(scene.light, result.plan, {}, res, 2)[0]
    np.testing.assert_array_equal(lengths, counts)
    assert len(met) == len(set(met)) == int(counts.sum()) > 0.5 * samples.hit.sum()
    rows, cols = np.divmod(np.asarray(met), samples.hit.shape[1])
    assert samples.hit[::-1][rows, cols].all()  # the sample texture's rows run bottom-up
    expected = projective_counts(result.plan.projective, scene.light, samples, res)
    assert expected.sum() == counts.sum(), name
    assert np.abs(expected - counts).sum() <= max(4, int(1e-3 * counts.sum())), name


def random_scene(seed: int) -> SceneSpec:
    """A floor, a back wall and random blockers of several sizes under a spot aimed at the
    floor (even seeds) or a sun from a random direction above, seen by a camera from outside."""
    rng = np.random.default_rng(seed)
    meshes = random_blockers(rng)
    if seed % 2 == 0:
        position = rng.uniform([-3.0, -3.0, 6.0], [3.0, 3.0, 9.0])
        light = LightSpec("spot", look_at(position, rng.uniform([-1.0, -1.0, 0.0], [1.0, 1.0, 0.0])),
                          spot_size=np.radians(rng.uniform(60.0, 120.0)))
    else:
        # The lamp's location, only an origin, anywhere near the scene.
        origin = rng.uniform([-5.0, -5.0, 5.0], [5.0, 5.0, 15.0])
        toward = np.append(rng.uniform(-0.8, 0.8, 2), 1.0)
        light = LightSpec("sun", look_at(origin, origin - toward))
    eye, target = rng.uniform([-9.0, -12.0, 3.0], [9.0, -7.0, 9.0]), rng.uniform([-2.0, -1.0, 0.0], [2.0, 3.0, 2.0])
    return SceneSpec(f"random{seed}", meshes, light, CameraSpec(look_at(eye, target), 60.0, (48, 36)))


@pytest.mark.parametrize("seed", range(4))
def test_exact_pass_equals_the_ray_caster_on_random_scenes(gl_backend, seed):
    scene = random_scene(seed)
    samples, lit, evaluable = view_samples(scene)
    judged = _judged(scene, samples, evaluable)
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples,
                                               ShadowSettings("sm", 128, exact=True))
    assert _wrong(result, lit, judged) <= max(1, int(1e-3 * judged.sum())), (seed, _wrong(result, lit, judged))
    assert (lit[judged] < 0.5).any() and (lit[judged] > 0.5).any()  # shadow and light to get right


def test_rounds_walk_every_entry_once(gl_backend, monkeypatch):
    """With a first bound of one entry every list longer than one takes later rounds over
    the map (the scissored redraws of tile 0); the marks and the entries walked are those of
    one round."""

    scene = build_preset("spot_street", (64, 48))
    samples, _, _ = view_samples(scene)
    pipe = ShadowPipeline(gl_backend)
    settings = ShadowSettings("sm", 64, exact=True)  # coarse: lists of several samples
    once = pipe.render(scene.light, scene.world_triangles(), samples, settings, measure=Measure(count_work=True))
    from addon.render.passes import exact as exact_pass
    monkeypatch.setattr(exact_pass, "EXACT_MAX_WALK", 1)  # the first round's bound (passes/exact.py)
    rounds = pipe.render(scene.light, scene.world_triangles(), samples, settings, measure=Measure(count_work=True))
    assert once.exact_work["rounds"] == 0 and rounds.exact_work["rounds"] >= 2, rounds.exact_work
    assert np.array_equal(rounds.visibility, once.visibility)
    assert rounds.exact_work["entries"] == once.exact_work["entries"] > rounds.exact_work["moved"] > 0


def test_a_spot_through_see_through_surfaces(gl_backend):
    """A 160 degree spot over cut-out and half-transparent cards: the exact pass over its
    map gives the product of the transmittances (the barycentrics from the edge sides), as
    the point light's pass does."""
    from tests.gl.test_alpha_pass import _scene

    scene = _scene(spot=True)
    assert scene.light.emission == "spot"
    samples, _, evaluable = view_samples(scene)
    expected = transmittance(scene.light.position, samples.positions.reshape(-1, 3), scene.world_triangles(),
                             scene.surface()).reshape(evaluable.shape)
    resident = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    result = ShadowPipeline(gl_backend).render(scene.light, resident, samples, ShadowSettings("sm", 256, exact=True))
    gl_backend.release_scene(resident)
    got, want = result.visibility[evaluable], expected[evaluable]
    assert (np.abs(want - 0.5) < 1e-6).sum() > 50 and (want == 0.0).sum() > 50
    wrong = np.abs(got - want) > 1e-3
    assert wrong.sum() <= max(2, int(2e-3 * evaluable.sum())), int(wrong.sum())


def _edge_on_box():
    """A box turned to the sun's azimuth, as sun_field's first hay bale: its front face is
    parallel to the sunlight but for 1.5e-6 rad towards it (Cycles' normal there gives 2.6e-6),
    70 m from the lamp's origin."""
    from addon.core.scene import SceneBuilder

    b = SceneBuilder("edge_on", (64, 48))
    b.plane("ground", (7.0, -70.0, 0.0), 20.0, 20.0)
    b.box("bale", (7.0, -70.0, 0.6), (1.2, 2.0, 1.2), rotate_z_deg=10.0 - 1e-4)
    el, az = np.radians(30.0), np.radians(10.0)
    b.sun_light((np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)), origin=(0.0, 0.0, 30.0))
    b.camera((7.5, -75.0, 0.8), (7.0, -70.0, 0.6), fov_deg=30.0)
    return b.finish()


def test_a_face_parallel_to_the_sun_is_not_shadowed_by_its_own_box(gl_backend, monkeypatch):
    """Its samples lie on their own face's plane, and on the edge planes of the faces beside
    it, to float32's rounding: unlifted, a share of them fell inside their own box. Lifted
    by EXACT_LIFT (three roundings) none do, as none does for Cycles (98.6 % lit there on
    sun_field; the rest is its own rounding)."""
    from addon.render import parameterizations

    scene = _edge_on_box()
    samples, _, _ = view_samples(scene)
    face = samples.hit & (np.abs(samples.normals @ np.array([np.sin(np.radians(10.0)), -np.cos(np.radians(10.0)),
                                                              0.0]) - 1.0) < 1e-6)
    assert 0.0 < float(samples.normals[face][0] @ -scene.light.axis) < 1e-5  # lit, edge-on
    assert face.sum() > 300
    pipe = ShadowPipeline(gl_backend)
    settings = ShadowSettings("sm", 256, exact=True)
    lifted = pipe.render(scene.light, scene.world_triangles(), samples, settings).visibility[face]
    monkeypatch.setattr(parameterizations, "EXACT_LIFT", 0.0)
    unlifted = pipe.render(scene.light, scene.world_triangles(), samples, settings).visibility[face]
    assert (lifted > 0.5).all(), int((lifted < 0.5).sum())
    assert (unlifted < 0.5).sum() > 0.05 * face.sum(), int((unlifted < 0.5).sum())


def test_sized_spots_and_suns_take_the_soft_paths_and_their_rows_no_note():
    """Every light type with a size is softened: a spot's sphere and a sun's disk take the
    exact pass's light points over their sm map, and the filter on sm and psm; no row of
    theirs carries the note of hard shadows. A hard spot keeps the hard pass."""
    from addon.compare import _row_note
    from addon.core.light_shape import POINT, Sphere, SunDisk
    from addon.render import soft
    from addon.render.frame import EXACT_SAMPLES
    from addon.render.pipeline import settings_for
    from addon.render.shaders import EXACT_SOFT_KEY

    scene = ResidentScene.of_triangles(np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]))
    spot = LightSpec("spot", look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0)), spot_size=1.0, shape=Sphere(0.3))
    sun = LightSpec("sun", look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0)), shape=SunDisk(0.1))
    for light in (spot, sun):
        exact = settings_for("exact", 256, light.emission)
        assert soft.sized_mode(light, exact) is soft.SizedMode.EXACT_SOFT
        assert soft.soft_uniforms(light, exact)[EXACT_SOFT_KEY] == EXACT_SAMPLES
        assert soft.list_resolution(light, exact) == 64 and soft.hit_words(light, exact) == EXACT_SAMPLES // 32
        for method in ("sm", "psm"):
            filtered = settings_for(method, 256, light.emission)
            assert soft.sized_mode(light, filtered) is soft.SizedMode.FILTERED
            assert soft.soft_uniforms(light, filtered)["ow_soft_count"] > 0
            assert _row_note(light, filtered, scene) is None
        assert _row_note(light, exact, scene) is None
    hard = dataclasses.replace(spot, shape=POINT)
    assert soft.exact_soft_uniforms(hard, settings_for("exact", 256, "spot")) == {EXACT_SOFT_KEY: 0}
