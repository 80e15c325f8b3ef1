"""The stress_* presets (issue 7 item 1): the contract, and the geometric fact each one stresses."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from addon.core import presets as PR
from addon.core import tessellate
from addon.core.scene import CameraSpec, SceneSpec

EXPECTED = {
    "stress_vertex_at_light", "stress_seam", "stress_huge_triangles", "stress_near_far", "stress_scale_small",
    "stress_scale_large", "stress_light_inside_object", "stress_camera_in_occluder", "stress_empty_view",
    "stress_one_texel", "stress_grazing", "stress_negative_scale", "stress_million",
}
STRESS = sorted(p.stem for p in PR.PRESET_DIR.glob("stress_*.py"))
SMALL = [name for name in STRESS if name != "stress_million"]

_cache: dict[str, SceneSpec] = {}


def scene(name: str) -> SceneSpec:
    """Each preset built once at the default 640x480 (the million preset is costly)."""
    if name not in _cache:
        _cache[name] = PR.build_preset(name)
    return _cache[name]


def mesh(spec: SceneSpec, name: str):
    return next(m for m in spec.meshes if m.name == name)


def corner_rays(camera: CameraSpec) -> np.ndarray:
    """Unit world directions (4, 3) of the camera frustum's corner rays."""
    width, height = camera.resolution
    half = math.tan(math.radians(camera.fov_deg) / 2.0)
    hx, hy = (half, half * height / width) if width >= height else (half * width / height, half)
    local = np.array([[sx * hx, sy * hy, -1.0] for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    world = local @ np.asarray(camera.matrix_world)[:3, :3].T
    return world / np.linalg.norm(world, axis=1, keepdims=True)


# ---------------------------------------------------------------- contract


def test_every_case_of_issue_7_has_a_preset():
    assert set(STRESS) == EXPECTED


def test_stress_all_selects_them_and_all_does_not():
    assert sorted(PR.select_presets("stress_all")) == STRESS
    assert not set(PR.select_presets("all")) & set(STRESS)


@pytest.mark.parametrize("name", STRESS)
def test_stress_preset_contract(name):
    """Described, listed as stress, 640x480 by default, one light and a camera, finite geometry."""
    spec = scene(name)
    info = PR.available_presets()[name]
    assert info.is_stress
    assert spec.description.strip() and spec.stresses.strip()
    assert info.description == spec.description and info.stresses == spec.stresses
    assert spec.camera.resolution == (640, 480)
    assert spec.light.emission in ("omni", "hemi") and spec.light.energy > 0.0
    tris = spec.world_triangles()
    assert len(tris) > 0 and np.all(np.isfinite(tris))
    for m in spec.meshes:
        assert np.all(np.isfinite(m.vertices)) and np.all(np.isfinite(m.matrix_world))
    assert np.all(np.isfinite(spec.camera.matrix_world)) and np.all(np.isfinite(spec.light.matrix_world))
    assert 0.0 < spec.camera.clip_start < spec.camera.clip_end


@pytest.mark.parametrize("name", SMALL)
def test_stress_preset_builds_deterministically(name):
    """Two builds are bit-identical (no unseeded randomness)."""
    a, b = PR.build_preset(name), PR.build_preset(name)
    assert np.array_equal(a.world_triangles(), b.world_triangles())
    assert [m.name for m in a.meshes] == [m.name for m in b.meshes]
    assert np.array_equal(a.light.matrix_world, b.light.matrix_world) and a.light.energy == b.light.energy
    assert np.array_equal(a.camera.matrix_world, b.camera.matrix_world)
    assert (a.camera.fov_deg, a.camera.clip_start, a.camera.clip_end) == (b.camera.fov_deg, b.camera.clip_start,
                                                                          b.camera.clip_end)


@pytest.mark.parametrize("name", SMALL)
def test_stress_scenes_are_small(name):
    """Every scene but the million one stays at a few hundred triangles."""
    assert len(scene(name).world_triangles()) < 500


# ---------------------------------------------------------------- per case


def test_vertex_at_light_has_a_vertex_exactly_at_the_light():
    spec = scene("stress_vertex_at_light")
    light = spec.light.position
    tris = spec.world_triangles()
    at_light = np.all(tris == light, axis=2)
    assert at_light.any()
    # Blender stores float32: the vertex must still coincide with the light there.
    assert np.any(np.all(tris.astype(np.float32) == light.astype(np.float32), axis=2))
    # Those triangles are edge-on from the light: sanitising drops exactly them.
    _, report = tessellate.sanitize(tris, light, scale=float(np.abs(tris - light).max()))
    assert report.edge_on == int(np.count_nonzero(at_light.any(axis=1))) == 1
    assert report.nonfinite == 0 and report.degenerate == 0
    # The touching sliver rises behind the light, away from the camera (which is on its -y side).
    sliver = mesh(spec, "sliver").world_triangles().reshape(-1, 3)
    assert np.all(sliver[:, 2] >= light[2]) and np.all(sliver[:, 1] >= light[1])
    assert spec.camera.matrix_world[1, 3] < light[1]


def test_seam_geometry():
    spec = scene("stress_seam")
    light = spec.light.position
    assert np.allclose(spec.light.axis, [0.0, 0.0, -1.0])  # seam plane is z = light z
    tris = spec.world_triangles()
    z = tris[..., 2]
    # Vertices exactly on the seam plane (v_z = 0), also in float32.
    assert np.count_nonzero(z == light[2]) >= 8
    assert np.count_nonzero(z.astype(np.float32) == np.float32(light[2])) >= 8
    # A triangle lying in the seam plane, and triangles only touching it from below and above.
    assert np.any(np.all(z == light[2], axis=1))
    touching = np.any(z == light[2], axis=1) & ~np.all(z == light[2], axis=1)
    assert np.any(touching & np.all(z <= light[2], axis=1)) and np.any(touching & np.all(z >= light[2], axis=1))
    # Vertices exactly on the light's axis above (v_z = -1 for the lower side) and below.
    on_axis = np.all(tris[..., :2] == light[:2], axis=-1)
    assert np.any(on_axis & (z > light[2])) and np.any(on_axis & (z < light[2]))
    # Huge triangles (edges over 5 m) straddling the seam.
    straddle = (z.min(axis=1) < light[2]) & (z.max(axis=1) > light[2])
    edge = np.linalg.norm(tris - np.roll(tris, 1, axis=1), axis=2).max(axis=1)
    assert np.count_nonzero(straddle & (edge > 5.0)) >= 4
    # The camera sits at seam height: the seam crosses the view.
    assert spec.camera.matrix_world[2, 3] == light[2]


def test_huge_triangles():
    spec = scene("stress_huge_triangles")
    light = spec.light.position
    ground = mesh(spec, "ground").world_triangles()
    assert len(ground) == 2
    assert np.ptp(ground[..., 0]) == 10000.0 and np.ptp(ground[..., 1]) == 10000.0
    # The shared diagonal passes exactly under the light.
    shared = [p for p in ground[0] if any(np.array_equal(p, q) for q in ground[1])]
    assert len(shared) == 2
    a, b = shared
    d, e = b[:2] - a[:2], light[:2] - a[:2]
    assert abs(d[0] * e[1] - d[1] * e[0]) < 1e-9
    for name in ("wall_north", "wall_west"):
        wall = mesh(spec, name).world_triangles()
        assert len(wall) == 2
        assert np.all(wall[..., 2].min(axis=1) < light[2]) and np.all(wall[..., 2].max(axis=1) > light[2])
        # Near the light: its plane passes within 2 m.
        n = np.cross(wall[0, 1] - wall[0, 0], wall[0, 2] - wall[0, 0])
        assert abs((light - wall[0, 0]) @ n) / np.linalg.norm(n) < 2.0
        assert np.linalg.norm(wall[0, 1] - wall[0, 0]) >= 4000.0 or np.linalg.norm(wall[0, 2] - wall[0, 1]) >= 4000.0


def test_near_far_ratio():
    """Nearest geometry about 1 mm from the light, farthest over 100 m: ratio < 1e-4 (about 1e-5)."""
    spec = scene("stress_near_far")
    light = spec.light.position
    pts = spec.world_triangles().reshape(-1, 3)
    dist = np.linalg.norm(pts - light, axis=1)
    # The vertex minimum bounds the true minimum from above, so the ratio is conservative.
    assert dist.min() / dist.max() < 1e-4
    assert 0.9e-3 < dist.min() < 1.1e-3 and dist.max() > 100.0
    plate = mesh(spec, "tiny_plate").world_triangles().reshape(-1, 3)
    assert np.abs(plate - light).max() < 1.1e-3 and plate[:, 0].min() - light[0] == pytest.approx(1e-3, abs=1e-9)
    wall = mesh(spec, "far_wall").world_triangles().reshape(-1, 3)
    assert wall[:, 0].min() - light[0] >= 100.0
    # The camera sees the wall's shadow region (the point straight out from the light).
    target = np.array([wall[:, 0].min(), light[1], light[2]])
    cam = spec.camera
    clip = cam.projection() @ np.linalg.inv(cam.matrix_world) @ np.append(target, 1.0)
    assert clip[3] > 0 and np.all(np.abs(clip[:3] / clip[3]) <= 1.0)


@pytest.mark.parametrize("name, scale", [("stress_scale_small", 1e-3), ("stress_scale_large", 1e4)])
def test_scaled_rooms_are_room_omni_scaled(name, scale):
    spec, base = scene(name), PR.build_preset("room_omni")
    assert np.allclose(spec.world_triangles(), base.world_triangles() * scale, rtol=1e-12, atol=0.0)
    assert np.allclose(spec.light.position, base.light.position * scale, rtol=1e-12)
    assert spec.light.energy == pytest.approx(base.light.energy * scale ** 2)
    assert np.allclose(spec.camera.matrix_world[:3, 3], base.camera.matrix_world[:3, 3] * scale, rtol=1e-12)
    assert np.allclose(spec.camera.matrix_world[:3, :3], base.camera.matrix_world[:3, :3])
    assert spec.camera.fov_deg == base.camera.fov_deg
    assert spec.camera.clip_start == pytest.approx(base.camera.clip_start * scale)
    assert spec.camera.clip_end == pytest.approx(base.camera.clip_end * scale)


def _edge_uses(tris: np.ndarray) -> dict[tuple[int, int], int]:
    uses: dict[tuple[int, int], int] = {}
    for t in tris:
        for k in range(3):
            key = tuple(sorted((int(t[k]), int(t[(k + 1) % 3]))))
            uses[key] = uses.get(key, 0) + 1
    return uses


def test_light_inside_object():
    spec = scene("stress_light_inside_object")
    lantern = mesh(spec, "lantern")
    local_light = (np.linalg.inv(lantern.matrix_world) @ np.append(spec.light.position, 1.0))[:3]
    lo, hi = lantern.vertices.min(axis=0), lantern.vertices.max(axis=0)
    assert np.all(local_light > lo) and np.all(local_light < hi)
    # Closed but for the window: every edge is shared by two triangles except the window's four.
    uses = _edge_uses(lantern.triangles)
    open_edges = sorted(e for e, n in uses.items() if n == 1)
    assert all(n in (1, 2) for n in uses.values())
    assert open_edges == [(8, 9), (8, 11), (9, 10), (10, 11)]
    window = lantern.vertices[8:12]
    assert np.all(window[:, 2] == lo[2])  # in the bottom face
    # Outward winding: the signed volume is positive.
    v = lantern.vertices[lantern.triangles]
    assert np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() > 0.0


def test_camera_in_occluder():
    spec = scene("stress_camera_in_occluder")
    hood = mesh(spec, "hood").world_triangles().reshape(-1, 3)
    lo, hi = hood.min(axis=0), hood.max(axis=0)
    cam = spec.camera.matrix_world[:3, 3]
    assert np.all(cam > lo) and np.all(cam < hi)
    # Open only toward +y, and the camera looks out through that side.
    uses = _edge_uses(mesh(spec, "hood").triangles)
    open_verts = mesh(spec, "hood").vertices[sorted({v for e, n in uses.items() if n == 1 for v in e})]
    assert np.all(open_verts[:, 1] == hi[1])
    assert np.all(corner_rays(spec.camera)[:, 1] > 0.0)


def test_empty_view_sees_no_geometry():
    """All geometry lies below the camera and every frustum ray climbs: no triangle can be in view."""
    spec = scene("stress_empty_view")
    cam = spec.camera.matrix_world[:3, 3]
    rays = corner_rays(spec.camera)
    # The frustum is the cone of its corner rays; each climbs, so the whole cone lies above z = cam z.
    assert np.all(rays[:, 2] > 0.1)
    assert spec.world_triangles()[..., 2].max() < cam[2]
    # And no vertex projects inside the clip volume.
    pts = spec.world_triangles().reshape(-1, 3)
    clip = (spec.camera.projection() @ np.linalg.inv(spec.camera.matrix_world)
            @ np.concatenate([pts, np.ones((len(pts), 1))], axis=1).T).T
    inside = (clip[:, 3] > 0) & np.all(np.abs(clip[:, :3]) <= clip[:, 3:4], axis=1)
    assert not inside.any()


def _ray_hits_box(origin, direction, lo, hi) -> bool:
    with np.errstate(divide="ignore"):
        t1, t2 = (lo - origin) / direction, (hi - origin) / direction
    t_near, t_far = np.minimum(t1, t2).max(), np.maximum(t1, t2).min()
    return bool(t_far >= max(t_near, 0.0))


def test_one_texel():
    spec = scene("stress_one_texel")
    light, cam = spec.light.position, spec.camera
    cube = mesh(spec, "tiny_cube").world_triangles().reshape(-1, 3)
    lo, hi = cube.min(axis=0), cube.max(axis=0)
    assert np.all(hi - lo <= 0.0101) and np.linalg.norm(lo - light) > 90.0
    origin = cam.matrix_world[:3, 3]
    rays = corner_rays(cam)
    # The tiny cube fills the view: every corner ray hits it.
    assert all(_ray_hits_box(origin, r, lo, hi) for r in rays)
    # The footprint on the lit face (x = lo.x) seen from the light spans under half a texel even
    # at the largest map resolution (a texel spans >= 2/4096 rad / sqrt(3) on any layer).
    foot = origin + rays * ((lo[0] - origin[0]) / rays[:, 0])[:, None]
    dirs = (foot - light) / np.linalg.norm(foot - light, axis=1, keepdims=True)
    spread = max(math.acos(min(1.0, float(a @ b))) for a in dirs for b in dirs)
    assert spread < 0.5 * (2.0 / 4096) / math.sqrt(3.0)
    # The pole's shadow edge on that face crosses the footprint.
    pole = mesh(spec, "pole").world_triangles().reshape(-1, 3)
    slope = ((pole[:, 1] - light[1]) / (pole[:, 0] - light[0])).max()
    y_edge = light[1] + slope * (lo[0] - light[0])
    assert foot[:, 1].min() < y_edge < foot[:, 1].max()


def test_grazing_receivers():
    spec = scene("stress_grazing")
    light = spec.light.position
    floor = mesh(spec, "floor").world_triangles().reshape(-1, 3)
    assert np.all(floor[:, 2] == 0.0) and light[2] == pytest.approx(0.02)
    xs = np.linspace(floor[:, 0].min(), floor[:, 0].max(), 201)
    ys = np.linspace(floor[:, 1].min(), floor[:, 1].max(), 61)
    gx, gy = np.meshgrid(xs, ys)
    horizontal = np.hypot(gx - light[0], gy - light[1])
    incidence = np.degrees(np.arctan2(horizontal, light[2]))  # angle to the floor's normal
    assert np.mean(incidence > 89.0) > 0.95
    assert np.degrees(math.atan2(38.0, 0.02)) > 89.9
    occluders = [m for m in spec.meshes if m.name != "floor"]
    assert occluders and all(m.world_triangles()[..., 2].max() <= 0.3 for m in occluders)


def test_negative_scale():
    spec = scene("stress_negative_scale")
    dets = {m.name: float(np.linalg.det(np.asarray(m.matrix_world)[:3, :3])) for m in spec.meshes}
    negative = [n for n, d in dets.items() if d < 0.0]
    assert len(negative) >= 4 and "floor_mirrored" in negative and dets["prism_plain"] > 0.0
    # Mirroring reverses the winding: the mirrored floor's winding normal points down, away from the light.
    floor = mesh(spec, "floor_mirrored").world_triangles()
    normal = np.cross(floor[:, 1] - floor[:, 0], floor[:, 2] - floor[:, 0])
    assert np.all(normal[:, 2] < 0.0)
    # The mirrored prism's world geometry is the plain prism's mirror image (up to placement).
    plain, mirrored = mesh(spec, "prism_plain"), mesh(spec, "prism_mirror_x")
    assert np.array_equal(plain.vertices, mirrored.vertices) and np.array_equal(plain.triangles, mirrored.triangles)
    a = plain.world_triangles() - plain.matrix_world[:3, 3]
    b = mirrored.world_triangles() - mirrored.matrix_world[:3, 3]
    assert np.allclose(a * np.array([-1.0, 1.0, 1.0]), b)
    # Signed volume of a mirrored closed prism is negative.
    vol = np.einsum("ij,ij->i", b[:, 0], np.cross(b[:, 1], b[:, 2])).sum()
    assert vol < 0.0


def test_million_triangles_fast():
    start = time.perf_counter()
    spec = PR.build_preset("stress_million")
    seconds = time.perf_counter() - start
    assert seconds < 3.0
    terrain = mesh(spec, "terrain")
    assert len(terrain.triangles) == 2 * 708 * 708 == 1_002_528
    assert sum(len(m.triangles) for m in spec.meshes) >= 1_000_000
    assert terrain.triangles.min() == 0 and terrain.triangles.max() == len(terrain.vertices) - 1
    assert np.all(np.isfinite(terrain.vertices))
    # Deterministic: the same terrain on a second build.
    again = mesh(PR.build_preset("stress_million"), "terrain")
    assert np.array_equal(terrain.vertices, again.vertices) and np.array_equal(terrain.triangles, again.triangles)
    # The light is above all of the terrain.
    assert spec.light.position[2] > terrain.vertices[:, 2].max() + 2.0
