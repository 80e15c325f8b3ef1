"""Single projective shadow maps: uniform SM and perspective PSM (addon/core/perspective.py).

Oracles are plain numpy: the cone's geometry for the spot SM, convex combinations of
the returned region H, world light rays (occluder and receiver on one ray must share
a texel and keep their order), the sign of the PPS light's w (Stamminger and
Drettakis 2002, sec. 3) and finite differences for the texel footprint.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from addon.core import perspective as P
from addon.core.errors import InputError
from addon.core.plan import frustum_corners
from addon.core.scene import CameraSpec, LightSpec, look_at

FAST = settings(max_examples=60, deadline=None)
RES = 1024

BOX_LO = np.array([-5.0, -5.0, 0.0])
BOX_HI = np.array([5.0, 5.0, 3.0])


def _spot(location, target, cone_deg: float) -> LightSpec:
    return LightSpec("spot", look_at(location, target), spot_size=math.radians(cone_deg))


def _sun(direction) -> LightSpec:
    return LightSpec("sun", look_at((0.0, 0.0, 0.0), np.asarray(direction, dtype=np.float64)))


def _camera(eye, target, fov: float = 60.0) -> CameraSpec:
    return CameraSpec(look_at(eye, target), fov, (640, 480))


# Camera outside the box looking at it from the front (y < 0), a little from above.
OUTSIDE = (_camera((0.0, -10.0, 2.0), (0.0, 0.0, 0.0)), 2.0, 20.0)
# Camera inside the box, looking along +y.
INSIDE = (_camera((0.0, -3.0, 1.5), (0.0, 10.0, 1.5)), 0.5, 10.0)

LIGHTS = {
    "spot_front": _spot((0.0, 5.0, 8.0), (0.0, 0.0, 0.0), 80.0),
    "spot_behind": _spot((0.0, -14.0, 6.0), (0.0, 0.0, 0.0), 60.0),
    "spot_in_box": _spot((1.0, -4.5, 2.9), (0.0, 0.0, 0.0), 120.0),
    "spot_wide": _spot((0.0, 0.0, 2.9), (0.0, 0.0, 0.0), 178.9),
    "sun_front": _sun((0.3, -1.0, -1.0)),
    "sun_behind": _sun((0.3, 1.0, -1.0)),
    "sun_down": _sun((0.0, 0.0, -1.0)),
    "sun_side": _sun((1.0, 0.1, -0.2)),
}
VIEWS = {"outside": OUTSIDE, "inside": INSIDE}
CASES = [(light, view) for light in LIGHTS for view in VIEWS]


def _maps(light_name: str, view_name: str) -> list[P.ProjectiveMap]:
    light = LIGHTS[light_name]
    camera, near, far = VIEWS[view_name]
    corners = frustum_corners(camera, near, far)
    return [P.sm_map(light, BOX_LO, BOX_HI, RES, corners),
            P.psm_map(light, camera, near, far, corners, BOX_LO, BOX_HI, RES)]


def _in_region(map_: P.ProjectiveMap, count: int, seed: int) -> np.ndarray:
    """The region's vertices and random convex combinations of them."""
    rng = np.random.default_rng(seed)
    weights = rng.dirichlet(np.ones(len(map_.region)), size=count)
    return np.concatenate([map_.region, weights @ map_.region])


def _assert_inside(map_: P.ProjectiveMap, points: np.ndarray, slack: float = 1e-9) -> None:
    uv, z, w = P.project(map_, points)
    assert np.all(w > 0.0)
    assert np.all((uv >= -slack) & (uv <= 1.0 + slack)), (uv.min(), uv.max())
    assert np.all((z >= -slack) & (z <= 1.0 + slack)), (z.min(), z.max())


def _view_depth(camera: CameraSpec, world: np.ndarray) -> np.ndarray:
    m = np.asarray(camera.matrix_world)
    return -((world - m[:3, 3]) @ m[:3, 2])


# ------------------------------------------------------------------ input checks


@pytest.mark.parametrize("emission", ["omni", "hemi"])
def test_point_lights_are_rejected(emission):
    light = LightSpec(emission, look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0)))
    camera, near, far = OUTSIDE
    corners = frustum_corners(camera, near, far)
    with pytest.raises(InputError, match="spot or sun"):
        P.sm_map(light, BOX_LO, BOX_HI, RES)
    with pytest.raises(InputError, match="spot or sun"):
        P.psm_map(light, camera, near, far, corners, BOX_LO, BOX_HI, RES)


def test_bad_view_depths_are_rejected():
    camera, near, far = OUTSIDE
    corners = frustum_corners(camera, near, far)
    with pytest.raises(InputError, match="near"):
        P.psm_map(LIGHTS["sun_front"], camera, 3.0, 2.0, corners, BOX_LO, BOX_HI, RES)
    with pytest.raises(InputError, match="frustum corners"):
        P.psm_map(LIGHTS["sun_front"], camera, near, far, corners[:4], BOX_LO, BOX_HI, RES)


# ------------------------------------------------------------------ uniform SM


@pytest.mark.parametrize("cone_deg", [20.0, 80.0, 150.0, 178.9])
def test_sm_spot_cone_edge_on_window_border_axis_at_centre(cone_deg):
    """Local direction at the cone's half-angle along +-x / +-y -> ndc = 1 / (1 + SPOT_MARGIN)
    on that axis; at 45 degrees azimuth it lies on the circle of that radius; axis -> centre."""
    light = _spot((2.0, -3.0, 7.0), (0.5, 0.5, 0.0), cone_deg)
    m = P.sm_map(light, BOX_LO, BOX_HI, RES)
    half = math.radians(cone_deg) / 2.0
    edge = 1.0 / (1.0 + P.SPOT_MARGIN)
    rot = light.rotation
    dist = 4.0
    uv, _, w = P.project(m, dist * light.axis)
    assert w > 0 and np.allclose(uv, [0.5, 0.5], atol=1e-12)
    for phi_deg in (0.0, 90.0, 180.0, 270.0, 45.0, 200.0):
        phi = math.radians(phi_deg)
        local = np.array([math.sin(half) * math.cos(phi), math.sin(half) * math.sin(phi), -math.cos(half)])
        uv, _, w = P.project(m, dist * (rot @ local))
        ndc = uv * 2.0 - 1.0
        assert w > 0
        assert np.linalg.norm(ndc) == pytest.approx(edge, rel=1e-9)
        assert np.allclose(ndc, edge * np.array([math.cos(phi), math.sin(phi)]), atol=1e-9)


def test_sm_spot_depth_covers_box_corners_in_cone_and_grows_along_rays():
    light = _spot((0.0, 0.0, 8.0), (0.0, 0.0, 0.0), 100.0)
    m = P.sm_map(light, BOX_LO, BOX_HI, RES)
    corners = P.box_corners(BOX_LO, BOX_HI) - light.position
    local = corners @ light.rotation
    in_cone = np.arctan2(np.linalg.norm(local[:, :2], axis=1), -local[:, 2]) <= math.radians(50.0)
    assert in_cone.sum() >= 4
    _, z, w = P.project(m, corners[in_cone])
    assert np.all(w > 0) and np.all((z >= 0.0) & (z <= 1.0))
    ray = np.array([0.3, -0.2, -1.0]) / np.linalg.norm([0.3, -0.2, -1.0])
    uv, z, _ = P.project(m, ray * np.linspace(6.0, 12.0, 50)[:, None])
    assert np.all(np.diff(z) > 0.0)
    assert np.ptp(uv, axis=0).max() < 1e-12  # one ray, one texel


def test_sm_sun_without_camera_fits_the_box():
    light = _sun((0.3, 0.4, -1.0))
    m = P.sm_map(light, BOX_LO, BOX_HI, RES)
    assert m.pps_light == "world" and not m.inverted and m.camera_shift == 0.0
    _assert_inside(m, P.box_corners(BOX_LO, BOX_HI) - light.position)
    # Orthographic: w == 1 everywhere, depth grows along the light's travel.
    _, z, w = P.project(m, light.axis * np.array([[-1.0], [0.0], [1.0]]))
    assert np.allclose(w, 1.0) and z[0] < z[1] < z[2]


def test_matrices_take_light_centred_points():
    """The translation is folded in: a spot SM equals look-at + perspective on world points,
    and translating the whole setup far away leaves every matrix (nearly) unchanged."""
    light = LIGHTS["spot_front"]
    m = P.sm_map(light, BOX_LO, BOX_HI, RES)
    world = np.array([[0.5, 0.2, 1.0], [-2.0, 1.0, 0.3]])
    local = (world - light.position) @ light.rotation  # light-local, axis -Z
    uv, _, _ = P.project(m, world - light.position)
    half = math.tan(light.spot_size / 2.0) * (1.0 + P.SPOT_MARGIN)
    expected = local[:, :2] / (-local[:, 2:3]) / half * 0.5 + 0.5
    assert np.allclose(uv, expected, atol=1e-12)

    offset = np.array([3.0e4, -2.0e4, 1.0e4])
    camera, near, far = OUTSIDE
    moved_cam = CameraSpec(np.asarray(camera.matrix_world) + np.pad(offset[:, None], ((0, 1), (3, 0))),
                           camera.fov_deg, camera.resolution)
    for light in (LIGHTS["spot_behind"], LIGHTS["sun_behind"]):
        moved = LightSpec(light.emission, np.asarray(light.matrix_world) + np.pad(offset[:, None], ((0, 1), (3, 0))),
                          spot_size=light.spot_size)
        a = P.psm_map(light, camera, near, far, frustum_corners(camera, near, far), BOX_LO, BOX_HI, RES)
        b = P.psm_map(moved, moved_cam, near, far, frustum_corners(moved_cam, near, far),
                      BOX_LO + offset, BOX_HI + offset, RES)
        assert a.pps_light == b.pps_light
        pts = _in_region(a, 50, 3)
        ua, za, _ = P.project(a, pts)
        ub, zb, _ = P.project(b, pts)
        assert np.allclose(ua, ub, atol=1e-7) and np.allclose(za, zb, atol=1e-7)


# ------------------------------------------------------------------ H maps inside


@pytest.mark.parametrize("light_name,view_name", CASES)
def test_region_maps_inside_the_map(light_name, view_name):
    for m in _maps(light_name, view_name):
        assert m.region.ndim == 2 and m.region.shape[1] == 3 and len(m.region) >= 1
        assert np.all(np.isfinite(m.matrix)) and m.matrix.dtype == np.float64
        _assert_inside(m, _in_region(m, 400, 1))


@pytest.mark.parametrize("light_name", ["spot_front", "spot_behind", "sun_front", "sun_behind", "sun_side"])
def test_psm_region_contains_the_visible_box(light_name):
    """H contains V n S: every visible point of the scene box is in the map."""
    camera, near, far = OUTSIDE
    corners = frustum_corners(camera, near, far)
    light = LIGHTS[light_name]
    m = P.psm_map(light, camera, near, far, corners, BOX_LO, BOX_HI, RES)
    tol = 1e-9 * 50
    v_in_s = P.halfspace_vertices(np.concatenate([P.hull_planes(corners - light.position, tol),
                                                  P.box_planes(BOX_LO - light.position, BOX_HI - light.position)]),
                                  tol)
    if light.emission == "spot":  # ... inside the spot's cone pyramid
        local = v_in_s @ light.rotation
        t = math.tan(light.spot_size / 2.0)
        v_in_s = v_in_s[np.all(np.abs(local[:, :2]) <= t * -local[:, 2:3] + 1e-9, axis=1)]
    assert len(v_in_s) >= 4
    _assert_inside(m, v_in_s, slack=1e-7)


# ------------------------------------------------------------------ PPS light classes


def _ray_pair(light: LightSpec, receiver: np.ndarray, toward_light: float) -> np.ndarray:
    """A point between the receiver and the light on the same world light ray (light-centred)."""
    if light.emission == "spot":
        return receiver * (1.0 - toward_light)
    return receiver - light.axis * toward_light


def test_spot_in_front_of_camera_is_a_pps_point_light():
    camera, near, far = OUTSIDE
    m = P.psm_map(LIGHTS["spot_front"], camera, near, far, frustum_corners(camera, near, far), BOX_LO, BOX_HI, RES)
    assert m.pps_light == "point" and not m.inverted and m.camera_shift == 0.0


def test_spot_behind_camera_plane_is_inverted_and_reverses_depth_order():
    camera, near, far = OUTSIDE
    light = LIGHTS["spot_behind"]
    assert _view_depth(camera, light.position[None])[0] < 0.0  # behind the camera plane
    corners = frustum_corners(camera, near, far)
    m = P.psm_map(light, camera, near, far, corners, BOX_LO, BOX_HI, RES)
    assert m.pps_light == "inverted" and m.inverted and m.camera_shift == 0.0
    receiver = np.array([0.0, 0.0, 0.0]) - light.position  # box centre floor, seen by the camera
    occluder = _ray_pair(light, receiver, 0.3)
    (uv_r, uv_o), (z_r, z_o), _ = P.project(m, np.stack([receiver, occluder]))
    assert np.allclose(uv_r, uv_o, atol=1e-12)
    assert z_o > z_r  # the point nearer the world light has the LARGER z01
    # The uniform map keeps the ordinary order.
    sm = P.sm_map(light, BOX_LO, BOX_HI, RES)
    _, (zs_r, zs_o), _ = P.project(sm, np.stack([receiver, occluder]))
    assert zs_o < zs_r


def test_sun_from_front_is_point_from_behind_is_inverted():
    camera, near, far = OUTSIDE
    corners = frustum_corners(camera, near, far)
    front = P.psm_map(LIGHTS["sun_front"], camera, near, far, corners, BOX_LO, BOX_HI, RES)
    behind = P.psm_map(LIGHTS["sun_behind"], camera, near, far, corners, BOX_LO, BOX_HI, RES)
    assert (front.pps_light, front.inverted) == ("point", False)
    assert (behind.pps_light, behind.inverted) == ("inverted", True)
    receiver = np.array([1.0, 1.0, 0.0])
    for m, light in ((front, LIGHTS["sun_front"]), (behind, LIGHTS["sun_behind"])):
        occluder = _ray_pair(light, receiver, 2.0)
        (uv_r, uv_o), (z_r, z_o), _ = P.project(m, np.stack([receiver, occluder]))
        assert np.allclose(uv_r, uv_o, atol=1e-12)
        assert (z_o > z_r) if m.inverted else (z_o < z_r)


def test_sun_perpendicular_to_view_is_directional():
    """A sun parallel to the image plane maps to w = 0 exactly: a directional PPS light
    (paper sec. 3.1), i.e. an orthographic map in PPS."""
    camera = _camera((0.0, -3.0, 1.5), (0.0, 10.0, 1.5))  # looks along +y, horizontally
    near, far = 0.5, 10.0
    corners = frustum_corners(camera, near, far)
    m = P.psm_map(_sun((0.0, 0.0, -1.0)), camera, near, far, corners, BOX_LO, BOX_HI, RES)
    assert (m.pps_light, m.inverted, m.camera_shift) == ("directional", False, 0.0)
    _assert_inside(m, _in_region(m, 300, 2))
    # Tilting it slightly forward or back gives an inverted or a point light far away,
    # and the map changes continuously (the kappa formulation is well conditioned);
    # the inverted one counts depth from the other end.
    pts = _in_region(m, 300, 4)
    uv0, z0, _ = P.project(m, pts)
    for tilt, kind in ((1e-7, "inverted"), (-1e-7, "point")):
        tilted = P.psm_map(_sun((0.0, tilt, -1.0)), camera, near, far, corners, BOX_LO, BOX_HI, RES)
        assert tilted.pps_light == kind
        uv1, z1, _ = P.project(tilted, pts)
        assert np.abs(uv1 - uv0).max() < 1e-5
        assert np.abs((1.0 - z1 if tilted.inverted else z1) - z0).max() < 1e-5


def test_directional_rule():
    """classify_pps_light: directional iff kappa * R <= DIRECTIONAL_EPS (kappa = |w| / |w c - l|)."""
    centre, radius = np.array([0.1, -0.2, 0.3]), 1.5
    ell = np.array([0.0, 2.0, 1.0])
    assert P.classify_pps_light(np.append(ell, 0.0), centre, radius) == "directional"
    limit = P.DIRECTIONAL_EPS * np.linalg.norm(ell) / radius  # |w| at the threshold, to first order
    assert P.classify_pps_light(np.append(ell, 0.5 * limit), centre, radius) == "directional"
    assert P.classify_pps_light(np.append(ell, -0.5 * limit), centre, radius) == "directional"
    assert P.classify_pps_light(np.append(ell, 2.0 * limit), centre, radius) == "point"
    assert P.classify_pps_light(np.append(ell, -2.0 * limit), centre, radius) == "inverted"
    assert P.classify_pps_light(np.array([0.0, 0.0, 0.5, 1.0]), centre, radius) == "point"


def test_point_light_in_camera_plane_is_directional():
    """The miner's lamp (paper 3.3): a spot at the camera, with no caster behind the camera,
    lies in the camera plane, so its PPS image is directional."""
    camera, near, far = OUTSIDE
    eye = np.asarray(camera.matrix_world)[:3, 3]
    light = _spot(eye + np.array([1.0, 0.0, 0.0]), (1.0, 0.0, 0.0), 70.0)
    m = P.psm_map(light, camera, near, far, frustum_corners(camera, near, far), BOX_LO, BOX_HI, RES)
    assert m.pps_light == "directional" and m.camera_shift == 0.0
    _assert_inside(m, _in_region(m, 300, 5))


# ------------------------------------------------------------------ occlusion


@pytest.mark.parametrize("light_name,view_name", CASES)
def test_occlusion_is_preserved(light_name, view_name):
    """Occluder and receiver on one world light ray, both in H: same uv, occluder nearer
    the light in the map's depth sense."""
    light = LIGHTS[light_name]
    rng = np.random.default_rng(7)
    for m in _maps(light_name, view_name):
        receiver = _in_region(m, 400, 11)
        # A spot's pair is a share of the way to the light, a sun's a distance toward it.
        toward = rng.uniform(0.05, 0.9, (len(receiver), 1)) * (1.0 if light.emission == "spot" else 3.0)
        occluder = _ray_pair(light, receiver, toward)
        # Keep the pairs whose occluder is in H too (in the map and in front of it).
        uv_o, z_o, w_o = P.project(m, occluder)
        keep = (w_o > 0) & np.all((uv_o >= 0) & (uv_o <= 1), axis=1) & (z_o >= 0) & (z_o <= 1)
        assert keep.sum() > 50
        uv_r, z_r, _ = P.project(m, receiver[keep])
        scale = 1.0 + np.abs(uv_r).max()
        assert np.abs(uv_o[keep] - uv_r).max() <= 1e-9 * scale
        nearer = (z_o[keep] > z_r) if m.inverted else (z_o[keep] < z_r)
        assert np.all(nearer)


@pytest.mark.parametrize("light_name,view_name", CASES)
def test_light_facing_triangles_are_counter_clockwise_in_uv(light_name, view_name):
    """One winding convention for every map: a small triangle facing the light, counter-
    clockwise seen from the light, is counter-clockwise in uv (anywhere in H)."""
    light = LIGHTS[light_name]
    for m in _maps(light_name, view_name):
        centres = _in_region(m, 30, 12)[-30:]
        size = 1e-4 * float(np.ptp(m.region, axis=0).max())
        for c in centres:
            ray = c / np.linalg.norm(c) if light.emission == "spot" else light.axis
            helper = np.eye(3)[int(np.argmin(np.abs(ray)))]
            e1 = np.cross(ray, helper)
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(e1, ray)  # e1 x e2 = -ray: the normal faces the light
            uv, _, _ = P.project(m, np.stack([c, c + size * e1, c + size * e2]))
            a, b = uv[1] - uv[0], uv[2] - uv[0]
            assert a[0] * b[1] - a[1] * b[0] > 0.0


# ------------------------------------------------------------------ camera shift


def test_camera_shift_for_casters_behind_the_camera():
    """Sun from behind, camera inside the box: H reaches behind the camera (sec. 4.2)."""
    camera, near, far = INSIDE
    light = _sun((0.2, 1.0, -0.5))
    corners = frustum_corners(camera, near, far)
    m = P.psm_map(light, camera, near, far, corners, BOX_LO, BOX_HI, RES)
    assert m.camera_shift > 0.0
    depth = _view_depth(camera, m.region + light.position)
    assert depth.min() < 0.0  # casters behind the camera are included ...
    assert depth.min() + m.camera_shift >= near * (1.0 - 1e-9)  # ... and in front of the shifted one
    assert depth.min() + m.camera_shift == pytest.approx(near, rel=1e-6)
    _assert_inside(m, _in_region(m, 500, 3))


def test_spot_in_box_behind_camera_shifts():
    camera, near, far = INSIDE
    light = _spot((0.5, -4.0, 2.5), (0.0, 0.0, 1.0), 90.0)
    m = P.psm_map(light, camera, near, far, frustum_corners(camera, near, far), BOX_LO, BOX_HI, RES)
    assert m.camera_shift > 0.0
    _assert_inside(m, _in_region(m, 500, 6))


@pytest.mark.parametrize("light", [_sun((0.2, -1.0, -0.5)), _sun((0.2, 1.0, -0.5))])
def test_no_shift_without_casters_behind(light):
    """Sun from the front (extrusion forward), or from behind with the box in front of the camera."""
    camera, near, far = INSIDE
    lo = BOX_LO.copy()
    if light.axis[1] > 0:
        lo[1] = -2.0  # the camera (y = -3) is now outside, behind the box
    m = P.psm_map(light, camera, near, far, frustum_corners(camera, near, far), lo, BOX_HI, RES)
    assert m.camera_shift == 0.0


# ------------------------------------------------------------------ geometry helpers


def _cube(size: float = 2.0, centre=(0.0, 0.0, 0.0)) -> np.ndarray:
    h = size / 2.0
    return P.box_corners(np.asarray(centre) - h, np.asarray(centre) + h)


def _same_points(a: np.ndarray, b: np.ndarray, tol: float = 1e-9) -> bool:
    if a.shape != b.shape:
        return False
    d = np.linalg.norm(a[:, None] - b[None], axis=-1)
    return bool(np.all(d.min(axis=1) <= tol) and np.all(d.min(axis=0) <= tol))


def test_hull_of_cube_and_back():
    pts = np.concatenate([_cube(2.0, (1.0, 2.0, 3.0)), [[1.0, 2.0, 3.0], [1.5, 2.2, 3.1]]])  # + interior points
    planes = P.hull_planes(pts)
    assert planes.shape == (6, 4)
    assert np.allclose(np.linalg.norm(planes[:, :3], axis=1), 1.0)
    assert np.all(pts @ planes[:, :3].T - planes[:, 3] <= 1e-12)
    assert _same_points(P.halfspace_vertices(planes, 1e-9), _cube(2.0, (1.0, 2.0, 3.0)))
    assert _same_points(P.halfspace_vertices(P.box_planes([0, 0, 0], [1, 2, 3]), 1e-9),
                        P.box_corners(np.zeros(3), np.array([1.0, 2.0, 3.0])))


def test_hull_of_tetrahedron():
    tet = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    planes = P.hull_planes(tet)
    assert planes.shape == (4, 4)
    normals = {tuple(np.round(n, 9)) for n in planes[:, :3]}
    s = 1.0 / math.sqrt(3.0)
    assert normals == {(-1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0), tuple(np.round([s, s, s], 9))}
    assert _same_points(P.halfspace_vertices(planes, 1e-9), tet)
    # Cutting the tetrahedron by x <= 0.5: 6 vertices.
    cut = P.halfspace_vertices(np.concatenate([planes, [[1.0, 0.0, 0.0, 0.5]]]), 1e-9)
    assert len(cut) == 6 and np.all(cut[:, 0] <= 0.5 + 1e-12)


def test_degenerate_hulls_stay_bounded():
    square = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0], [0.5, 0.5, 1.0]])
    assert _same_points(P.halfspace_vertices(P.hull_planes(square), 1e-9), square[:4])
    segment = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.5, 0.5, 0.5]])
    assert _same_points(P.halfspace_vertices(P.hull_planes(segment), 1e-9), segment[:2])
    point = np.array([[2.0, -1.0, 3.0]] * 3)
    assert _same_points(P.halfspace_vertices(P.hull_planes(point), 1e-9), point[:1])
    assert P.hull_planes(np.zeros((0, 3))).shape == (0, 4)


def test_empty_intersection_and_fallbacks():
    a, b = P.box_planes([0, 0, 0], [1, 1, 1]), P.box_planes([2, 0, 0], [3, 1, 1])
    assert P.halfspace_vertices(np.concatenate([a, b]), 1e-9).shape == (0, 3)
    assert P.halfspace_vertices(a[:2], 1e-9).shape == (0, 3)
    # A view that misses the scene box: H is empty; the maps still cover S.
    camera = _camera((0.0, -10.0, 2.0), (0.0, -20.0, 2.0))  # looking away
    near, far = 1.0, 5.0
    for light in (LIGHTS["spot_front"], LIGHTS["sun_front"]):
        m = P.psm_map(light, camera, near, far, frustum_corners(camera, near, far), BOX_LO, BOX_HI, RES)
        assert np.all(np.isfinite(m.matrix)) and math.isfinite(m.depth_offset)
        _assert_inside(m, _in_region(m, 100, 8))


def test_spot_cone_missing_the_box_stays_valid():
    light = _spot((0.0, 0.0, 10.0), (0.0, 0.0, 20.0), 30.0)  # points away from the scene
    m = P.sm_map(light, BOX_LO, BOX_HI, RES)
    assert np.all(np.isfinite(m.matrix)) and m.depth_offset > 0
    _assert_inside(m, m.region)


# ------------------------------------------------------------------ footprint and offset


@pytest.mark.parametrize("light_name", ["spot_front", "sun_behind", "sun_side"])
def test_texel_footprint_matches_finite_differences(light_name):
    camera, near, far = OUTSIDE
    light = LIGHTS[light_name]
    m = P.psm_map(light, camera, near, far, frustum_corners(camera, near, far), BOX_LO, BOX_HI, RES)
    pts = _in_region(m, 20, 9)[-20:]
    h = 1e-5 * (1.0 + np.abs(pts).max())
    jac = np.empty((len(pts), 2, 3))
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        jac[:, :, k] = (P.project(m, pts + step)[0] - P.project(m, pts - step)[0]) / (2.0 * h)
    expected = (1.0 / RES) / np.linalg.svd(jac, compute_uv=False)[:, -1]
    got = P.texel_footprint(m, pts, RES)
    assert got.shape == (20,)
    assert np.allclose(got, expected, rtol=1e-5)
    assert np.allclose(P.texel_footprint(m, pts, 2 * RES), got / 2.0, rtol=1e-12)


@pytest.mark.parametrize("light_name,view_name", [("spot_front", "outside"), ("sun_behind", "inside"),
                                                  ("sun_down", "outside"), ("spot_in_box", "inside")])
def test_depth_offset_positive_and_halves_with_resolution(light_name, view_name):
    light = LIGHTS[light_name]
    camera, near, far = VIEWS[view_name]
    corners = frustum_corners(camera, near, far)
    for make in (lambda r: P.sm_map(light, BOX_LO, BOX_HI, r, corners),
                 lambda r: P.psm_map(light, camera, near, far, corners, BOX_LO, BOX_HI, r)):
        a, b = make(512), make(1024)
        assert math.isfinite(a.depth_offset) and a.depth_offset > 0.0
        assert b.depth_offset == pytest.approx(a.depth_offset / 2.0, rel=1e-6)


def test_depth_offset_is_half_a_texel_of_depth_on_a_45_degree_receiver():
    """Orthographic sun map: a 45 degree receiver rises one world unit per unit across the
    map, so the rule gives 0.5 * (z01 per unit along the ray) * (largest texel side)."""
    light = _sun((0.2, 0.1, -1.0))
    m = P.sm_map(light, BOX_LO, BOX_HI, RES)
    _, z, _ = P.project(m, np.array([[0.0, 0.0, 0.0], light.axis]))
    footprint = P.texel_footprint(m, m.region.mean(axis=0), RES)
    assert m.depth_offset == pytest.approx(0.5 * (z[1] - z[0]) * footprint, rel=1e-9)


# ------------------------------------------------------------------ property test


@FAST
@given(
    eye=st.tuples(*[st.floats(-8.0, 8.0)] * 3),
    target=st.tuples(*[st.floats(-3.0, 3.0)] * 3),
    fov=st.floats(15.0, 110.0),
    near=st.floats(0.02, 2.0),
    depth_ratio=st.floats(1.05, 500.0),
    light_pos=st.tuples(*[st.floats(-10.0, 10.0)] * 3),
    light_dir=st.tuples(*[st.floats(-1.0, 1.0)] * 3),
    cone=st.floats(1.0, 178.9),
    sun=st.booleans(),
    lo=st.tuples(*[st.floats(-6.0, 0.0)] * 3),
    size=st.tuples(*[st.floats(0.0, 8.0)] * 3),
)
def test_random_setups_stay_finite_and_cover_h(eye, target, fov, near, depth_ratio, light_pos, light_dir,
                                               cone, sun, lo, size):
    eye, target, light_dir = np.array(eye), np.array(target), np.array(light_dir)
    if np.linalg.norm(target - eye) < 1e-2 or np.linalg.norm(light_dir) < 1e-2:
        return
    camera = _camera(eye, target, fov)
    far = near * depth_ratio
    corners = frustum_corners(camera, near, far)
    if sun:
        light = LightSpec("sun", look_at(light_pos, np.array(light_pos) + light_dir))
    else:
        light = LightSpec("spot", look_at(light_pos, np.array(light_pos) + light_dir), spot_size=math.radians(cone))
    lo = np.array(lo)
    hi = lo + np.array(size)
    for m in (P.sm_map(light, lo, hi, 512, corners), P.psm_map(light, camera, near, far, corners, lo, hi, 512)):
        assert np.all(np.isfinite(m.matrix)) and np.all(np.isfinite(m.region))
        assert math.isfinite(m.depth_offset) and m.depth_offset > 0.0
        assert math.isfinite(m.camera_shift) and m.camera_shift >= 0.0
        assert m.pps_light in ("world", "point", "inverted", "directional")
        assert m.inverted == (m.pps_light == "inverted")
        _assert_inside(m, _in_region(m, 50, 0), slack=1e-7)
