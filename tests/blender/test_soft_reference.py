"""A sized light's Cycles reference (issue 27): the light as the file has it, its noise
measured from two halves, and `hard` for the hard-shadow study.

The expected soft visibility comes from an independent numpy integration over the light
(the sphere's visible cap, uniform in solid angle; the area light's surface, Lambertian),
cosine-weighted at the floor, with a ray-box test against the one blocker.
"""
from __future__ import annotations

import dataclasses

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from addon.core import metrics  # noqa: E402
from addon.core.light_shape import Area, Sphere, shape_from_dict, stratified_unit_square  # noqa: E402
from addon.core.scene import SceneBuilder, SceneSpec  # noqa: E402
from addon.reference.blender_scene import build_blender_scene, remove_blender_scene  # noqa: E402
from addon.reference.capture import capture  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from tests.support.soft_oracle import soft_visibility  # noqa: E402

pytestmark = pytest.mark.blender

SIZE = (64, 48)
SOFT = 64
BOX_LO, BOX_HI = np.array([-0.5, -0.5, 0.0]), np.array([0.5, 0.5, 1.0])
LIGHT = np.array([0.4, 0.3, 3.0])


def scene(light: str) -> SceneSpec:
    b = SceneBuilder(f"soft_{light}", SIZE)
    b.plane("floor", (0.0, 0.0, 0.0), 8.0, 8.0)
    b.box("box", 0.5 * (BOX_LO + BOX_HI), BOX_HI - BOX_LO)
    if light == "sphere":
        b.point_light(LIGHT, radius=0.6)
    elif light == "spot":
        # A blended 60 degree cone whose fading edge crosses the floor in view.
        b.spot_light(LIGHT, (1.0, 0.6, 0.0), 60.0, radius=0.6)
        b._light = dataclasses.replace(b._light, spot_blend=0.4)
    else:
        b.area_light(LIGHT, (0.4, 0.3, 0.0), 1.4, 0.9)
    b.camera((0.0, -5.0, 4.5), (0.0, 0.3, 0.0), fov_deg=60.0)
    return b.finish()


def render(spec: SceneSpec, **kwargs) -> tuple[ReferenceData, dict]:
    blender_scene = build_blender_scene(spec)
    try:
        light = next(o for o in blender_scene.objects if o.type == "LIGHT").data
        ref = capture(blender_scene, **kwargs)
        after = {"shadow_soft_size": light.shadow_soft_size, "size": getattr(light, "size", None)}
        return ref, after
    finally:
        remove_blender_scene(blender_scene)


def segments_blocked(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(P, M) bool: the segment from each p (P, 3) to each q (P, M, 3) crosses the box."""
    d = q - p[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (BOX_LO - p[:, None, :]) / d
        t1 = (BOX_HI - p[:, None, :]) / d
    near = np.nanmax(np.minimum(t0, t1), axis=-1)
    far = np.nanmin(np.maximum(t0, t1), axis=-1)
    return (near <= far) & (far > 1e-6) & (near < 1.0 - 1e-6)


def sphere_visibility(p: np.ndarray, radius: float, n: int = 1024) -> np.ndarray:
    """Cosine-weighted share of the sphere's visible cap each floor point p sees."""
    to_c = LIGHT - p
    dist = np.linalg.norm(to_c, axis=1)
    w = to_c / dist[:, None]
    cos_max = np.sqrt(1.0 - (radius / dist) ** 2)
    uv = stratified_unit_square(n)
    cos_t = 1.0 - uv[None, :, 0] * (1.0 - cos_max[:, None])
    sin_t = np.sqrt(1.0 - cos_t ** 2)
    phi = 2.0 * math.pi * uv[None, :, 1]
    u = np.cross(w, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(w, u)
    d = (sin_t * np.cos(phi))[..., None] * u[:, None] + (sin_t * np.sin(phi))[..., None] * v[:, None] \
        + cos_t[..., None] * w[:, None]
    # Where each direction meets the sphere first: t = b - sqrt(b^2 - c).
    b = np.einsum("pmi,pi->pm", d, to_c)
    t = b - np.sqrt(np.maximum(b * b - (dist ** 2 - radius ** 2)[:, None], 0.0))
    q = p[:, None, :] + t[..., None] * d
    weight = np.maximum(d[..., 2], 0.0)  # the floor's normal is +Z
    lit = ~segments_blocked(p, q)
    return (weight * lit).sum(axis=1) / weight.sum(axis=1)


def area_visibility(p: np.ndarray, size: tuple[float, float], matrix: np.ndarray, n: int = 1024) -> np.ndarray:
    """Share of a Lambertian rectangle's light each floor point p gets."""
    uv = stratified_unit_square(n)
    local = np.column_stack([(uv - 0.5) * size, np.zeros(n), np.ones(n)])
    q = (local @ matrix.T)[:, :3]
    normal = -matrix[:3, 2]  # the light faces its local -Z
    d = q[None] - p[:, None]
    r2 = np.einsum("pmi,pmi->pm", d, d)
    cos_r = np.maximum(d[..., 2], 0.0) / np.sqrt(r2)
    cos_e = np.maximum(-np.einsum("pmi,i->pm", d, normal), 0.0) / np.sqrt(r2)
    weight = cos_r * cos_e / r2
    lit = ~segments_blocked(p, np.broadcast_to(q, d.shape))
    return (weight * lit).sum(axis=1) / weight.sum(axis=1)


def same_shape(a, b) -> bool:
    """Equal shapes up to Blender's float32 sizes."""
    da, db = a.as_dict(), b.as_dict()
    return da.keys() == db.keys() and all(
        da[k] == db[k] if isinstance(da[k], str) else math.isclose(da[k], db[k], rel_tol=1e-6) for k in da)


def floor_pixels(ref: ReferenceData, spec: SceneSpec) -> np.ndarray:
    """Evaluated floor pixels (z = 0) away from the box's base."""
    ev = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, spec.light)
    on_floor = np.abs(ref.position[..., 2]) < 1e-3
    return ev & on_floor


@pytest.mark.parametrize("light", ["sphere", "area"])
def test_a_sized_light_renders_its_penumbra_with_its_noise(light):
    spec = scene(light)
    ref, after = render(spec, soft_samples=SOFT)
    shape = ref.light_shape()
    assert same_shape(shape, spec.light.shape) and shape.sized
    assert ref.emission == ("omni" if light == "sphere" else "hemi")
    assert ref.meta["samples"] == SOFT and ref.visibility_noise is not None
    mask = floor_pixels(ref, spec)
    p = ref.position[mask].astype(np.float64)
    ratio = metrics.reference_ratio(ref.shadowed, ref.unshadowed)[mask]
    if light == "sphere":
        expected = sphere_visibility(p, 0.6)
    else:
        expected = area_visibility(p, (1.4, 0.9), spec.light.matrix_world)
    penumbra = (expected > 0.05) & (expected < 0.95)
    assert penumbra.sum() > 100  # the light's size makes a wide penumbra
    noise = float(ref.visibility_noise[mask].mean())
    assert 0.0 < noise < 0.05
    # The reference converges to the integral: within twice its own measured noise.
    err = float(np.abs(ratio - expected).mean())
    assert err <= 2.0 * noise + 0.005, (err, noise)
    # And the noise is where the penumbra is: none in full light.
    assert float(ref.visibility_noise[mask][expected > 0.999].mean()) < 0.2 * noise


def test_a_blended_spot_weighs_each_light_point_by_its_cone():
    """Cycles attenuates each sample of a sized spot by the cone along its own direction
    (render/soft.py's spot_cone): near the fading edge its ratio follows the oracle that
    weighs the points so (tests/support/soft_oracle.py), not the one that weighs them alike."""
    spec = scene("spot")
    ref, _ = render(spec, soft_samples=SOFT)
    assert ref.meta["spot_blend"] == pytest.approx(0.4) and ref.light_spec().spot_blend == pytest.approx(0.4)
    light = ref.light_spec()
    mask = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
    p = ref.position[mask].astype(np.float64)
    normals = ref.normal[mask].astype(np.float64)
    ratio = metrics.reference_ratio(ref.shadowed, ref.unshadowed)[mask]
    tris = np.asarray(ref.triangles, dtype=np.float64)
    weighed = soft_visibility(light, p, normals, tris, n=256)
    alike = soft_visibility(dataclasses.replace(light, emission="omni", spot_size=math.pi, spot_blend=0.0),
                            p, normals, tris, n=256)
    noise = float(ref.visibility_noise[mask].mean())
    err_weighed = float(np.abs(ratio - weighed).mean())
    err_alike = float(np.abs(ratio - alike).mean())
    assert err_weighed <= 2.0 * noise + 0.005, (err_weighed, noise)
    assert err_weighed < 0.7 * err_alike, (err_weighed, err_alike)


def test_hard_takes_the_size_away_for_the_render_only():
    spec = scene("sphere")
    ref, after = render(spec, hard=True)
    assert not ref.light_shape().sized and ref.visibility_noise is None
    assert same_shape(shape_from_dict(ref.meta["light_shape_file"]), spec.light.shape)
    assert after["shadow_soft_size"] == pytest.approx(0.6)  # the scene keeps its light
    mask = floor_pixels(ref, spec)
    ratio = metrics.reference_ratio(ref.shadowed, ref.unshadowed)[mask]
    assert np.mean((ratio > 0.02) & (ratio < 0.98)) < 0.01  # binary: no penumbra


def test_the_reference_keeps_its_shape_and_noise_on_disk(tmp_path):
    spec = scene("area")
    ref, _ = render(spec, soft_samples=8)
    path = ref.save(tmp_path / "ref.npz")
    back = ReferenceData.load(path)
    assert same_shape(back.light_shape(), Area("rectangle", 1.4, 0.9))
    assert np.array_equal(back.visibility_noise, ref.visibility_noise)
    assert Sphere(0.6) != back.light_shape()
