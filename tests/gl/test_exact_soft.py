"""The exact pass of a sized light (lib/exact_soft.glsl, issue 27) against the numpy
integration over the same light points (tests/support/soft_oracle.py): the scenes of the
soft filter's test (a box and a post on a floor, a sphere light whose paraboloid seam cuts
the penumbra, and an area light), on the warped dual paraboloid (`exact`), the plain one,
and the cube; a sized spot and a sun's disk over their own map; an area light of narrow
spread. With the same N points the two agree to float32 rounding, for any N; with more
points both converge."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from addon.core.alpha import AlphaMap
from addon.core.errors import InputError
from addon.core.light_shape import POINT
from addon.core.scene import SceneBuilder
from addon.render.frame import ShadowSettings, settings_for
from addon.render.pipeline import ShadowPipeline
from addon.render.resident import ResidentScene
from addon.render.frame import Measure
from tests.gl.test_alpha_pass import _card
from tests.gl.test_soft_filter import _case
from tests.support.oracle import view_samples
from tests.support.soft_oracle import reached, soft_visibility

pytestmark = pytest.mark.gl


def _exact(backend, scene, samples, n: int, parameterization: str = "dpsm", warp: str = "notw", light=None,
           resolution: int = 256, segments: bool = True, **kwargs):
    """The exact frame; `segments` False keeps the lists' walk where segments would go."""
    settings = ShadowSettings(parameterization, resolution, warp=warp, exact=True, exact_samples=n,
                              exact_segments=segments)
    return ShadowPipeline(backend).render(light or scene.light, scene.world_triangles(), samples, settings,
                                          **kwargs)


def _reached_image(scene, samples, evaluable: np.ndarray) -> np.ndarray:
    """(H, W) bool: the evaluable pixels the light reaches with nothing in the way."""
    out = np.zeros_like(evaluable)
    out[evaluable] = reached(scene.light, samples.positions[evaluable], samples.normals[evaluable], n=64)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("walk", ["lists", "segments"])
@pytest.mark.parametrize("name", ["sphere", "area", "area_spread"])
@pytest.mark.parametrize("param,warp", [("dpsm", "notw"), ("dpsm", "none"), ("cube", "none"), ("cube", "notw")])
def test_exact_soft_equals_the_integral_over_its_points(gl_backend, name, param, warp, walk):
    """Every pixel's share of the light equals the oracle's over the same 64 points: the grown
    footprints leave no segment untested, on either side of the seam and through the warp;
    so do the segments through the tree (passes/segments.py)."""
    _, scene, samples, evaluable, _ = _case(name)
    # An area light's spread leaves some receivers dark: Cycles evaluates only the reached.
    evaluable = evaluable & _reached_image(scene, samples, evaluable)
    ours = _exact(gl_backend, scene, samples, 64, param, warp, segments=walk == "segments").visibility[evaluable]
    truth = soft_visibility(scene.light, samples.positions[evaluable], samples.normals[evaluable],
                            scene.world_triangles(), n=64)
    penumbra = (truth > 0.02) & (truth < 0.98)
    assert penumbra.sum() > 300, name  # a wide penumbra is measured
    diff = np.abs(ours - truth)
    # float32 against float64: a segment within rounding of an edge may fall either way.
    assert float(diff.mean()) < 1e-4, (name, param, warp, float(diff.mean()))
    assert float((diff > 1.5 / 64).mean()) < 1e-3, (name, param, warp)


@pytest.mark.slow
@pytest.mark.parametrize("walk", ["lists", "segments"])
@pytest.mark.parametrize("name", ["spot", "spot_blend", "sun"])
def test_exact_soft_over_a_spot_or_sun_map(gl_backend, name, walk):
    """A sized spot's sphere and a sun's disk, over their own sm map: every pixel's share
    equals the oracle's over the same 64 points, whatever the map's resolution (the grown
    footprints cover every segment: a spot's through the map's perspective, a sun's by the
    depth its rays travel)."""
    _, scene, samples, evaluable, _ = _case(name)
    evaluable = evaluable & _reached_image(scene, samples, evaluable)  # a blended cone's edge
    truth = soft_visibility(scene.light, samples.positions[evaluable], samples.normals[evaluable],
                            scene.world_triangles(), n=64)
    assert ((truth > 0.02) & (truth < 0.98)).sum() > 100, name
    for resolution in (64, 512):
        ours = _exact(gl_backend, scene, samples, 64, "sm", "none", resolution=resolution,
                      segments=walk == "segments")
        diff = np.abs(ours.visibility[evaluable] - truth)
        assert float(diff.mean()) < 1e-4, (name, resolution, float(diff.mean()))
        assert float((diff > 1.5 / 64).mean()) < 1e-3, (name, resolution)
        assert ours.plan.parameterization == "sm"


@pytest.mark.slow
def test_exact_soft_converges_with_its_points(gl_backend):
    """The same equality at 16 points, and 256 points come nearer to a 1024-point integral
    than 16 do (the bits of all 256 points, in 8 words, are read)."""
    _, scene, samples, evaluable, _ = _case("sphere")
    points, normals = samples.positions[evaluable], samples.normals[evaluable]
    tris = scene.world_triangles()
    few = _exact(gl_backend, scene, samples, 16).visibility[evaluable]
    assert float(np.abs(few - soft_visibility(scene.light, points, normals, tris, n=16)).mean()) < 1e-4
    many = _exact(gl_backend, scene, samples, 256).visibility[evaluable]
    fine = soft_visibility(scene.light, points, normals, tris, n=1024)
    assert float(np.abs(many - fine).mean()) < 0.5 * float(np.abs(few - fine).mean())


@pytest.mark.parametrize("name,param", [("sphere", "dpsm"), ("area", "cube"), ("spot_blend", "sm"), ("sun", "sm")])
def test_clusters_decide_as_their_points_would(gl_backend, monkeypatch, name, param):
    """The walk decides a cluster of points whole where its box lies beside an edge plane or
    inside all three (ow_exact_cluster). With boxes too large to decide anything, every point
    is tested on its own; the shares must not change. Each cluster's box holds its points,
    and the clusters are tiles of the points' grid, so a tile's box is small."""
    from addon.render import soft
    from addon.render.shaders import EXACT_SOFT_CLUSTER

    _, scene, samples, evaluable, _ = _case(name)
    warp = "notw" if param == "dpsm" else "none"
    clustered = _exact(gl_backend, scene, samples, 256, param, warp, segments=False).visibility
    table = soft._exact_pattern(scene.light.shape, 256)
    bounds = soft._exact_bounds(scene.light.shape, 256)
    for c in range(256 // EXACT_SOFT_CLUSTER):
        points = table[c * EXACT_SOFT_CLUSTER:(c + 1) * EXACT_SOFT_CLUSTER, :3]
        assert np.all(points >= bounds[2 * c, :3]) and np.all(points <= bounds[2 * c + 1, :3])
    order = soft.cluster_order(256)
    assert sorted(order.tolist()) == list(range(256))
    tiles = {(int(i) % 16 // 4, int(i) // 16 // 4) for i in order[:EXACT_SOFT_CLUSTER]}
    assert len(tiles) == 1  # the first cluster is one 4 x 4 tile of the 16 x 16 grid
    undecided = np.tile([[-1e6, -1e6, -1e6, 0.0], [1e6, 1e6, 1e6, 0.0]], (256 // EXACT_SOFT_CLUSTER, 1))
    monkeypatch.setattr(soft, "_exact_bounds", lambda shape, count: undecided)
    pointwise = _exact(gl_backend, scene, samples, 256, param, warp, segments=False).visibility
    assert np.array_equal(clustered[evaluable], pointwise[evaluable]), float(
        np.abs(clustered - pointwise)[evaluable].max())


@pytest.mark.parametrize("name,param", [("sphere", "dpsm"), ("spot", "sm")])
def test_the_footprints_grow_for_the_farthest_sample(gl_backend, name, param):
    """The footprints grow for a receiver as far from the light as the farthest view sample
    (soft.sample_far, from the plan's sample polytope): that bound holds every sample, and
    lies below the unbounded growth's infinity."""
    from addon.render.soft import sample_far

    _, scene, samples, evaluable, _ = _case(name)
    result = _exact(gl_backend, scene, samples, 16, param, "notw" if param == "dpsm" else "none", segments=False)
    far = sample_far(result.plan, scene.light)
    farthest = float(np.linalg.norm(samples.positions[evaluable] - scene.light.position, axis=-1).max())
    assert farthest <= far < 10.0 * farthest, (farthest, far)


def test_a_hard_light_keeps_the_hard_pass(gl_backend):
    """Size 0 gives the hard exact pass's binary answer, whatever exact_samples says."""
    _, scene, samples, evaluable, _ = _case("sphere")
    hard_light = dataclasses.replace(scene.light, shape=POINT)
    hard = _exact(gl_backend, scene, samples, 64, light=hard_light).visibility
    plain = ShadowPipeline(gl_backend).render(hard_light, scene.world_triangles(), samples,
                                              settings_for("exact", 256)).visibility
    assert np.array_equal(hard, plain)
    assert set(np.unique(hard[evaluable])) <= {0.0, 1.0}


def test_the_light_points_are_a_square(gl_backend):
    for bad in (0, 32, 300, 64.0):
        with pytest.raises(InputError, match="exact_samples"):
            ShadowSettings("dpsm", 256, exact=True, exact_samples=bad)


def test_rounds_finish_a_sized_lights_lists(gl_backend, monkeypatch):
    """With a first walk bound of one entry the lists take several rounds, and the shares
    are those of one round."""

    _, scene, samples, _, _ = _case("area")
    once = _exact(gl_backend, scene, samples, 16, "dpsm", "none", resolution=64, segments=False,
                  measure=Measure(count_work=True))
    from addon.render.passes import exact as exact_pass
    monkeypatch.setattr(exact_pass, "EXACT_MAX_WALK", 1)  # the first round's bound (passes/exact.py)
    rounds = _exact(gl_backend, scene, samples, 16, "dpsm", "none", resolution=64, segments=False,
                    measure=Measure(count_work=True))
    assert once.exact_work["rounds"] == 0 and rounds.exact_work["rounds"] >= 2, rounds.exact_work
    assert np.array_equal(rounds.visibility, once.visibility)
    # A frame that does not wait leaves the rounds to its first read; the test, which weighs
    # a sized light's marks itself, runs again over the finished marks.
    triangles = scene.world_triangles()
    triangles.flags.writeable = False  # resident, so the frame need not finish before it returns
    pipeline = ShadowPipeline(gl_backend)
    deferred = pipeline.render(scene.light, triangles, samples,
                               ShadowSettings("dpsm", 64, warp="none", exact=True, exact_samples=16,
                                              exact_segments=False))
    assert deferred.pending and deferred.completer is not None
    assert np.array_equal(deferred.visibility, once.visibility)
    assert deferred.exact_work["rounds"] == rounds.exact_work["rounds"]
    pipeline.release()


@pytest.mark.parametrize("name,param", [("sphere", "dpsm"), ("area", "cube"), ("spot_blend", "sm"), ("sun", "sm")])
def test_segments_mark_what_the_lists_mark(gl_backend, monkeypatch, name, param):
    """The segments through the tree give the lists' shares, without a list entry walked;
    a walk cut into many turns (a budget of 64 boxes and triangles a sample) gives the same."""
    from addon.render.passes import segments

    _, scene, samples, evaluable, _ = _case(name)
    warp = "notw" if param == "dpsm" else "none"
    lists = _exact(gl_backend, scene, samples, 64, param, warp, segments=False, measure=Measure(count_work=True))
    walked = _exact(gl_backend, scene, samples, 64, param, warp, measure=Measure(count_work=True))
    assert lists.exact_work["entries"] > 0 and walked.exact_work["entries"] == 0
    assert gl_backend.segments.turns == 1
    diff = np.abs(walked.visibility - lists.visibility)[evaluable]
    assert float(diff.mean()) < 1e-4 and float((diff > 1.5 / 64).mean()) < 1e-3, float(diff.mean())
    monkeypatch.setattr(segments, "RAY_TREE_BUDGET", 64)
    turns = _exact(gl_backend, scene, samples, 64, param, warp).visibility
    assert gl_backend.segments.turns > 4
    assert np.array_equal(turns, walked.visibility)


def test_a_stepped_frame_yields_between_the_segments_turns(gl_backend, monkeypatch):
    """The viewport spreads a frame over redraws (the pacer stepping): the segments' pass
    yields between its turns, and ends with the visibility of the frame drawn whole."""
    from addon.render.passes import segments

    _, scene, samples, _, _ = _case("area")
    monkeypatch.setattr(segments, "RAY_TREE_BUDGET", 64)
    settings = ShadowSettings("dpsm", 256, warp="notw", exact=True, exact_samples=64)
    whole = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples, settings).visibility
    turns = gl_backend.segments.turns
    monkeypatch.setattr(gl_backend.pacer, "stepping", True)
    steps = ShadowPipeline(gl_backend).render_steps(scene.light, scene.world_triangles(), samples, settings)
    yields = 0
    try:
        while True:
            next(steps)
            yields += 1
    except StopIteration as done:
        stepped = done.value.visibility
    assert turns > 10 and yields >= turns - 1  # besides the pauses between stages
    assert np.array_equal(stepped, whole)


def test_scenes_of_more_than_opaque_triangles_keep_the_lists():
    """Hair and points, see-through faces and media are not in the tree: their frames walk
    the lists (passes/segments.fits)."""
    from addon.render.passes import segments

    tris = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    assert segments.fits(ResidentScene.of_triangles(tris))
    b = SceneBuilder("see_through", (16, 12))
    _card(b, "curtain", (0.0, 0.0, 1.0), 3.0, AlphaMap.constant("curtain", 0.4))
    b.point_light((0.0, 0.0, 4.0), radius=0.1)
    b.camera((0.0, -6.0, 0.6), (0.0, 0.0, 0.0), fov_deg=30.0)
    curtain = b.finish()
    assert not segments.fits(ResidentScene.of_triangles(curtain.world_triangles(), surface=curtain.surface()))


def test_a_curtain_lets_its_share_of_the_light_through(gl_backend):
    """A card of alpha 0.4 under a small sphere light: where the card hides the whole light,
    the points whose fixed thresholds the alpha passes are blocked, 40 % of them."""
    b = SceneBuilder("soft_curtain", (128, 96))
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    _card(b, "curtain", (0.0, 0.0, 1.0), 3.0, AlphaMap.constant("curtain", 0.4))
    b.point_light((0.0, 0.0, 4.0), radius=0.1)
    b.camera((0.0, -6.0, 0.6), (0.0, 0.0, 0.0), fov_deg=30.0)  # under the card, from the side
    scene = b.finish()
    samples, _, evaluable = view_samples(scene)
    resident = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    ours = ShadowPipeline(gl_backend).render(scene.light, resident, samples,
                                             ShadowSettings("dpsm", 256, warp="notw", exact=True)).visibility
    gl_backend.release_scene(resident)
    xy = samples.positions[..., :2]
    under = evaluable & (np.abs(xy).max(axis=-1) < 0.8) & (samples.positions[..., 2] < 0.01)
    assert under.sum() > 100
    assert np.allclose(ours[under], 0.6, atol=0.05), (float(ours[under].min()), float(ours[under].max()))
