"""See-through materials in the shadow passes (issue 25), against the numpy ray caster.

A floor under a point light, with a cut-out card (a checker alpha image), a curtain of
alpha 0.5 with a smaller veil of alpha 0.5 over part of it, and an opaque box. `exact`
must give the product of (1 - alpha) along each sample's segment. The maps store the
opaque surfaces' depth and put the partly transparent ones in the veil (lib/veil.glsl),
so on the cut-outs they are right wherever a map of their resolution can be, and behind
the curtains they pass its light; with the alpha ignored they are clearly wrong.
"""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.alpha import AlphaMap
from addon.core.scene import SceneBuilder
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from tests.support.oracle import transmittance, view_samples

pytestmark = pytest.mark.gl


def _card(builder: SceneBuilder, name: str, centre, size: float, alpha: AlphaMap, tiles: float = 1.0) -> None:
    """A horizontal square facing up, UVs over `tiles` repeats of its alpha."""
    h = size / 2.0
    corners = np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]]) + np.asarray(centre)
    uvs = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) * tiles
    builder.mesh(name, corners, [[0, 1, 2], [0, 2, 3]], uvs=uvs, alpha=alpha)


def _scene(spot: bool = False):
    b = SceneBuilder("alpha_test", (96, 72))
    b.plane("floor", (0.0, 0.0, 0.0), 12.0, 12.0)
    checker = (np.indices((8, 8)).sum(axis=0) % 2).astype(np.float32)
    _card(b, "card", (-1.5, 0.0, 1.5), 2.0, AlphaMap("checker", checker, "closest", "repeat"))
    _card(b, "fence", (1.5, -1.5, 1.5), 2.0, AlphaMap("holes", checker, "linear", "repeat"), tiles=3.0)
    _card(b, "curtain", (1.5, 1.5, 1.5), 2.0, AlphaMap.constant("curtain", 0.5))
    _card(b, "veil", (1.8, 1.8, 2.0), 1.4, AlphaMap.constant("veil", 0.5))  # over part of the curtain
    b.box("box", (0.0, 3.0, 0.5), (1.0, 1.0, 1.0))
    if spot:
        b.spot_light((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), 160.0)
    else:
        b.point_light((0.0, 0.0, 4.0))
    b.camera((0.0, -7.0, 7.0), (0.0, 0.0, 0.0), fov_deg=60.0)
    return b.finish()


@pytest.fixture(scope="module")
def alpha_case():
    scene = _scene()
    samples, _, evaluable = view_samples(scene)
    light = scene.light.position
    expected = transmittance(light, samples.positions.reshape(-1, 3), scene.world_triangles(),
                             scene.surface()).reshape(evaluable.shape)
    return scene, samples, expected, evaluable


def test_exact_gives_the_product_of_transmittances(gl_backend, alpha_case):
    scene, samples, expected, evaluable = alpha_case
    pipe = ShadowPipeline(gl_backend)
    from addon.render.resident import ResidentScene

    resident = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    result = pipe.render(scene.light, resident, samples, ShadowSettings("dpsm", 256, warp="notw", exact=True))
    got = result.visibility[evaluable]
    want = expected[evaluable]
    half = np.abs(want - 0.5) < 1e-6
    assert half.sum() > 50 and (want == 0.0).sum() > 50 and ((want > 0) & (want < 1) & ~half).sum() > 0
    # Cut-outs are exact; fractional crossings to the word's quantisation. A sample on a
    # texel boundary of the closest-filtered checker may round either way: a few.
    wrong = np.abs(got - want) > 1e-3
    assert wrong.sum() <= max(2, int(2e-3 * evaluable.sum())), int(wrong.sum())
    gl_backend.release_scene(resident)


@pytest.mark.parametrize("param,warp", [("dpsm", "notw"), ("cube", "none")])
def test_maps_alpha_test_at_one_half(gl_backend, alpha_case, param, warp):
    scene, samples, expected, evaluable = alpha_case
    from addon.render.resident import ResidentScene

    pipe = ShadowPipeline(gl_backend)
    decisive = evaluable & (np.abs(expected - 0.5) > 0.25)  # the curtain's pixels are fractional
    settings = ShadowSettings(param, 1024, warp=warp)
    with_alpha = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    plain = ResidentScene.of_triangles(scene.world_triangles())
    wrong = {}
    for name, resident in (("alpha", with_alpha), ("ignored", plain)):
        vis = pipe.render(scene.light, resident, samples, settings).visibility
        wrong[name] = int((((vis > 0.5) != (expected > 0.5)) & decisive).sum())
        gl_backend.release_scene(resident)
    assert wrong["alpha"] <= max(3, int(0.01 * decisive.sum())), wrong
    assert wrong["ignored"] > 10 * max(wrong["alpha"], 5), wrong


@pytest.mark.parametrize("param,warp", [("dpsm", "notw"), ("cube", "none"), ("dpsm", "none")])
def test_maps_pass_the_light_of_partly_transparent_surfaces(gl_backend, alpha_case, param, warp):
    """Behind the curtain (alpha 0.5) a map gives one half, behind both curtains one
    quarter (the veil's product), as the ray caster does; in front of them, and away from
    them, all that was lit stays lit. Only a texel's width at their rims may differ."""
    scene, samples, expected, evaluable = alpha_case
    from addon.render.resident import ResidentScene

    resident = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    vis = ShadowPipeline(gl_backend).render(scene.light, resident, samples,
                                            ShadowSettings(param, 1024, warp=warp)).visibility
    gl_backend.release_scene(resident)
    for share in (0.5, 0.25):
        behind = evaluable & (np.abs(expected - share) < 1e-6)
        close = np.abs(vis - share) < 2e-3  # the optical depth's quantisation, and the exp
        assert behind.sum() > 40 and close[behind].mean() >= 0.93, (share, int(behind.sum()),
                                                                   float(close[behind].mean()))
    lit = evaluable & (expected == 1.0)
    assert (vis[lit] == 1.0).mean() >= 0.99


@pytest.mark.parametrize("method", ["sm", "psm"])
def test_spot_maps_pass_the_light_of_partly_transparent_surfaces(gl_backend, method):
    """The projective maps' veil: the same halves and quarters under a spot light."""
    scene = _scene(spot=True)
    samples, _, evaluable = view_samples(scene)
    expected = transmittance(scene.light.position, samples.positions.reshape(-1, 3), scene.world_triangles(),
                             scene.surface()).reshape(evaluable.shape)
    from addon.render.resident import ResidentScene

    resident = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    vis = ShadowPipeline(gl_backend).render(scene.light, resident, samples, ShadowSettings(method, 1024)).visibility
    gl_backend.release_scene(resident)
    for share in (0.5, 0.25):
        behind = evaluable & (np.abs(expected - share) < 1e-6)
        close = np.abs(vis - share) < 2e-3
        assert behind.sum() > 40 and close[behind].mean() >= 0.93, (share, float(close[behind].mean()))


def test_the_veil_does_not_outlive_its_atlas(gl_backend, alpha_case):
    """A frame without see-through parts after one with them gives what it gives first."""
    scene, samples, _, _ = alpha_case
    from addon.render.resident import ResidentScene

    pipe = ShadowPipeline(gl_backend)
    settings = ShadowSettings("dpsm", 512, warp="notw")
    plain = ResidentScene.of_triangles(scene.world_triangles())
    first = pipe.render(scene.light, plain, samples, settings).visibility
    see_through = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    veiled = pipe.render(scene.light, see_through, samples, settings).visibility
    again = pipe.render(scene.light, plain, samples, settings).visibility
    assert not np.array_equal(veiled, first) and ((veiled > 0) & (veiled < 1)).any()
    assert np.array_equal(again, first) and set(np.unique(first)) <= {0.0, 1.0}
    gl_backend.release_scene(plain)
    gl_backend.release_scene(see_through)


def test_alpha_maps_upload_once_and_free_with_their_last_part(gl_backend, alpha_case):
    scene = alpha_case[0]
    from addon.render.resident import ResidentScene

    before = gl_backend.resident_alpha_maps()
    a = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    b = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    gl_backend.sync_scene(a)
    gl_backend.sync_scene(b)
    # checker, holes and alpha 0.5 (the curtain's and the veil's, one digest): shared by a and b
    assert gl_backend.resident_alpha_maps() == before + 3
    gl_backend.release_scene(a)
    assert gl_backend.resident_alpha_maps() == before + 3
    gl_backend.release_scene(b)
    assert gl_backend.resident_alpha_maps() == before


def test_the_foliage_preset_shadows_through_its_alpha(gl_backend):
    """On the foliage preset (leaf cards, chain-link, a curtain) `exact` gives the ray
    caster's transmittance; with the alpha ignored it gives the shadows of rectangles."""
    from addon.core.presets import build_preset
    from addon.render.resident import ResidentScene

    scene = build_preset("foliage", (128, 96))
    samples, _, evaluable = view_samples(scene)
    expected = transmittance(scene.light.position, samples.positions.reshape(-1, 3), scene.world_triangles(),
                             scene.surface()).reshape(evaluable.shape)[evaluable]
    pipe = ShadowPipeline(gl_backend)
    settings = ShadowSettings("dpsm", 1024, warp="notw", exact=True)
    wrong = {}
    for name, surface in (("alpha", scene.surface()), ("ignored", None)):
        resident = ResidentScene.of_triangles(scene.world_triangles(), surface=surface)
        got = pipe.render(scene.light, resident, samples, settings).visibility[evaluable]
        wrong[name] = int((np.abs(got - expected) > 1e-3).sum())
        gl_backend.release_scene(resident)
    assert wrong["alpha"] <= max(2, int(1e-3 * evaluable.sum())), wrong
    assert wrong["ignored"] > 0.05 * evaluable.sum(), wrong
