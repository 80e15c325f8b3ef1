"""Depth maps against analytic radial distances, on tiny targets."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import projection
from addon.core.scene import SceneBuilder
from addon.render.pipeline import ShadowPipeline, ShadowSettings, ViewSamples

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
                                               ShadowSettings(param, res, cull=False), keep_atlas=True)
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
                                               ShadowSettings("dpsm", 32, cull=False), keep_atlas=True)
    assert np.all(_tile(result, 1) == 1.0)
    corner = _tile(result, 0)[0, 0]  # outside the unit disk
    assert corner == 1.0
