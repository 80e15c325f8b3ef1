"""Depth maps against analytic radial distances, on tiny targets."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import projection
from addon.core.scene import SceneBuilder
from addon.render.pipeline import ShadowPipeline, ShadowSettings, ViewSamples
from addon.render.frame import Measure

pytestmark = pytest.mark.gl


def _floor_scene(size=8.0, height=-1.0):
    b = SceneBuilder("floor", (8, 8))
    b.plane("floor", (0.0, 0.0, height), size, size)
    b.point_light((0.0, 0.0, 0.0))
    b.camera((0.0, 0.0, 5.0), (0.0, 0.0, 0.0))
    return b.finish()


def _samples(scene, point):
    pos = np.zeros((8, 8, 3))
    pos[:] = point
    return ViewSamples(pos, np.tile([0.0, 0.0, 1.0], (8, 8, 1)), np.ones((8, 8), bool), scene.camera)


def _tile(result, slot):
    x, y = result.layout.origin(result.tile_of_slot[slot])
    res = result.layout.resolution
    return result.atlas[y:y + res, x:x + res]


@pytest.mark.parametrize("param,slot", [("dpsm", 0), ("cube", 5), ("unfold", 0)])
def test_floor_depth_is_exact_radial_distance(gl_backend, param, slot):
    """Every covered texel stores (|P| - near)/(far - near) of the floor point on its ray."""
    scene = _floor_scene()
    res = 32
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(),
                                               _samples(scene, (0.3, 0.2, -1.0)),
                                               ShadowSettings(param, res, cull=False), measure=Measure(keep_atlas=True))
    layer = next(layer for layer in result.plan.drawn if layer.slot == slot)
    tile = _tile(result, slot)
    centres = (np.arange(res) + 0.5) / res * 2 - 1
    xy = np.stack(np.meshgrid(centres, centres), axis=-1)  # row = y, as GL stores it
    dirs = projection.unproject(layer.kind, xy) @ layer.rotation  # to world
    t = -1.0 / dirs[..., 2]  # ray meets z = -1
    expected = projection.normalized_depth(t, result.geometry.near, result.geometry.far)
    inside = np.all(np.abs(dirs[..., :2] * t[..., None]) < 4.0 - 0.05, axis=-1) & (dirs[..., 2] < -0.05)
    if layer.kind == projection.PARABOLOID:
        inside &= np.linalg.norm(xy, axis=-1) < 1.0 - 2.0 / res
    if layer.kind == projection.UNFOLD:
        # Tessellated edges may stray a texel (pi * 2/res radians here) off the floor's
        # curved outline, so keep 1.5 texels away from it.
        reach = 4.0 - 1.5 * projection.texel_angle(layer.kind, xy, res) * t
        inside &= np.all(np.abs(dirs[..., :2] * t[..., None]) < reach[..., None], axis=-1)
    assert inside.sum() > res  # the test looks at a real area
    assert np.all(np.isfinite(tile))
    assert np.allclose(tile[inside], expected[inside], atol=2e-6)


def test_empty_texels_hold_far_and_opposite_side_is_empty(gl_backend):
    """Texels no triangle covers stay at depth 1; the upper side sees nothing of a floor below."""
    scene = _floor_scene()
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(),
                                               _samples(scene, (0.3, 0.2, -1.0)),
                                               ShadowSettings("dpsm", 32, cull=False), measure=Measure(keep_atlas=True))
    assert np.all(_tile(result, 1) == 1.0)
    corner = _tile(result, 0)[0, 0]  # outside the unit disk
    assert corner == 1.0


# (parameterization, slot, centres of the two sample clusters on the floor z = -1).
# The cube face is +X, which sees the floor edge-on towards its horizon: the floor's
# triangles pass behind the light, and their footprints are clipped at the near plane.
WARPED_FLOOR_CASES = [("dpsm", 0, [[0.6, 0.4], [-0.9, -0.7]]), ("cube", 0, [[2.0, 0.6], [5.0, -1.5]])]


@pytest.mark.parametrize("param,slot,clusters", WARPED_FLOOR_CASES)
@pytest.mark.parametrize("warp", ["notw", "rtw"])
def test_warped_floor_depth_follows_the_exact_inverse_warp(gl_backend, param, slot, clusters, warp):
    """Through a strong warp, every covered texel stores the floor's radial distance on
    the ray of its own centre, taken back through numpy's exact inverse warp.

    The footprint pass reads that ray from the layer's ray table (the GLSL exact
    inverse), so this bounds the float32 search against numpy's float64 one. The floor
    is two triangles, 100 times their height across.
    """
    scene = _floor_scene(size=200.0)
    res = 64
    rng = np.random.default_rng(3)
    # Samples bunched in two clusters: a warp far from the identity.
    centres = np.asarray(clusters, dtype=np.float64)
    pts = centres[rng.integers(0, 2, size=(24, 24))] + rng.normal(0.0, 0.12, size=(24, 24, 2))
    pos = np.concatenate([pts, np.full((24, 24, 1), -1.0)], axis=-1)
    samples = ViewSamples(pos, np.tile([0.0, 0.0, 1.0], (24, 24, 1)), np.ones((24, 24), bool), scene.camera)
    result = ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples,
                                               ShadowSettings(param, res, cull=False, warp=warp), measure=Measure(keep_atlas=True))
    layer = next(layer for layer in result.plan.drawn if layer.slot == slot)
    mapping = result.mappings[slot]
    assert mapping.warp is not None and not np.allclose(mapping.warp.rows, 0.0)
    tile = _tile(result, slot)
    centres_uv = (np.arange(res) + 0.5) / res
    uv = np.stack(np.meshgrid(centres_uv, centres_uv), axis=-1)  # row = v, as GL stores it
    xy = mapping.inverse(uv)
    dirs = projection.unproject(layer.kind, xy) @ layer.rotation
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -1.0 / dirs[..., 2]
    expected = projection.normalized_depth(t, result.geometry.near, result.geometry.far)
    hit = np.all(np.abs(dirs[..., :2] * t[..., None]) < 100.0 - 0.1, axis=-1) & (dirs[..., 2] < -0.05)
    if layer.kind == projection.PARABOLOID:
        hit &= np.linalg.norm(xy, axis=-1) < 1.0 - 0.05
    assert hit.sum() > res * res // 8
    assert np.all(np.isfinite(tile))
    error = np.abs(tile[hit] - expected[hit])
    # A 64^2 map with a warp node every texel is far harsher than the presets. Measured
    # on llvmpipe over the four cases: 90th percentile error <= 1.1e-8, and no texel off
    # by more than 1e-4 (the tessellated pass before the footprints left up to 60 of 4096).
    assert np.percentile(error, 90) < 1e-7
    assert np.count_nonzero(error > 1e-4) <= 2
