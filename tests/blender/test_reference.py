"""The Cycles reference (addon.reference): capture, conventions and cache.

Tiny scenes (64x48, one sample) keep this fast: each capture is two Cycles renders
of well under a second. Expected values come from independent numpy ray casting
against the SceneSpec, not from Blender.
"""
from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from addon.core import metrics  # noqa: E402
from addon.core.errors import InputError, ReferenceCaptureError  # noqa: E402
from addon.core.scene import LightSpec, SceneBuilder, SceneSpec  # noqa: E402
from addon.reference import cache  # noqa: E402
from addon.reference.blender_scene import build_blender_scene, remove_blender_scene  # noqa: E402
from addon.reference.capture import capture  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from tests.support.cli_run import env_with, python_ok  # noqa: E402
from tests.support.oracle import camera_rays, ray_hits  # noqa: E402

pytestmark = pytest.mark.blender

REPO_ROOT = Path(__file__).resolve().parents[2]
SIZE = (64, 48)
BOX_CENTER, BOX_SIZE = np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 1.0])
LIGHT = np.array([0.5, 0.3, 4.0])


# ----------------------------------------------------------------------------
# helpers: independent geometry
# ----------------------------------------------------------------------------
def floor_box_scene(name: str = "tiny", size=SIZE, camera=((0.0, -7.0, 5.0), (0.0, 0.0, 0.0))) -> SceneSpec:
    b = SceneBuilder(name, size)
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    b.box("box", BOX_CENTER, BOX_SIZE)
    b.point_light(LIGHT)
    b.camera(camera[0], camera[1], fov_deg=60.0)
    return b.finish()


def render(spec: SceneSpec, samples: int = 1) -> ReferenceData:
    scene = build_blender_scene(spec)
    try:
        return capture(scene, samples=samples)
    finally:
        remove_blender_scene(scene)


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise 2D hull (Andrew's monotone chain)."""
    pts = sorted(map(tuple, points))

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def signed_distance_inside(hull: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Distance of points to the hull border, positive inside (CCW hull)."""
    dist = np.full(len(xy), np.inf)
    for a, b in zip(hull, np.roll(hull, -1, axis=0)):
        edge = b - a
        normal = np.array([-edge[1], edge[0]]) / np.linalg.norm(edge)  # points inside for CCW
        dist = np.minimum(dist, (xy - a) @ normal)
    return dist


def box_corners() -> np.ndarray:
    half = BOX_SIZE / 2.0
    return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half + BOX_CENTER


def shadow_footprint(light: np.ndarray) -> np.ndarray:
    """Hull of the box's corners projected from the light onto z = 0."""
    corners = box_corners()
    t = light[2] / (light[2] - corners[:, 2])
    projected = light[:2] + (corners[:, :2] - light[:2]) * t[:, None]
    return convex_hull(np.vstack([projected, corners[:, :2]]))


def sun_footprint(direction: np.ndarray) -> np.ndarray:
    """Hull of the box's corners projected along a sun's direction onto z = 0 (the box
    floats 0.5 m up, so its own footprint is lit from the side and not part of it)."""
    corners = box_corners()
    projected = corners[:, :2] - direction[:2] * (corners[:, 2] / direction[2])[:, None]
    return convex_hull(projected)


def light_spec_of(ref: ReferenceData) -> LightSpec:
    """The LightSpec a reference describes (spot_size only matters for a spot)."""
    return LightSpec(ref.emission, ref.light_matrix, spot_size=ref.spot_size)  # type: ignore[arg-type]


def floor_mask(ref: ReferenceData) -> np.ndarray:
    return ref.hit & (np.abs(ref.position[..., 2]) < 1e-4)


# ----------------------------------------------------------------------------
# fixtures
# ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def omni() -> tuple[SceneSpec, ReferenceData]:
    spec = floor_box_scene()
    return spec, render(spec)


@pytest.fixture(scope="module")
def oracle(omni) -> dict[str, np.ndarray]:
    """Independent ray cast of every pixel against the spec's triangles."""
    spec, _ = omni
    origins, dirs = camera_rays(spec.camera)
    t, _ = ray_hits(origins, dirs, spec.world_triangles())
    hit = np.isfinite(t)
    position = np.where(hit[:, None], origins + dirs * np.where(hit, t, 0.0)[:, None], 0.0)
    shape = spec.camera.resolution[::-1]
    return {"hit": hit.reshape(shape), "position": position.reshape(*shape, 3)}


# ----------------------------------------------------------------------------
# capture
# ----------------------------------------------------------------------------
def test_shapes_and_dtypes(omni):
    spec, ref = omni
    w, h = SIZE
    assert ref.resolution == (w, h)
    assert ref.position.shape == (h, w, 3) and ref.position.dtype == np.float32
    assert ref.normal.shape == (h, w, 3) and ref.normal.dtype == np.float32
    assert ref.hit.shape == (h, w) and ref.hit.dtype == bool
    for name in ("shadowed", "unshadowed"):
        arr = getattr(ref, name)
        assert arr.shape == (h, w) and arr.dtype == np.float32
        assert np.all(np.isfinite(arr))
    assert ref.triangles.dtype == np.float32 and ref.triangles.shape[1:] == (3, 3)
    assert ref.light_matrix.shape == (4, 4) and ref.light_matrix.dtype == np.float64
    assert ref.camera_matrix.shape == (4, 4) and ref.camera_matrix.dtype == np.float64
    assert ref.emission == "omni"
    assert ref.camera_fov_deg == pytest.approx(60.0, abs=1e-4)
    np.testing.assert_allclose(ref.camera_matrix, spec.camera.matrix_world, atol=1e-5)
    np.testing.assert_allclose(ref.light_matrix, spec.light.matrix_world, atol=1e-5)
    assert ref.meta["samples"] == 1 and ref.meta["blender_version"] == bpy.app.version_string
    assert set(ref.meta["render_seconds"]) == {"shadowed", "unshadowed"}
    assert ref.visibility().shape == (h, w) and ref.visibility().dtype == bool


def test_hit_mask_matches_ray_cast(omni, oracle):
    _, ref = omni
    assert not ref.hit[0].any(), "top row looks at the sky"
    assert ref.hit[-1].all(), "bottom row looks at the floor"
    # Only pixels whose centre ray grazes the floor's far edge may disagree.
    assert np.count_nonzero(ref.hit != oracle["hit"]) <= 2
    assert np.all(ref.position[~ref.hit] == 0.0) and np.all(ref.normal[~ref.hit] == 0.0)


def test_positions_lie_on_the_geometry(omni, oracle):
    """Position = the pixel centre's first hit: this also fixes the row order (row 0 = top)."""
    _, ref = omni
    both = ref.hit & oracle["hit"]
    err = np.linalg.norm(ref.position[both] - oracle["position"][both], axis=-1)
    assert np.percentile(err, 99) < 1e-3
    floor = both & (oracle["position"][..., 2] < 1e-6)
    assert floor.sum() > 1000
    assert np.abs(ref.position[floor][:, 2]).max() < 1e-4
    # Flipping rows would put far floor points at the bottom: check the trend directly.
    assert ref.position[-1, 32, 1] < ref.position[20, 32, 1]


def test_row_order_by_projecting_a_known_point(omni):
    """The pixel where the box's top centre projects holds that position."""
    spec, ref = omni
    point = BOX_CENTER + np.array([0.0, 0.0, BOX_SIZE[2] / 2.0])
    clip = spec.camera.projection() @ np.linalg.inv(ref.camera_matrix) @ np.append(point, 1.0)
    ndc = clip[:2] / clip[3]
    w, h = ref.resolution
    col = int((ndc[0] * 0.5 + 0.5) * w)
    row = int((0.5 - ndc[1] * 0.5) * h)  # image rows run downwards
    assert ref.hit[row, col]
    assert np.linalg.norm(ref.position[row, col] - point) < 0.15  # within one pixel's footprint
    assert ref.position[h - 1 - row, col, 2] < 1e-4, "the mirrored row is floor, not the box top"


def test_normals_are_unit_geometric_and_face_the_camera(omni, oracle):
    _, ref = omni
    n = ref.normal[ref.hit]
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)
    floor = ref.hit & (np.abs(ref.position[..., 2]) < 1e-4)
    np.testing.assert_allclose(ref.normal[floor], np.broadcast_to([0, 0, 1], ref.normal[floor].shape), atol=1e-5)
    to_camera = ref.camera_position - ref.position[ref.hit]
    assert np.all(np.einsum("ij,ij->i", n, to_camera) > 0)
    # Box faces give axis-aligned normals (flat, geometric: not smoothed at corners).
    box = ref.hit & (ref.position[..., 2] > 0.5 + 1e-3)
    assert box.sum() > 20
    assert np.all(np.abs(ref.normal[box]).max(axis=-1) > 1 - 1e-5)


def test_backface_normal_is_flipped_towards_the_camera():
    """Seen from below, the +Z floor reports True Normal -Z: Cycles faces it to the ray."""
    b = SceneBuilder("below", (16, 12))
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    b.point_light((0.0, 0.0, -3.0))
    b.camera((0.0, -3.0, -4.0), (0.0, 0.0, 0.0), fov_deg=60.0)
    ref = render(b.finish())
    assert ref.hit.all()
    np.testing.assert_allclose(ref.normal[ref.hit], np.broadcast_to([0, 0, -1], ref.normal[ref.hit].shape), atol=1e-5)
    assert (ref.unshadowed[ref.hit] > 0).all(), "the light below lights the back face"


def test_unshadowed_is_hard_unoccluded_light(omni):
    """Unshadowed follows cos/r^2 exactly (hard light, no occlusion); shadowed <= unshadowed."""
    _, ref = omni
    assert np.all(ref.unshadowed >= ref.shadowed - 1e-6)
    floor = ref.hit & (np.abs(ref.position[..., 2]) < 1e-4)
    d = LIGHT - ref.position[floor].astype(np.float64)
    r2 = (d**2).sum(-1)
    law = ref.unshadowed[floor] / (d[:, 2] / np.sqrt(r2) / r2)
    assert law.std() / law.mean() < 1e-3
    # With one sample the shadow test is binary: shadowed is 0 or the unshadowed value.
    ratio = ref.shadowed[floor] / ref.unshadowed[floor]
    assert np.all((ratio < 1e-4) | (ratio > 1 - 1e-4))


def test_box_shadow_inside_analytic_footprint(omni):
    _, ref = omni
    vis = ref.visibility()
    floor = ref.hit & (np.abs(ref.position[..., 2]) < 1e-4)
    assert np.all(ref.lit_domain()[floor]), "the whole floor faces the light"
    dark = floor & ~vis
    assert dark.sum() >= 10, "the box casts a visible shadow"
    hull = shadow_footprint(LIGHT)
    inside = signed_distance_inside(hull, ref.position[..., :2].reshape(-1, 2).astype(np.float64)).reshape(vis.shape)
    assert np.all(inside[dark] > -1e-3), "shadowed floor pixels lie in the footprint"
    assert np.all(vis[floor & (inside < -0.05)]), "floor well outside the footprint is lit"
    assert not np.any(vis[floor & (inside > 0.05)]), "floor well inside the footprint is dark"


def test_triangles_are_the_scene(omni):
    spec, ref = omni
    expected = spec.world_triangles()
    assert ref.triangles.shape == expected.shape

    def canonical(tris):  # order-free comparison: sort corners, then triangles
        t = np.round(np.asarray(tris, dtype=np.float64), 4)
        t = np.array([sorted(map(tuple, tri)) for tri in t])
        return t[np.lexsort(t.reshape(len(t), -1).T[::-1])]

    np.testing.assert_allclose(canonical(ref.triangles), canonical(expected), atol=1e-4)


def test_hemi_light_leaves_the_back_half_space_dark():
    b = SceneBuilder("hemi", SIZE)
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    b.hemi_light((0.0, 0.0, 1.0), (1.0, 0.0, 1.0))  # axis +X: the x < 0 half is behind it
    b.camera((0.0, -7.0, 5.0), (0.0, 0.0, 0.0), fov_deg=60.0)
    spec = b.finish()
    ref = render(spec)
    assert ref.emission == "hemi"
    x = ref.position[..., 0]
    behind, front = ref.hit & (x < -0.05), ref.hit & (x > 0.05)
    assert behind.sum() > 100 and front.sum() > 100
    assert np.all(ref.unshadowed[behind] == 0.0)
    assert np.all(ref.unshadowed[front] > 0.0)
    assert not ref.lit_domain()[behind].any()
    np.testing.assert_allclose(ref.light_matrix, spec.light.matrix_world, atol=1e-5)


# ----------------------------------------------------------------------------
# spot and sun lights
# ----------------------------------------------------------------------------
SUN_DIRECTION = np.array([0.5, -1.0, -1.2]) / np.linalg.norm([0.5, -1.0, -1.2])  # towards the camera
SPOT_APEX, SPOT_DEG = np.array([0.0, 0.0, 4.0]), 50.0


def sun_scene(name: str = "sun") -> SceneSpec:
    b = SceneBuilder(name, SIZE)
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    b.box("box", BOX_CENTER, BOX_SIZE)
    b.sun_light(SUN_DIRECTION, strength=3.0, origin=(-3.0, 2.0, 6.0))
    b.camera((0.0, -7.0, 5.0), (0.0, 0.0, 0.0), fov_deg=60.0)
    return b.finish()


def spot_scene(name: str = "spot") -> SceneSpec:
    b = SceneBuilder(name, SIZE)
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    b.box("box", BOX_CENTER, BOX_SIZE)
    b.spot_light(SPOT_APEX, (0.0, 0.0, 0.0), spot_size_deg=SPOT_DEG, energy=500.0)
    b.camera((0.0, -7.0, 5.0), (0.0, 0.0, 0.0), fov_deg=60.0)
    return b.finish()


@pytest.fixture(scope="module")
def sun() -> tuple[SceneSpec, ReferenceData]:
    spec = sun_scene()
    return spec, render(spec)


@pytest.fixture(scope="module")
def spot() -> tuple[SceneSpec, ReferenceData]:
    spec = spot_scene()
    return spec, render(spec)


def test_sun_reference_captures_emission_sun_and_finite_data(sun):
    """A SUN is captured as emission "sun": finite passes, its direction in the light matrix,
    spot_size pi, the same light on every floor pixel (no falloff) and the box's shadow
    where the parallel projection of its corners puts it."""
    spec, ref = sun
    assert ref.emission == "sun" and ref.spot_size == math.pi
    for name in ("position", "normal", "shadowed", "unshadowed"):
        assert np.all(np.isfinite(getattr(ref, name))), name
    np.testing.assert_allclose(ref.light_matrix, spec.light.matrix_world, atol=1e-5)
    np.testing.assert_allclose(light_spec_of(ref).axis, SUN_DIRECTION, atol=1e-6)
    assert ref.meta["sun_angle_deg"] == 0.0 and ref.meta["light_energy"] == pytest.approx(3.0)
    floor = floor_mask(ref)
    assert floor.sum() > 1000 and np.all(ref.unshadowed[floor] > 0.0)
    assert ref.unshadowed[floor].std() / ref.unshadowed[floor].mean() < 1e-3
    vis = ref.visibility()
    hull = sun_footprint(SUN_DIRECTION)
    inside = signed_distance_inside(hull, ref.position[..., :2].reshape(-1, 2).astype(np.float64)).reshape(vis.shape)
    dark = floor & ~vis
    assert dark.sum() >= 10
    assert np.all(inside[dark] > -1e-3), "shadowed floor pixels lie in the footprint"
    assert np.all(vis[floor & (inside < -0.05)]) and not np.any(vis[floor & (inside > 0.05)])
    # Every floor pixel faces the sun, and the evaluable mask agrees with the lit domain.
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light_spec_of(ref))
    assert np.all(evaluable[floor])
    assert np.array_equal(evaluable, ref.lit_domain() & evaluable)


def test_sun_faces_turned_away_get_no_light(sun):
    """Box faces whose normal points along the sun's travel are dark and never evaluable."""
    _, ref = sun
    away = ref.hit & (np.einsum("...i,i->...", ref.normal, SUN_DIRECTION) > 0.05)
    assert away.sum() > 5
    assert np.all(ref.unshadowed[away] == 0.0)
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light_spec_of(ref))
    assert not evaluable[away].any()


def test_spot_reference_stores_emission_and_cone(spot, tmp_path):
    """A SPOT narrower than 179 degrees is emission "spot" with its cone in spot_size
    (radians, Blender's float32), also in meta, and both survive save/load."""
    spec, ref = spot
    assert ref.emission == "spot"
    assert ref.spot_size == pytest.approx(math.radians(SPOT_DEG), abs=1e-6)
    assert ref.meta["spot_size_deg"] == pytest.approx(SPOT_DEG, abs=1e-4) and ref.meta["spot_blend"] == 0.0
    np.testing.assert_allclose(ref.light_matrix, spec.light.matrix_world, atol=1e-5)
    back = ReferenceData.load(ref.save(tmp_path / "spot.npz"))
    assert back.emission == "spot" and back.spot_size == ref.spot_size


def test_pixels_outside_the_spot_cone_are_not_evaluable(spot):
    """Floor outside the cone gets no light and is not evaluable; inside (away from the rim)
    it is lit and evaluable; the mask never counts a pixel Cycles left unlit."""
    _, ref = spot
    light = light_spec_of(ref)
    d = ref.position.astype(np.float64) - SPOT_APEX
    angle = np.degrees(np.arccos(np.clip((d @ light.axis) / np.linalg.norm(d, axis=-1), -1.0, 1.0)))
    floor = floor_mask(ref)
    outside, inside = floor & (angle > SPOT_DEG / 2 + 0.5), floor & (angle < SPOT_DEG / 2 - 0.5)
    assert outside.sum() > 300 and inside.sum() > 100
    assert np.all(ref.unshadowed[outside] == 0.0) and np.all(ref.unshadowed[inside] > 0.0)
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
    assert not evaluable[outside].any() and evaluable[inside].all()
    assert not (evaluable & ~ref.lit_domain()).any()
    # The cone test alone excludes the outside too, even where light leaked (unshadowed > 0).
    leaked = np.where(ref.hit, 1.0, 0.0)
    assert not metrics.evaluable_mask(ref.position, ref.normal, ref.hit, leaked, light)[outside].any()
    # The box under the light still casts its shadow inside the cone.
    assert (inside & ~ref.visibility()).sum() >= 10


def test_soft_sun_keeps_its_angle_unless_hard(sun):
    """A sun with a non-zero angle renders soft, as the artist renders it (issue 27): a
    penumbra, its noise measured; `hard` renders it as angle 0 (the same visibility) and
    either way the file's angle is put back."""
    _, hard = sun
    scene = build_blender_scene(sun_scene("soft_sun"))
    try:
        light = next(o for o in scene.objects if o.type == "LIGHT")
        light.data.angle = math.radians(10.0)
        soft = capture(scene, soft_samples=16)
        assert light.data.angle == pytest.approx(math.radians(10.0))
        made_hard = capture(scene, hard=True)
        assert light.data.angle == pytest.approx(math.radians(10.0))
    finally:
        remove_blender_scene(scene)
    assert soft.emission == "sun" and soft.meta["sun_angle_deg"] == pytest.approx(10.0, abs=1e-4)
    assert soft.light_shape().sized and soft.visibility_noise is not None
    ratio = metrics.reference_ratio(soft.shadowed, soft.unshadowed)[soft.lit_domain()]
    assert np.count_nonzero((ratio > 0.05) & (ratio < 0.95)) > 0
    assert not made_hard.light_shape().sized and made_hard.visibility_noise is None
    assert np.array_equal(made_hard.visibility(), hard.visibility())


def test_blended_spot_is_captured_with_a_warning(spot, caplog):
    """A spot with blend > 0 is not refused: the capture warns that its cone edge is soft;
    it stays a spot, and visibility (a ratio) matches the hard cone's wherever both are lit."""
    _, hard = spot
    scene = build_blender_scene(spot_scene("blended_spot"))
    try:
        light = next(o for o in scene.objects if o.type == "LIGHT")
        light.data.spot_blend = 0.4
        with caplog.at_level(logging.WARNING, logger="addon.reference.capture"):
            ref = capture(scene, samples=1)
    finally:
        remove_blender_scene(scene)
    assert any("blend" in r.getMessage() and "soft" in r.getMessage() for r in caplog.records)
    assert ref.emission == "spot" and ref.meta["spot_blend"] == pytest.approx(0.4)
    both = ref.lit_domain() & hard.lit_domain()
    assert both.sum() > 100
    assert np.array_equal(ref.visibility()[both], hard.visibility()[both])


def test_named_sun_is_picked_among_several_lights():
    """With a point light and a sun in the scene, naming the sun captures the sun."""
    scene = build_blender_scene(sun_scene("two_lights"))
    extra = bpy.data.objects.new("extra_point", bpy.data.lights.new("extra_point", "POINT"))
    scene.collection.objects.link(extra)
    try:
        with pytest.raises(ReferenceCaptureError, match="several"):
            capture(scene)
        sun_obj = next(o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN")
        ref = capture(scene, light=sun_obj.name)
        assert ref.emission == "sun"
    finally:
        remove_blender_scene(scene)
        light_data = extra.data
        bpy.data.objects.remove(extra)
        bpy.data.lights.remove(light_data)


def test_a_light_disabled_in_the_viewport_gets_the_matrix_cycles_renders_with():
    """A sun disabled in the viewport but rendered (issue 53's old file): the viewport
    depsgraph never evaluates it, so its matrix_world stays as made (the identity, a sun
    straight down); the reference takes the render's matrix, its rotation."""
    from mathutils import Euler

    scene = build_blender_scene(sun_scene("hidden_sun"))
    old = next(o for o in scene.objects if o.type == "LIGHT")
    old.hide_render = True
    hidden = bpy.data.objects.new("hidden_sun", bpy.data.lights.new("hidden_sun", "SUN"))
    hidden.data.energy = 3.0
    hidden.data.angle = 0.0
    hidden.rotation_euler = (0.5, 0.2, 0.3)
    hidden.hide_viewport = True
    scene.collection.objects.link(hidden)
    try:
        assert np.allclose(np.array(hidden.matrix_world), np.eye(4))  # what the viewport has
        ref = capture(scene, light=hidden.name)
        rotation = np.array(Euler((0.5, 0.2, 0.3)).to_matrix())
        np.testing.assert_allclose(ref.light_matrix[:3, :3], rotation, atol=1e-5)
        np.testing.assert_allclose(light_spec_of(ref).axis, rotation @ np.array([0.0, 0.0, -1.0]), atol=1e-5)
    finally:
        remove_blender_scene(scene)
        light_data = hidden.data
        bpy.data.objects.remove(hidden)
        bpy.data.lights.remove(light_data)


@pytest.mark.parametrize(("kind", "size_deg", "blend", "expected"), [
    ("POINT", None, 0.0, "omni"),
    ("SUN", None, 0.0, "sun"),
    ("SPOT", 45.0, 0.0, "spot"),
    ("SPOT", 178.9, 0.0, "spot"),
    ("SPOT", 179.0, 0.0, "hemi"),  # the rule the UI shares (core.scene.spot_emission)
    ("SPOT", 179.5, 0.0, "hemi"),
    ("SPOT", 180.0, 0.0, "hemi"),
    ("SPOT", 180.0, 0.3, "hemi"),  # a blend fades the light but keeps the half space
    ("SPOT", 60.0, 0.3, "spot"),
])
def test_emission_of_blender_lights(kind, size_deg, blend, expected):
    from addon.reference.capture import emission_of

    light = bpy.data.lights.new("emission_probe", kind)
    try:
        if size_deg is not None:
            light.spot_size = math.radians(size_deg)
            light.spot_blend = blend
        assert emission_of(light) == expected
    finally:
        bpy.data.lights.remove(light)


def test_spot_cone_below_blenders_minimum_is_refused():
    """Blender clamps spot_size to 1 degree; building a narrower spot is an InputError."""
    b = SceneBuilder("needle", (16, 12))
    b.plane("floor", (0.0, 0.0, 0.0), 4.0, 4.0)
    b.spot_light((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), spot_size_deg=0.5)
    b.camera((0.0, -3.0, 3.0), (0.0, 0.0, 0.0))
    scenes = len(bpy.data.scenes)
    with pytest.raises(InputError, match="spot cone 0.5 degrees"):
        build_blender_scene(b.finish())
    assert len(bpy.data.scenes) == scenes, "nothing is created before the check"


def test_eevee_row_takes_every_light_type(spot, sun, tmp_path):
    """The eevee row (the anchor of every comparison) fits point, hemi, spot and sun lights:
    the method registry offers it for each, the row's note names what EEVEE shadows a spot
    and a sun with, and a reference of an emission it has no structure for is refused
    before any EEVEE process starts."""
    import dataclasses

    from addon.core import methods
    from addon.reference import eevee, eevee_rows

    for emission in ("omni", "hemi", "spot", "sun"):
        assert methods.fits("eevee", emission) and emission in eevee.TILEMAPS
    assert "per hemi or spot" in eevee.ROW_NOTE and "per sun" in eevee.ROW_NOTE
    _, ref = spot
    odd = dataclasses.replace(ref, emission="laser")
    with pytest.raises(InputError, match="'laser'"):
        eevee_rows.eevee_rows(["--preset", "none"], odd, "label", tmp_path, None)
    assert not (tmp_path / "eevee").exists()


def test_capture_restores_the_scene_and_leaves_no_datablocks():
    spec = floor_box_scene("restore")
    counts = {k: len(getattr(bpy.data, k)) for k in ("scenes", "objects", "meshes", "lights", "cameras",
                                                      "materials", "worlds", "images")}
    default_scene = bpy.data.scenes[0]
    default_engine = default_scene.render.engine
    scene = build_blender_scene(spec)
    layer = scene.view_layers[0]
    light = next(o for o in scene.objects if o.type == "LIGHT")
    light.data.shadow_soft_size = 0.25  # a user's soft light: captured hard, then restored
    scene.render.film_transparent = False
    before = (scene.render.engine, scene.render.filepath, scene.render.image_settings.file_format,
              scene.cycles.samples, scene.cycles.max_bounces, scene.world, layer.material_override,
              len(layer.aovs), layer.use_pass_position, light.data.use_shadow)
    try:
        capture(scene, samples=1)
        after = (scene.render.engine, scene.render.filepath, scene.render.image_settings.file_format,
                 scene.cycles.samples, scene.cycles.max_bounces, scene.world, layer.material_override,
                 len(layer.aovs), layer.use_pass_position, light.data.use_shadow)
        assert after == before
        assert light.data.shadow_soft_size == pytest.approx(0.25)
        assert scene.render.film_transparent is False
    finally:
        remove_blender_scene(scene)
    assert default_scene.render.engine == default_engine
    after_counts = {k: len(getattr(bpy.data, k)) for k in counts}
    # The Render Result image may appear once per process; everything else must balance.
    after_counts["images"] = counts["images"] = min(counts["images"], after_counts["images"])
    assert after_counts == counts


def test_capture_errors_are_named():
    scene = bpy.data.scenes.new("no camera")
    try:
        with pytest.raises(ReferenceCaptureError, match="camera"):
            capture(scene)
    finally:
        bpy.data.scenes.remove(scene)
    b = SceneBuilder("nolight", (16, 12))
    b.plane("floor", (0.0, 0.0, 0.0), 4.0, 4.0)
    b.point_light((0.0, 0.0, 2.0))
    b.camera((0.0, -3.0, 3.0), (0.0, 0.0, 0.0))
    scene = build_blender_scene(b.finish())
    try:
        floor = next(o for o in scene.objects if o.type == "MESH")
        with pytest.raises(ReferenceCaptureError, match="spot, sun or area light"):
            capture(scene, light=floor.name)  # a mesh named as the light
    finally:
        remove_blender_scene(scene)


# ----------------------------------------------------------------------------
# data and cache
# ----------------------------------------------------------------------------
def test_save_load_round_trip(omni, tmp_path):
    _, ref = omni
    path = ref.save(tmp_path / "ref.npz")
    back = ReferenceData.load(path)
    for name in ("position", "normal", "hit", "shadowed", "unshadowed", "triangles", "light_matrix", "camera_matrix"):
        a, b = getattr(ref, name), getattr(back, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name
    assert back.emission == ref.emission and back.resolution == ref.resolution
    assert back.camera_fov_deg == ref.camera_fov_deg
    assert back.meta["render_seconds"] == ref.meta["render_seconds"]
    assert np.array_equal(back.visibility(), ref.visibility())


def test_old_file_without_spot_size_loads_with_pi(omni, spot, tmp_path):
    """Files written before the spot_size field load with pi; an old spot file falls back
    to the cone its meta recorded. No format bump: both are still format 1."""
    for (_, ref), expected in ((omni, math.pi), (spot, spot[1].spot_size)):
        path = ref.save(tmp_path / f"{ref.emission}.npz")
        with np.load(path, allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files if k != "spot_size"}
        old = tmp_path / f"old_{ref.emission}.npz"
        with open(old, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        back = ReferenceData.load(old)
        assert back.spot_size == pytest.approx(expected, abs=1e-6)
    meta = json.loads(str(arrays["meta"]))
    meta.pop("spot_size_deg")
    arrays["meta"] = np.array(json.dumps(meta))
    with open(old, "wb") as fh:
        np.savez_compressed(fh, **arrays)
    assert ReferenceData.load(old).spot_size == math.pi


def test_spot_size_outside_its_range_is_refused():
    with pytest.raises(ReferenceCaptureError, match="spot_size"):
        ReferenceData(position=np.zeros((1, 1, 3)), normal=np.zeros((1, 1, 3)), hit=np.ones((1, 1), bool),
                      shadowed=np.zeros((1, 1)), unshadowed=np.zeros((1, 1)), triangles=np.zeros((0, 3, 3)),
                      light_matrix=np.eye(4), emission="spot", camera_matrix=np.eye(4), camera_fov_deg=60.0,
                      resolution=(1, 1), spot_size=0.0)


def test_visibility_threshold():
    h, w = 1, 4
    ref = ReferenceData(
        position=np.zeros((h, w, 3)), normal=np.zeros((h, w, 3)), hit=np.ones((h, w), bool),
        shadowed=np.array([[0.0, 0.49, 0.5, 0.0]]), unshadowed=np.array([[1.0, 1.0, 1.0, 0.0]]),
        triangles=np.zeros((0, 3, 3)), light_matrix=np.eye(4), emission="omni",
        camera_matrix=np.eye(4), camera_fov_deg=60.0, resolution=(w, h),
    )
    assert ref.visibility().tolist() == [[False, False, True, False]]
    assert ref.lit_domain().tolist() == [[True, True, True, False]]


def test_load_or_capture_caches(tmp_path, monkeypatch):
    size = (48, 36)
    calls = []
    real = cache._capture_preset

    def counting(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(cache, "_capture_preset", counting)
    counts = {k: len(getattr(bpy.data, k)) for k in ("scenes", "objects", "meshes", "lights", "cameras", "materials")}
    messages: list[str] = []
    first = cache.load_or_capture("courtyard", size, cache_dir=tmp_path, log_progress=messages.append)
    assert len(calls) == 1 and messages
    files = list(tmp_path.glob("courtyard_48x36_*.npz"))
    assert len(files) == 1 and first.meta["cache_key"] in files[0].name
    assert first.meta["preset"] == "courtyard" and first.resolution == size
    assert {k: len(getattr(bpy.data, k)) for k in counts} == counts, "capture leaked datablocks"

    second = cache.load_or_capture("courtyard", size, cache_dir=tmp_path)
    assert len(calls) == 1, "the second call must come from the cache"
    assert np.array_equal(second.visibility(), first.visibility())
    assert np.array_equal(second.triangles, first.triangles)

    # Without bpy the cached file still serves (any Blender version that made it).
    monkeypatch.setattr(cache, "blender_version", lambda: None)
    third = cache.load_or_capture("courtyard", size, cache_dir=tmp_path)
    assert np.array_equal(third.position, first.position) and len(calls) == 1
    with pytest.raises(ReferenceCaptureError, match="not cached"):
        cache.load_or_capture("courtyard", (40, 30), cache_dir=tmp_path)
    monkeypatch.undo()

    monkeypatch.setattr(cache, "_capture_preset", counting)
    cache.load_or_capture("courtyard", size, cache_dir=tmp_path, refresh=True)
    assert len(calls) == 2


def test_cache_dir_from_environment(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "env"))
    assert cache.cache_dir_path() == tmp_path / "env"
    monkeypatch.delenv(cache.CACHE_ENV)
    assert cache.cache_dir_path() == REPO_ROOT / ".cache" / "reference"
    assert cache.cache_dir_path(tmp_path) == tmp_path


def test_cached_load_does_not_import_bpy(omni, tmp_path):
    """A cache hit in a fresh interpreter loads without importing bpy."""
    size = (32, 24)
    ref = cache.load_or_capture("room_hemi", size, cache_dir=tmp_path)
    script = (
        "import sys, json\n"
        f"sys.path.insert(0, {str(REPO_ROOT)!r})\n"
        "from addon.reference.cache import load_or_capture\n"
        f"ref = load_or_capture('room_hemi', {size!r}, cache_dir={str(tmp_path)!r})\n"
        "print(json.dumps({'bpy': 'bpy' in sys.modules, 'hit': int(ref.hit.sum())}))\n"
    )
    out = python_ok("-c", script, env=env_with(PYTHONPATH=REPO_ROOT))
    result = json.loads(out.strip().splitlines()[-1])
    assert result == {"bpy": False, "hit": int(ref.hit.sum())}
