"""Light frames: the layers of a light and the slot rule (addon/core/frames.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from addon.core import frames as F
from addon.core.errors import InputError
from addon.core.projection import CUBE, PARABOLOID
from addon.core.scene import LightSpec, look_at, orthonormalize

FAST = settings(max_examples=60, deadline=None)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q @ np.diag(np.sign(np.diag(r)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q


def _light(emission: str, rotation: np.ndarray, position=(1.0, -2.0, 3.0), scale=1.0) -> LightSpec:
    m = np.eye(4)
    m[:3, :3] = rotation * scale
    m[:3, 3] = position
    return LightSpec(emission, m)


seeds = st.integers(0, 2**32 - 1)


# ---------------------------------------------------------------- layer sets


@pytest.mark.parametrize(
    "emission, par, slots",
    [
        ("omni", "dpsm", [0, 1]),
        ("omni", "cube", [0, 1, 2, 3, 4, 5]),
        ("hemi", "dpsm", [0]),
        ("hemi", "cube", [0, 1, 2, 3, 5]),  # +Z (slot 4) looks away from the axis
    ],
)
def test_layer_sets(emission, par, slots):
    """Omni: 2 sides / 6 faces; hemi: only the axis side / every face but local +Z."""
    layers = F.light_layers(_light(emission, np.eye(3)), par)
    assert [layer.slot for layer in layers] == slots
    kind = PARABOLOID if par == "dpsm" else CUBE
    assert all(layer.kind == kind for layer in layers)
    assert len({layer.name for layer in layers}) == len(layers)
    assert F.slot_count(par) == (2 if par == "dpsm" else 6)


def test_hemi_dropped_face_looks_away_from_axis():
    """The face a hemi light drops is the one whose axis is opposite the light's axis."""
    rot = _random_rotation(np.random.default_rng(3))
    light = _light("hemi", rot)
    omni = F.light_layers(_light("omni", rot), "cube")
    hemi_slots = {layer.slot for layer in F.light_layers(light, "cube")}
    (dropped,) = [layer for layer in omni if layer.slot not in hemi_slots]
    assert np.allclose(dropped.rotation[2], -light.axis, atol=1e-12)


def test_unknown_parameterization_raises_input_error():
    """A bad parameterization name is a user error that names it."""
    with pytest.raises(InputError, match="sphere"):
        F.light_layers(_light("omni", np.eye(3)), "sphere")


# ---------------------------------------------------------------- rotations


@FAST
@given(seeds, st.sampled_from(["omni", "hemi"]), st.sampled_from(["dpsm", "cube"]), st.floats(0.1, 10.0))
def test_layer_rotations_are_proper_orthonormal(seed, emission, par, scale):
    """Every layer rotation is orthonormal with determinant +1, even for a scaled light."""
    light = _light(emission, _random_rotation(np.random.default_rng(seed)), scale=scale)
    for layer in F.light_layers(light, par):
        r = layer.rotation
        assert np.allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)


@FAST
@given(seeds, st.sampled_from(["omni", "hemi"]), st.sampled_from(["dpsm", "cube"]))
def test_slot_zero_axis_is_light_axis(seed, emission, par):
    """Slot 0 of dpsm looks along the light's axis (local -Z in world)."""
    rot = _random_rotation(np.random.default_rng(seed))
    light = _light(emission, rot)
    layers = {layer.slot: layer for layer in F.light_layers(light, par)}
    if par == "dpsm":
        assert np.allclose(layers[0].rotation[2], -rot[:, 2], atol=1e-12)
        assert np.allclose(layers[0].rotation[2], light.axis, atol=1e-12)
        if 1 in layers:
            assert np.allclose(layers[1].rotation[2], rot[:, 2], atol=1e-12)
    else:
        # Cube slot 5 (-Z) is the face looking along the axis.
        assert np.allclose(layers[5].rotation[2], light.axis, atol=1e-12)


@FAST
@given(seeds)
def test_cube_face_axes_are_signed_light_axes(seed):
    """Faces 0..5 look along light-local +X, -X, +Y, -Y, +Z, -Z (in world)."""
    rot = _random_rotation(np.random.default_rng(seed))
    layers = F.light_layers(_light("omni", rot), "cube")
    expected = [rot[:, 0], -rot[:, 0], rot[:, 1], -rot[:, 1], rot[:, 2], -rot[:, 2]]
    for layer, axis in zip(layers, expected):
        assert np.allclose(layer.rotation[2], axis, atol=1e-12)


def test_light_axis_is_local_minus_z_of_look_at():
    """A hemi light made by look_at points its axis at the target."""
    light = LightSpec("hemi", look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0)))
    assert np.allclose(light.axis, [0.0, 0.0, -1.0], atol=1e-12)
    side0 = F.light_layers(light, "dpsm")[0]
    # The floor point straight below is on the paraboloid axis: local (0, 0, +3).
    assert np.allclose(side0.to_local(np.array([0.0, 0.0, -3.0])), [0.0, 0.0, 3.0], atol=1e-12)


def test_to_local_is_rotation_of_offsets():
    """to_local applies the layer rotation to (..., 3) offsets."""
    layer = F.light_layers(_light("omni", _random_rotation(np.random.default_rng(5))), "cube")[2]
    offs = np.random.default_rng(6).normal(size=(4, 3, 3))
    assert np.allclose(layer.to_local(offs), np.einsum("ij,abj->abi", layer.rotation, offs))


# ---------------------------------------------------------------- pick_slot


def _light_local_to_world(light: LightSpec, d: np.ndarray) -> np.ndarray:
    return d @ light.rotation.T


@FAST
@given(seeds)
def test_pick_slot_paraboloid_lands_in_front_hemisphere(seed):
    """The picked paraboloid side sees the direction in its front half (local z >= 0)."""
    rng = np.random.default_rng(seed)
    light = _light("omni", _random_rotation(rng))
    layers = F.light_layers(light, "dpsm")
    d = rng.normal(size=(200, 3))
    d[:5, 2] = 0.0  # on the seam: either side's rim, must still be z >= 0
    slots = F.pick_slot("dpsm", d)
    world = _light_local_to_world(light, d)
    for slot in (0, 1):
        local = layers[slot].to_local(world[slots == slot])
        assert np.all(local[:, 2] >= -1e-12)


@FAST
@given(seeds)
def test_pick_slot_cube_lands_in_face_frustum(seed):
    """The picked cube face is the major axis: |x| <= z and |y| <= z in its frame."""
    rng = np.random.default_rng(seed)
    light = _light("omni", _random_rotation(rng))
    layers = F.light_layers(light, "cube")
    d = rng.normal(size=(300, 3))
    # Ties (cube edges and corners) must still land inside the picked face.
    d[:8] = [[1, 1, 0], [-1, 1, 1], [1, -1, -1], [0, 2, -2], [3, 3, 3], [-1, -1, -1], [0, 0, -1], [2, 0, 2]]
    slots = F.pick_slot("cube", d)
    assert set(np.unique(slots)) <= set(range(6))
    world = _light_local_to_world(light, d)
    for slot in range(6):
        local = layers[slot].to_local(world[slots == slot])
        z = local[:, 2]
        assert np.all(z > 0.0)
        assert np.all(np.abs(local[:, 0]) <= z * (1 + 1e-12))
        assert np.all(np.abs(local[:, 1]) <= z * (1 + 1e-12))


def test_pick_slot_known_directions():
    """Axis directions pick their own face; local z <= 0 picks paraboloid side 0, z > 0 side 1."""
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float) * 2.5
    assert list(F.pick_slot("cube", axes)) == [0, 1, 2, 3, 4, 5]
    assert list(F.pick_slot("dpsm", axes)) == [0, 0, 0, 0, 1, 0]  # the seam (z = 0) goes to side 0


def test_pick_slot_cube_ties_go_x_then_y_then_z():
    """Documented tie rule (shared with the GLSL test): X before Y before Z."""
    d = np.array([[1, 1, 0], [-1, 1, 0], [0, 1, 1], [0, -1, -1], [1, 0, 1], [-1, 0, -1], [1, 1, 1], [-1, -1, -1]],
                 dtype=float)
    assert list(F.pick_slot("cube", d)) == [0, 1, 2, 3, 0, 1, 0, 1]


def test_paraboloid_side_frames_match_documented_rows():
    """Side 0 rows are (+X, -Y, -Z) of the light, side 1 rows (+X, +Y, +Z), in world."""
    rot = _random_rotation(np.random.default_rng(11))
    side0, side1 = F.light_layers(_light("omni", rot), "dpsm")
    assert np.allclose(side0.rotation, np.stack([rot[:, 0], -rot[:, 1], -rot[:, 2]]), atol=1e-12)
    assert np.allclose(side1.rotation, rot.T, atol=1e-12)


def test_pick_slot_keeps_batch_shape():
    """pick_slot works on (..., 3) arrays."""
    d = np.random.default_rng(2).normal(size=(3, 4, 3))
    assert F.pick_slot("cube", d).shape == (3, 4)
    assert F.pick_slot("dpsm", d).shape == (3, 4)


# ---------------------------------------------------------------- emission


def test_in_emission_hemi_is_half_space_along_axis():
    """A hemi light emits into offsets with a positive component along its axis only."""
    light = LightSpec("hemi", look_at((0.0, 0.0, 2.0), (1.0, 0.0, 2.0)))  # axis +X
    offs = np.array([[1.0, 0.0, 0.0], [0.1, 5.0, -3.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 1.0], [-1e-9, 1.0, 0.0]])
    assert list(F.in_emission(light, offs)) == [True, True, False, False, False]


def test_in_emission_omni_is_everything():
    """An omni light emits everywhere; the result keeps the batch shape."""
    light = LightSpec("omni", np.eye(4))
    offs = np.random.default_rng(0).normal(size=(5, 2, 3))
    got = F.in_emission(light, offs)
    assert got.shape == (5, 2) and got.all()


@FAST
@given(seeds)
def test_hemi_emission_lies_in_kept_layers(seed):
    """Every emitted direction of a hemi light picks a slot the hemi light has."""
    rng = np.random.default_rng(seed)
    light = _light("hemi", _random_rotation(rng))
    world = rng.normal(size=(300, 3))
    world = world[F.in_emission(light, world)]
    local = world @ light.rotation  # world -> light local
    for par in ("dpsm", "cube"):
        kept = {layer.slot for layer in F.light_layers(light, par)}
        assert set(np.unique(F.pick_slot(par, local))) <= kept


def test_scaled_light_matrix_keeps_unit_axis():
    """A scaled / sheared light matrix still yields a unit axis and proper rotation."""
    m = np.eye(4)
    m[:3, :3] = np.diag([2.0, 3.0, 0.5]) @ orthonormalize(np.array([[1, 0.1, 0], [0, 1, 0], [0, 0, 1.0]]))
    light = LightSpec("hemi", m)
    assert np.linalg.norm(light.axis) == pytest.approx(1.0, abs=1e-12)
    assert np.linalg.det(light.rotation) == pytest.approx(1.0, abs=1e-12)
    assert math.isclose(float(np.linalg.norm(F.light_layers(light, "dpsm")[0].rotation[2])), 1.0, abs_tol=1e-12)
