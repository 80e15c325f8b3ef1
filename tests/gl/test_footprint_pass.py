"""The footprint depth pass (footprint.vert/.frag) on the GPU: exact coverage and depth at
every texel centre, checked against the exact ray caster, and geometry that stays resident.

Each case draws one random triangle of a hard kind (seen whole, straddling the seam,
covering a pole, one vertex 1e-4 from the light, huge) into a 64x64 layer, plain or
warped. Every texel centre whose ray, through numpy's exact inverse map, meets the
triangle must be covered with that hit's depth, and every other texel left empty,
except texels whose ray lies within float32 rounding of one of the triangle's edge planes.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from addon.core import projection
from addon.core.scene import LightSpec
from addon.render.pipeline import ShadowPipeline, ShadowSettings, ViewSamples
from addon.render.resident import ResidentScene
from addon.render.frame import Measure
from tests.core.test_footprint import KINDS, _random_rotation, _triangle
from tests.support.oracle import ray_hits

pytestmark = pytest.mark.gl

RES = 64
# A texel may disagree with the exact caster only where its ray passes this close (in
# radians) to an edge plane of the triangle: float32 rays and edge normals.
EDGE_MARGIN = 1e-4
DEPTH_TOLERANCE = 2e-5  # normalised depth, float32 over a far / near ratio of up to 1e5
# A float32 ray (the warped layers' searched inverse) errs by about this angle; where the
# triangle's plane is seen at a grazing angle the hit distance errs by t * angle / cos.
RAY_ANGLE = 1e-5


def _light() -> LightSpec:
    return LightSpec("omni", np.eye(4))


def _samples(tri: np.ndarray, rng: np.random.Generator) -> ViewSamples:
    """View samples on the triangle (barycentric), bunched so that a warp is far from the identity."""
    weights = rng.dirichlet([0.3, 0.3, 0.3], size=(16, 16))
    positions = np.einsum("hwk,kc->hwc", weights, tri)
    normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    normal /= np.linalg.norm(normal)
    return ViewSamples(positions, np.broadcast_to(normal, positions.shape).copy(), np.ones((16, 16), bool), None)


def _edge_margin(dirs: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Angle from each unit ray to the nearest of the triangle's three edge planes through the light."""
    normals = np.cross(tri, np.roll(tri, -1, axis=0))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return np.min(np.abs(dirs @ normals.T), axis=1)


def _check_layer(result, layer, tri: np.ndarray) -> tuple[int, int]:
    """(mismatched texels away from the edges, covered texels) of one drawn layer."""
    x, y = result.layout.origin(result.tile_of_slot[layer.slot])
    tile = result.atlas[y:y + RES, x:x + RES]
    centres = (np.arange(RES) + 0.5) / RES
    uv = np.stack(np.meshgrid(centres, centres), axis=-1).reshape(-1, 2)  # row = v, as GL stores it
    mapping = result.mappings.get(layer.slot)
    xy = mapping.inverse(uv) if mapping is not None else uv * 2.0 - 1.0
    dirs = projection.unproject(layer.kind, xy) @ layer.rotation  # world, light-centred
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    looked_up = np.ones(len(dirs), dtype=bool)
    if layer.kind == projection.PARABOLOID:
        looked_up = np.linalg.norm(xy, axis=1) <= 1.0  # the hemisphere; the corners are never read
    t, _ = ray_hits(np.zeros_like(dirs), dirs, tri[None], eps=0.0)
    hit = np.isfinite(t)
    stored = tile.reshape(-1)
    covered = stored < 1.0
    clear = _edge_margin(dirs, tri) > EDGE_MARGIN
    wrong = looked_up & clear & (covered != hit)
    depth = projection.normalized_depth(np.where(hit, t, 0.0), result.geometry.near, result.geometry.far)
    both = looked_up & clear & hit & covered & (depth < 1.0)
    normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    cos = np.abs(dirs @ (normal / np.linalg.norm(normal)))
    with np.errstate(divide="ignore", invalid="ignore"):
        grazing = RAY_ANGLE * np.where(hit, t, 0.0) / np.maximum(cos, 1e-12) / (result.geometry.far - result.geometry.near)
    wrong |= both & (np.abs(stored - np.clip(depth, 0.0, 1.0)) > DEPTH_TOLERANCE + grazing)
    return int(np.count_nonzero(wrong)), int(np.count_nonzero(looked_up & covered))


CASES = [("dpsm", "none"), ("cube", "none"), ("dpsm", "notw"), ("cube", "notw"), ("dpsm", "rtw")]


@pytest.mark.parametrize("param,warp", CASES)
def test_footprints_cover_exactly_the_texels_whose_ray_hits(gl_backend, param, warp):
    rng = np.random.default_rng(17)
    pipeline = ShadowPipeline(gl_backend)
    light = _light()
    covered_total = 0
    for index in range(20):
        kind = KINDS[index % len(KINDS)]
        tri = _triangle(rng, kind) @ _random_rotation(rng).T
        result = pipeline.render(light, tri[None], _samples(tri, rng), ShadowSettings(param, RES, cull=False, warp=warp),
                                 measure=Measure(keep_atlas=True))
        for layer in result.plan.drawn:
            wrong, covered = _check_layer(result, layer, tri)
            covered_total += covered
            assert wrong == 0, (kind, index, layer.name, wrong, covered)
    assert covered_total > 20 * RES  # the cases cover real areas


def _room() -> np.ndarray:
    """A floor at z = -2 under a light at the origin, and some clutter around."""
    rng = np.random.default_rng(4)
    clutter = rng.normal(size=(200, 3, 3)) * 0.3 + rng.normal(size=(200, 1, 3)) * 3.0 + np.array([0.0, 0.0, 6.0])
    floor = np.array([[[-20, -20, -2], [20, -20, -2], [20, 20, -2]], [[-20, -20, -2], [20, 20, -2], [-20, 20, -2]]])
    return np.concatenate([clutter, floor.astype(np.float64)])


def _view(tris: np.ndarray) -> ViewSamples:
    """Samples on the floor below the light."""
    grid = np.stack(np.meshgrid(np.linspace(-2, 2, 24), np.linspace(-2, 2, 24), [-2.0]), axis=-1).reshape(24, 24, 3)
    return ViewSamples(grid, np.tile([0.0, 0.0, 1.0], (24, 24, 1)), np.ones((24, 24), bool), None)


def test_a_repeated_frame_uploads_no_geometry(gl_backend):
    """Geometry goes up once; a moved object changes a uniform only; new geometry uploads
    that object alone."""
    pipeline = ShadowPipeline(gl_backend)
    light, tris = _light(), _room()
    scene = ResidentScene.of_triangles(tris, key="room")
    scene.set_geometry("blocker", np.array([[[-1.0, -1.0, -0.5], [1.0, -1.0, -0.5], [0.0, 1.5, -0.5]]]))
    samples = _view(tris)
    settings = ShadowSettings("dpsm", RES, warp="notw")
    start = gl_backend.geometry_bytes
    first = pipeline.render(light, scene, samples, settings)
    uploaded = gl_backend.geometry_bytes - start
    assert uploaded == sum(obj.vertex_texels().nbytes for obj in scene.objects.values())
    again = pipeline.render(light, scene, samples, settings)
    assert gl_backend.geometry_bytes - start == uploaded  # nothing new
    assert np.array_equal(again.visibility, first.visibility)
    assert (first.visibility < 0.5).sum() > 50  # the blocker shadows the floor

    moved = np.eye(4)
    moved[:3, 3] = (0.0, 0.0, 10.0)  # the blocker goes behind the light: it shadows something else
    scene.set_matrix("blocker", moved)
    shifted = pipeline.render(light, scene, samples, settings)
    assert gl_backend.geometry_bytes - start == uploaded
    assert not np.array_equal(shifted.visibility, first.visibility)

    scene.set_geometry("blocker", np.array([[[-2.0, -2.0, -0.5], [2.0, -2.0, -0.5], [0.0, 2.5, -0.5]]]))
    pipeline.render(light, scene, samples, settings)
    assert gl_backend.geometry_bytes - start == uploaded + scene.objects["blocker"].vertex_texels().nbytes
    scene.remove("blocker")
    pipeline.render(light, scene, samples, settings)
    assert gl_backend.resident_objects() >= 1 and "blocker" not in gl_backend._resident_revisions()
    gl_backend.release_scene(scene)


def test_triangle_arrays_stay_resident_only_when_read_only(gl_backend):
    """A read-only array (the viewport's selections) keeps its upload while the same array
    comes back; a writeable one is uploaded for its frame and freed after it."""
    pipeline = ShadowPipeline(gl_backend)
    light, tris = _light(), _room()
    samples = _view(tris)
    settings = ShadowSettings("cube", RES)
    held = gl_backend.resident_objects()
    frozen = tris.copy()
    frozen.flags.writeable = False
    pipeline.render(light, frozen, samples, settings)
    start = gl_backend.geometry_bytes
    pipeline.render(light, frozen, samples, settings)
    assert gl_backend.geometry_bytes == start
    assert gl_backend.resident_objects() == held + 1
    pipeline.render(light, tris, samples, settings)
    pipeline.render(light, tris, samples, settings)
    assert gl_backend.geometry_bytes == start + 2 * ResidentScene.of_triangles(tris).objects.popitem()[1].vertex_texels().nbytes
    assert gl_backend.resident_objects() == held + 1  # the writeable array's upload is gone
    pipeline.release()
    assert gl_backend.resident_objects() == held


def test_object_matrix_places_geometry_as_world_triangles_do(gl_backend):
    """An object drawn through a scaled, rotated, far-translated matrix shadows as its
    world-space triangles do."""
    rng = np.random.default_rng(8)
    pipeline = ShadowPipeline(gl_backend)
    light = LightSpec("omni", np.array([[1, 0, 0, 5e4], [0, 1, 0, -3e4], [0, 0, 1, 2e3], [0, 0, 0, 1.0]]))
    local = rng.normal(size=(60, 3, 3)) * 0.2
    matrix = np.eye(4)
    matrix[:3, :3] = _random_rotation(rng) * 1.7
    matrix[:3, 3] = light.position + (0.3, -0.2, -2.0)
    world = local @ matrix[:3, :3].T + matrix[:3, 3]
    floor = np.array([[[-50, -50, -4], [50, -50, -4], [0, 60, -4]]]) + light.position
    scene = ResidentScene()
    scene.set_geometry("object", local, matrix)
    scene.set_geometry("floor", floor)
    pts = light.position + np.stack(np.meshgrid(np.linspace(-3, 3, 24), np.linspace(-3, 3, 24), [-4.0]),
                                    axis=-1).reshape(24, 24, 3)
    samples = ViewSamples(pts, np.tile([0.0, 0.0, 1.0], (24, 24, 1)), np.ones((24, 24), bool), None)
    settings = ShadowSettings("dpsm", 256, cull=False)
    by_matrix = pipeline.render(light, scene, samples, settings)
    by_world = pipeline.render(light, np.concatenate([world, floor]), samples, settings)
    shadowed = by_world.visibility < 0.5
    assert 20 < shadowed.sum() < shadowed.size - 20  # a real shadow on the floor
    assert np.count_nonzero(by_matrix.visibility != by_world.visibility) <= 2
    gl_backend.release_scene(scene)


def point_cloud() -> tuple[np.ndarray, ViewSamples]:
    """A dense cluster of small triangles below a light at the origin (chunks of it are
    small and far: point sprites), a few big triangles around it (quads), and samples."""
    rng = np.random.default_rng(9)
    centres = rng.normal(size=(20000, 1, 3)) * 0.8 + np.array([0.3, -0.2, -6.0])
    small = centres + rng.normal(size=(20000, 3, 3)) * 0.03  # a few texels each at 256
    tris = np.concatenate([small, rng.normal(size=(40, 3, 3)) * 4.0])
    return tris, _samples(np.array([[-6.0, -6.0, -9.0], [6.0, -6.0, -9.0], [0.0, 7.0, -9.0]]), rng)


@pytest.mark.parametrize("param,warp", [("dpsm", "none"), ("dpsm", "notw"), ("cube", "none")])
def test_point_sprites_store_what_quads_store(gl_backend, monkeypatch, param, warp):
    """Chunks of small triangles drawn as point sprites give the same atlas, texel for
    texel, as the same triangles drawn as quads; and points are really used (on the
    warped layer only where the warp's global stretch bound allows)."""
    from addon.render import footprint_runs

    tris, samples = point_cloud()
    light, pipeline = _light(), ShadowPipeline(gl_backend)
    scene = ResidentScene.of_triangles(tris, key="cloud")
    settings = ShadowSettings(param, 256, cull=False, warp=warp)
    used = []
    real = footprint_runs.footprint_ranges

    def spy(*args, **kwargs):
        runs = real(*args, **kwargs)
        used.extend(run.points for run in runs)
        return runs

    monkeypatch.setattr(footprint_runs, "footprint_ranges", spy)  # what RunMemo calls
    sprites = pipeline.render(light, scene, samples, settings, measure=Measure(keep_atlas=True))
    assert any(used) or warp != "none"
    monkeypatch.setattr(footprint_runs, "MAX_POINT_SIZE", 0)  # no chunk fits: all quads
    used.clear()
    pipeline = ShadowPipeline(gl_backend)  # its own kept runs: the constant changed
    quads = pipeline.render(light, scene, samples, settings, measure=Measure(keep_atlas=True))
    assert used and not any(used)
    assert np.array_equal(sprites.atlas, quads.atlas)
    assert np.count_nonzero(sprites.atlas < 1.0) > 1000
    gl_backend.release_scene(scene)


def test_a_steady_frame_draws_the_runs_it_kept(gl_backend, monkeypatch):
    """The chunk runs of a frame whose inputs did not change are the last frame's, without
    the host's chunk tests (footprint_runs.RunMemo); a moved light tests again."""
    from addon.render import footprint_runs

    tris, samples = point_cloud()
    pipeline = ShadowPipeline(gl_backend)
    scene = ResidentScene.of_triangles(tris, key="cloud")
    settings = ShadowSettings("dpsm", 256)
    calls = []
    real = footprint_runs.footprint_ranges

    def spy(*args, **kwargs):
        calls.append(args[2].slot)
        return real(*args, **kwargs)

    monkeypatch.setattr(footprint_runs, "footprint_ranges", spy)
    light = _light()
    first = pipeline.render(light, scene, samples, settings, measure=Measure(keep_atlas=True))
    assert calls
    calls.clear()
    again = pipeline.render(light, scene, samples, settings, measure=Measure(keep_atlas=True))
    assert not calls and np.array_equal(again.atlas, first.atlas)
    matrix = np.array(light.matrix_world, dtype=np.float64)
    matrix[:3, 3] += (0.05, 0.0, 0.0)
    moved = dataclasses.replace(light, matrix_world=matrix)
    pipeline.render(moved, scene, samples, settings)
    assert calls
    gl_backend.release_scene(scene)


def test_a_large_object_is_stored_as_parts_and_shadows_as_one(gl_backend, monkeypatch):
    """Beyond MAX_PART_TRIANGLES an object becomes several textures; it draws, moves and
    goes away as one object."""
    from addon.render import resident

    pipeline, light, tris = ShadowPipeline(gl_backend), _light(), _room()
    samples, settings = _view(tris), ShadowSettings("dpsm", RES)
    one = ResidentScene.of_triangles(tris)
    assert len(one.objects) == 1
    whole = pipeline.render(light, one, samples, settings)
    monkeypatch.setattr(resident, "MAX_PART_TRIANGLES", 64)
    scene = ResidentScene.of_triangles(tris, key="room")
    assert len(scene.objects) == -(-len(tris) // 64) and "room#1" in scene.objects
    parted = pipeline.render(light, scene, samples, settings)
    assert np.array_equal(parted.visibility, whole.visibility)
    scene.set_matrix("room", np.eye(4))
    scene.remove("room")
    assert not scene.objects and {"room", "room#1"} <= scene.removed
    gl_backend.release_scene(scene)


def test_object_matrices_are_checked():
    """A matrix that is not finite and invertible is refused by name, before any upload."""
    from addon.core.errors import InputError

    scene = ResidentScene()
    scene.set_geometry("plate", _room()[:4])
    kept = scene.objects["plate"]
    flat = np.diag([1.0, 1.0, 0.0, 1.0])
    with pytest.raises(InputError, match="invertible"):
        scene.set_geometry("plate", _room()[:8], flat)
    with pytest.raises(InputError, match="finite 4x4"):
        scene.set_matrix("plate", np.full((4, 4), np.nan))
    assert scene.objects == {"plate": kept} and np.array_equal(kept.matrix, np.eye(4))  # nothing lost
