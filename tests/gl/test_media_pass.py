"""Homogeneous media in the shadow passes (issue 43), against core/media.py's oracle.

A floor and a figure under a light, and a box of fog (a medium: no surface, extinction
sigma) around the figure, reaching below the floor, so that the floor and the figure are
receivers inside the fog. `exact` must give exp(-sigma L) per channel, L each sample's
length inside the box towards the light, times the opaque figure's hard shadow; the maps
give it along each texel's ray (lib/media.glsl's haze), so they are right but for a
texel's width at the box's silhouette. With the light inside the fog, every segment
starts in it.
"""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.alpha import Surface
from addon.core.media import Medium, optical_depths, visibility, winding_numbers
from addon.core.scene import SceneBuilder
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from addon.render.resident import ResidentScene
from addon.render.frame import Measure
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl

FOG_CENTRE, FOG_SIZE = (0.3, 0.2, 0.9), (2.4, 2.0, 2.2)


def _finished(builder: SceneBuilder):
    builder.point_light((0.0, 0.0, 5.0))
    builder.camera((0.0, -6.0, 5.0), (0.0, 0.0, 0.0), fov_deg=60.0)
    return builder.finish()


SUN = (-0.3, 0.25, -1.0)  # the sun's light travels along this


def _case(light=(0.8, -0.6, 4.0), spot: bool = False, sun: bool = False):
    b = SceneBuilder("fog_test", (96, 72))
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    b.box("figure", (0.2, 0.3, 0.6), (0.4, 0.4, 1.2))
    if sun:
        b.sun_light(SUN)
    elif spot:
        b.spot_light(light, (0.0, 0.0, 0.0), 150.0)
    else:
        b.point_light(light)
    b.camera((0.0, -6.5, 5.5), (0.0, 0.0, 0.3), fov_deg=55.0)
    scene = b.finish()
    samples, hard, evaluable = view_samples(scene)  # the camera sees no medium
    return scene, samples, hard, evaluable


def _fog() -> np.ndarray:
    b = SceneBuilder("fog_only", (8, 8))
    b.box("fog", FOG_CENTRE, FOG_SIZE)
    return _finished(b).world_triangles()


def _resident(scene, fog: np.ndarray, medium: Medium) -> ResidentScene:
    resident = ResidentScene()
    resident.set_geometry("opaque", scene.world_triangles())
    surface = Surface.opaque(len(fog)).with_media(np.zeros(len(fog), np.int32), (medium,))
    resident.set_geometry("fog", fog, surface=surface)
    return resident


def _expected(scene, samples, hard, fog, medium):
    # A sun: its rays from a point far upstream (1e5 m: their directions part by 3e-5 over the fog).
    origin = (-1e5 * scene.light.axis if scene.light.emission == "sun" else scene.light.position)
    depth = optical_depths(origin, samples.positions.reshape(-1, 3), fog, np.zeros(len(fog), np.int32), (medium,))
    return hard * visibility(depth).reshape(hard.shape)


def test_the_fog_box_is_closed_and_wound_outward():
    fog = _fog()
    assert abs(winding_numbers(np.array(FOG_CENTRE), fog) - 1.0) < 1e-9
    assert abs(winding_numbers(np.array([5.0, 5.0, 5.0]), fog)) < 1e-9


@pytest.mark.parametrize("light,sigma", [((0.8, -0.6, 4.0), 0.9), ((0.5, 0.6, 1.6), 0.7),
                                         ((0.8, -0.6, 4.0), (0.2, 0.9, 2.5))],
                         ids=["outside", "light_inside", "tinted"])
def test_exact_gives_the_transmittance_of_the_fog(gl_backend, light, sigma):
    scene, samples, hard, evaluable = _case(light)
    fog, medium = _fog(), Medium("fog", sigma)
    want = _expected(scene, samples, hard, fog, medium)
    resident = _resident(scene, fog, medium)
    try:
        got = ShadowPipeline(gl_backend).render(scene.light, resident, samples,
                                                ShadowSettings("dpsm", 256, warp="notw", exact=True)).visibility
    finally:
        gl_backend.release_scene(resident)
    inside = evaluable & (want > 0.0) & (want < 1.0)
    assert inside.sum() > 500, int(inside.sum())  # most of the floor and figure are in the fog
    error = np.abs(got - want)[evaluable]
    assert error.max() < 2e-3, float(error.max())  # float32 and the fixed point, no more


def test_exact_without_the_medium_is_the_opaque_shadow_only(gl_backend):
    """The same frame with the fog's triangles as a surface shadows far more: the medium
    path is what lets the light through."""
    scene, samples, hard, evaluable = _case()
    fog = _fog()
    resident = ResidentScene()
    resident.set_geometry("opaque", scene.world_triangles())
    resident.set_geometry("fog", fog)
    try:
        got = ShadowPipeline(gl_backend).render(scene.light, resident, samples,
                                                ShadowSettings("dpsm", 256, exact=True)).visibility
    finally:
        gl_backend.release_scene(resident)
    want = _expected(scene, samples, hard, fog, Medium("fog", 0.9))
    assert np.abs(got - want)[evaluable].mean() > 0.05


@pytest.mark.parametrize("kind", ["spot", "sun"])
def test_exact_under_a_spot_and_a_sun(gl_backend, kind):
    scene, samples, hard, evaluable = _case(spot=kind == "spot", sun=kind == "sun")
    fog, medium = _fog(), Medium("fog", 1.1)
    want = _expected(scene, samples, hard, fog, medium)
    resident = _resident(scene, fog, medium)
    try:
        result = ShadowPipeline(gl_backend).render(scene.light, resident, samples,
                                                   ShadowSettings("sm", 512, exact=True))
    finally:
        gl_backend.release_scene(resident)
    tested = evaluable & (result.flags == 0)
    assert tested.sum() > 500 and ((want > 0.05) & (want < 0.95) & tested).sum() > 300
    assert np.abs(result.visibility - want)[tested].max() < 2e-3


@pytest.mark.parametrize("kind,method", [("spot", "sm"), ("spot", "psm"), ("sun", "sm"), ("sun", "psm")])
def test_spot_and_sun_maps_give_the_fog(gl_backend, kind, method):
    """A spot's and a sun's haze: the fog's triangles rasterised in the map, each texel's
    crossings along the light's ray through it. The spot's map (150 degrees at 1024) has
    texels of 5 mm at the fog's top, where rays graze its edges: 5 % of the samples there
    differ by more than 0.01 (0.3 % at 4096, measured)."""
    scene, samples, hard, evaluable = _case(spot=kind == "spot", sun=kind == "sun")
    fog, medium = _fog(), Medium("fog", (0.5, 0.9, 1.4))
    want = _expected(scene, samples, hard, fog, medium)
    resident = _resident(scene, fog, medium)
    try:
        result = ShadowPipeline(gl_backend).render(scene.light, resident, samples, ShadowSettings(method, 1024))
    finally:
        gl_backend.release_scene(resident)
    tested = evaluable & (result.flags == 0)
    error = np.abs(result.visibility - want)[tested]
    assert tested.sum() > 500 and np.mean(error < 0.01) >= 0.93, float(np.mean(error < 0.01))
    assert error.mean() < 0.003, float(error.mean())


@pytest.mark.parametrize("param,warp", [("dpsm", "notw"), ("cube", "none"), ("dpsm", "none")])
@pytest.mark.parametrize("light", [(0.8, -0.6, 4.0), (0.5, 0.6, 1.6)], ids=["outside", "light_inside"])
def test_maps_give_the_fog_along_their_texels(gl_backend, param, warp, light):
    """The haze of one convex box is exact along each texel's ray; only samples whose
    texel's ray and own segment part at the box's silhouette, or at the figure's, differ."""
    scene, samples, hard, evaluable = _case(light)
    fog, medium = _fog(), Medium("fog", (0.5, 0.9, 1.4))
    want = _expected(scene, samples, hard, fog, medium)
    resident = _resident(scene, fog, medium)
    try:
        got = ShadowPipeline(gl_backend).render(scene.light, resident, samples,
                                                ShadowSettings(param, 1024, warp=warp)).visibility
    finally:
        gl_backend.release_scene(resident)
    error = np.abs(got - want)[evaluable]
    assert np.mean(error < 0.01) >= 0.97, float(np.mean(error < 0.01))
    assert error.mean() < 0.01, float(error.mean())


@pytest.mark.parametrize("method", ["exact", "dpsm+notw"])
def test_a_sized_light_through_the_fog(gl_backend, method):
    """A sphere light of 0.15 m over the fog: both weigh the fog along the segment to the
    light's centre (pipeline.media_drawn), times the share of the light the surfaces let
    through. Against the mean over the sphere's points of each point's transmittance,
    which they approximate: within 0.01 on average, and their error is that of the
    centre's segment."""
    from addon.core.light_shape import Sphere
    from addon.core.scene import LightSpec
    from addon.render.frame import settings_for

    scene, samples, hard, evaluable = _case()
    sized = LightSpec("omni", scene.light.matrix_world, shape=Sphere(0.15))
    fog, medium = _fog(), Medium("fog", 0.9)
    rng = np.random.default_rng(7)
    points = rng.normal(size=(64, 3))
    points = scene.light.position + 0.15 * points / np.linalg.norm(points, axis=1, keepdims=True)
    positions = samples.positions.reshape(-1, 3)
    mean_kept = np.mean([visibility(optical_depths(q, positions, fog, np.zeros(len(fog), np.int32), (medium,)))
                         for q in points], axis=0).reshape(hard.shape)
    resident = _resident(scene, fog, medium)
    try:
        got = ShadowPipeline(gl_backend).render(sized, resident, samples,
                                                settings_for(method, 512, "omni")).visibility
    finally:
        gl_backend.release_scene(resident)
    clear = evaluable & hard & _clear_of_figure(scene, positions, hard.shape)
    assert clear.sum() > 1000
    assert np.abs(got - mean_kept)[clear].mean() < 0.01


def _clear_of_figure(scene, positions: np.ndarray, shape) -> np.ndarray:
    """Samples far from the figure's shadow: a sized light's own penumbra is not asked here."""
    figure = np.array([0.2, 0.3, 0.6])
    return (np.linalg.norm(positions[:, :2] - figure[:2], axis=1) > 1.2).reshape(shape)


def test_the_transmittance_map_comes_with_the_atlas(gl_backend):
    """A frame that keeps its atlas keeps the haze's transmittance too (the overlay's and the
    report's map): below one where texels see the fog, as low as the thickest slab lets
    through, one elsewhere; a scene without media has none."""
    scene, samples, hard, evaluable = _case()
    fog, medium = _fog(), Medium("fog", 0.9)
    resident = _resident(scene, fog, medium)
    pipe = ShadowPipeline(gl_backend)
    try:
        result = pipe.render(scene.light, resident, samples, ShadowSettings("dpsm", 256, warp="notw"), measure=Measure(keep_atlas=True))
    finally:
        gl_backend.release_scene(resident)
    assert result.haze is not None and result.haze.shape == result.atlas.shape
    foggy = result.haze < 1.0
    # No slab of the box is longer than its diagonal, and every ray that meets it crosses it.
    assert foggy.sum() > 1000 and result.haze.min() >= np.exp(-0.9 * np.linalg.norm(FOG_SIZE)) - 1e-3
    assert (result.haze[foggy] < np.exp(-0.9 * 0.5)).any()  # some rays cross more than 0.5 m
    plain = ResidentScene.of_triangles(scene.world_triangles())
    try:
        assert pipe.render(scene.light, plain, samples, ShadowSettings("dpsm", 256), measure=Measure(keep_atlas=True)).haze is None
    finally:
        gl_backend.release_scene(plain)


def test_a_large_sphere_light_through_the_fog_follows_its_points(gl_backend):
    """A sphere light of 0.5 m over the fog, exact: each sample weighs the fog along the
    segments of a stratified share of the light's points, with the surfaces' weights and
    marks (shadow_test.frag). Against the weighted mean over 256 points of the cap each
    sample sees (what Cycles integrates), on the samples whose fog shadow the light's size
    softens: within 0.006 on average, and at least twice as close as 16 points would be."""
    from addon.core.light_shape import Sphere
    from addon.core.scene import LightSpec
    from addon.render.frame import settings_for
    from addon.render.soft import cluster_order, share_points
    from tests.support.soft_oracle import _blocked, sphere_targets

    scene, samples, hard, evaluable = _case()
    sized = LightSpec("omni", scene.light.matrix_world, shape=Sphere(0.5))
    fog, medium = _fog(), Medium("fog", 0.9)
    resident = _resident(scene, fog, medium)
    try:
        got = ShadowPipeline(gl_backend).render(sized, resident, samples, settings_for("exact", 512, "omni")).visibility
    finally:
        gl_backend.release_scene(resident)
    positions = samples.positions.reshape(-1, 3).astype(np.float64)
    normals = samples.normals.reshape(-1, 3).astype(np.float64)
    centre = visibility(optical_depths(sized.position, positions, fog, np.zeros(len(fog), np.int32), (medium,)))
    rng = np.random.default_rng(3)
    candidates = np.flatnonzero(evaluable.reshape(-1))
    picked = rng.choice(candidates, size=400, replace=False)
    opaque = scene.world_triangles()
    subset16 = cluster_order(256)[list(share_points(256, 16))]
    want, sixteen = [], []
    for i in picked:
        p, n = positions[i:i + 1], normals[i]
        n = n if np.dot(n, sized.position - p[0]) >= 0.0 else -n
        q = sphere_targets(sized.position, 0.5, p, 256)[0]
        d = q - p[0]
        weight = np.maximum(d @ n, 0.0) / np.linalg.norm(d, axis=1) * ~_blocked(p, q[None], opaque)[0]
        total = np.maximum(d @ n, 0.0) / np.linalg.norm(d, axis=1)
        kept = visibility(optical_depths(p[0], q, fog, np.zeros(len(fog), np.int32), (medium,)))
        want.append((weight * kept).sum() / total.sum())
        share = (weight[subset16] * kept[subset16]).sum() / max(weight[subset16].sum(), 1e-30)
        sixteen.append(weight.sum() / total.sum() * share)
    want, sixteen = np.array(want), np.array(sixteen)
    soft = np.abs(want - centre[picked]) > 0.02  # the light's size shows in the fog's shadow
    assert soft.sum() > 40, soft.sum()
    ours = np.abs(got.reshape(-1)[picked] - want)[soft]
    theirs = np.abs(sixteen - want)[soft]
    assert ours.mean() < 0.006 and ours.mean() < 0.5 * theirs.mean(), (ours.mean(), theirs.mean())
