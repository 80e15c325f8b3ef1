"""Density grids in the shadow test (issue 43, lib/grids.glsl), against core/media.py's
oracle: a floor and a figure under a light, and a cloud (a blob of density on a grid of
24 x 20 x 16 voxels, turned, reaching below the floor), marched from each view sample to
the light in half-voxel steps. Every method marches the same way, the maps and `exact`
alike, so each gives the cloud's transmittance times its own hard shadow.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core.media import GridMedium, grid_optical_depths, visibility
from addon.core.scene import SceneBuilder
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from addon.render.resident import ResidentScene
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl

SHAPE = (16, 20, 24)  # nz, ny, nx
VOXEL = 0.12


def cloud(sigma=(1.2, 1.6, 2.0)) -> GridMedium:
    """A soft blob with a hole, turned 30 degrees about Z, its box from (-1.4, -1.2, -0.3)."""
    nz, ny, nx = SHAPE
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    centre = (np.array([nx, ny, nz]) - 1) / 2.0
    r2 = ((i - centre[0]) / 9.0) ** 2 + ((j - centre[1]) / 7.5) ** 2 + ((k - centre[2]) / 6.0) ** 2
    density = np.exp(-2.0 * r2) * (1.0 - 0.8 * np.exp(-((i - 15.0) ** 2 + (j - 8.0) ** 2) / 6.0))
    angle = math.radians(30.0)
    to_world = np.eye(4)
    to_world[:3, :3] = VOXEL * np.array([[math.cos(angle), -math.sin(angle), 0.0],
                                         [math.sin(angle), math.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    to_world[:3, 3] = (-1.4, -1.2, -0.3)
    return GridMedium("cloud", sigma, density.astype(np.float32), np.linalg.inv(to_world))


def _case(light=(0.9, -0.4, 4.0), sun: bool = False):
    b = SceneBuilder("cloud_test", (96, 72))
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    b.box("figure", (0.2, 0.3, 0.6), (0.4, 0.4, 1.2))
    if sun:
        b.sun_light((-0.3, 0.25, -1.0))
    else:
        b.point_light(light)
    b.camera((0.0, -6.5, 5.5), (0.0, 0.0, 0.3), fov_deg=55.0)
    scene = b.finish()
    samples, hard, evaluable = view_samples(scene)
    return scene, samples, hard, evaluable


def _expected(scene, samples, hard, grid):
    points = samples.positions.reshape(-1, 3)
    # A sun's rays: from 20 m upstream of each point, past the whole cloud.
    origin = points - 20.0 * scene.light.axis if scene.light.emission == "sun" else scene.light.position
    depth = grid_optical_depths(origin, points, (grid,), steps=2048)
    return hard * visibility(depth).reshape(hard.shape)


def test_the_oracle_samples_between_voxel_centres():
    grid = cloud()
    to_world = np.linalg.inv(grid.to_index)
    centre = (to_world @ np.array([3.0, 4.0, 5.0, 1.0]))[:3]
    assert grid.density_at(centre[None])[0] == pytest.approx(float(grid.density[5, 4, 3]), rel=1e-6)
    half = (to_world @ np.array([3.5, 4.0, 5.0, 1.0]))[:3]
    assert grid.density_at(half[None])[0] == pytest.approx(float(grid.density[5, 4, 3:5].mean()), rel=1e-6)
    outside = (to_world @ np.array([-0.6, 4.0, 5.0, 1.0]))[:3]
    assert grid.density_at(outside[None])[0] == 0.0


@pytest.mark.parametrize("method,light", [("exact", (0.9, -0.4, 4.0)), ("dpsm+notw", (0.9, -0.4, 4.0)),
                                          ("cube", (0.9, -0.4, 4.0)), ("exact", (-0.2, 0.0, 0.4)),
                                          ("sm", None)],
                         ids=["exact", "dpsm_notw", "cube", "light_inside", "sun_sm"])
def test_the_march_gives_the_clouds_transmittance(gl_backend, method, light):
    from addon.render.frame import settings_for

    scene, samples, hard, evaluable = _case(light or (0.0, 0.0, 4.0), sun=light is None)
    grid = cloud()
    want = _expected(scene, samples, hard, grid)
    resident = ResidentScene.of_triangles(scene.world_triangles())
    resident.set_grid("cloud", grid)
    try:
        result = ShadowPipeline(gl_backend).render(scene.light, resident, samples,
                                                   settings_for(method, 512, scene.light.emission))
    finally:
        gl_backend.release_scene(resident)
    judged = evaluable & (result.flags == 0) & (hard == (result.visibility > 0.0))  # its own hard shadow agrees
    cloudy = judged & (want < 0.95) & (want > 0.0)
    assert cloudy.sum() > 300, int(cloudy.sum())
    error = np.abs(result.visibility - want)[judged]
    # Half-voxel steps against the oracle's fine ones (measured: 3e-4 at most, 9e-5 on average).
    assert error.max() < 2e-3 and error.mean() < 3e-4, (float(error.max()), float(error.mean()))


def test_without_the_grid_the_frame_is_unchanged(gl_backend):
    """A grid is marched only where a scene holds one: the same frame without it gives the
    plain hard shadows."""
    scene, samples, hard, evaluable = _case()
    resident = ResidentScene.of_triangles(scene.world_triangles())
    try:
        got = ShadowPipeline(gl_backend).render(scene.light, resident, samples, ShadowSettings("dpsm", 512)).visibility
    finally:
        gl_backend.release_scene(resident)
    assert set(np.unique(got[evaluable])) <= {0.0, 1.0}


@pytest.mark.parametrize("method", ["exact", "dpsm+notw"])
def test_a_sized_light_marches_towards_its_points(gl_backend, method):
    """A sphere light of 0.3 m over a cloud with a sharp edge (a box of constant density):
    each sample marches towards 8 of the light's points, so its light is their mean, within
    0.01 of the mean over 64 points of the disk of the sphere facing it (the centre alone
    errs more near the cloud's edge, where the points part)."""
    from addon.core.light_shape import Sphere, stratified_points
    from addon.core.scene import LightSpec
    from addon.render.frame import settings_for

    scene, samples, hard, evaluable = _case((0.9, -0.4, 2.6))
    sized = LightSpec("omni", scene.light.matrix_world, shape=Sphere(0.3))
    box = np.ones((8, 10, 12), np.float32)
    to_world = np.diag([0.15, 0.15, 0.15, 1.0])
    to_world[:3, 3] = (-0.9, -0.7, 0.9)
    grid = GridMedium("slab", 2.0, box, np.linalg.inv(to_world))
    positions = samples.positions.reshape(-1, 3)
    light = scene.light.position
    w = light - positions
    w /= np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-30)
    a = np.cross(w, np.where(np.abs(w[:, 2:3]) < 0.9, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(w, a)
    disk = stratified_points(Sphere(0.3), 64)
    mean_kept = np.mean([visibility(grid_optical_depths(light + x * a + y * b, positions, (grid,), steps=256))
                         for x, y, _ in disk], axis=0).reshape(hard.shape)
    centre = visibility(grid_optical_depths(light, positions, (grid,), steps=256)).reshape(hard.shape)
    resident = ResidentScene.of_triangles(scene.world_triangles())
    resident.set_grid("slab", grid)
    try:
        got = ShadowPipeline(gl_backend).render(sized, resident, samples, settings_for(method, 512, "omni")).visibility
    finally:
        gl_backend.release_scene(resident)
    clear = evaluable & hard & (np.linalg.norm(positions[:, :2] - [0.2, 0.3], axis=1) > 1.2).reshape(hard.shape)
    edge = clear & (np.abs(mean_kept - centre) > 0.05)  # where the light's points part at the edge
    assert clear.sum() > 1000 and edge.sum() > 50, (int(clear.sum()), int(edge.sum()))
    assert np.abs(got - mean_kept)[clear].mean() < 0.01
    assert np.abs(got - mean_kept)[edge].mean() < 0.5 * np.abs(centre - mean_kept)[edge].mean()


def test_a_moved_grid_keeps_its_texture_and_a_dropped_one_is_freed(gl_backend):
    """The GPU holds a grid's density by its own digest: a moved grid (the viewport's moved
    Volume object) shares it, uploads nothing and hashes nothing again; a grid whose density
    changed, or that its scene dropped, frees its texture at the next sync."""
    grid = cloud()
    scene = ResidentScene()
    scene.set_grid("cloud", grid)
    others = set(gl_backend.grids.textures)  # the shared backend's, from earlier tests
    gl_backend.sync_scene(scene)
    held = dict(gl_backend.grids.textures)
    assert set(held) - others == {grid.density_digest}
    shift = np.eye(4)
    shift[:3, 3] = (0.5, 0.0, 0.0)
    moved = grid.moved(grid.to_index @ np.linalg.inv(shift))
    assert moved.density is grid.density and moved.density_digest == grid.density_digest
    assert moved.digest != grid.digest
    assert moved.density_at(np.array([[0.5, 0.0, 0.4]]))[0] == grid.density_at(np.array([[0.0, 0.0, 0.4]]))[0]
    scene.set_grid("cloud", moved)
    uploaded = gl_backend.geometry_bytes
    gl_backend.sync_scene(scene)
    assert gl_backend.geometry_bytes == uploaded and gl_backend.grids.textures == held
    denser = GridMedium("cloud", grid.sigma, 2.0 * grid.density, grid.to_index)
    scene.set_grid("cloud", denser)
    gl_backend.sync_scene(scene)
    assert set(gl_backend.grids.textures) - others == {denser.density_digest}
    assert grid.density_digest not in gl_backend.grids.textures or grid.density_digest in others
    scene.remove("cloud")
    gl_backend.sync_scene(scene)
    assert set(gl_backend.grids.textures) - others == set()
    gl_backend.release_scene(scene)
