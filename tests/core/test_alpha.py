"""core/alpha.py: Cycles' image lookup, the transfer, surfaces and the exact pass's word."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import alpha
from addon.core.alpha import AlphaMap, Surface
from addon.core.errors import InputError


def test_closest_reads_the_texel_under_the_uv():
    image = np.arange(6, dtype=np.float32).reshape(2, 3) / 5.0  # row 0 is v = 0
    amap = AlphaMap("m", image, "closest", "repeat")
    assert amap.sample(np.array([0.1, 0.1])) == pytest.approx(0.0)
    assert amap.sample(np.array([0.9, 0.9])) == pytest.approx(1.0)
    assert amap.sample(np.array([1.1, 0.1])) == pytest.approx(0.0)  # repeats
    assert AlphaMap("m", image, "closest", "clip").sample(np.array([1.1, 0.1])) == 0.0
    assert AlphaMap("m", image, "closest", "extend").sample(np.array([1.1, 0.1])) == pytest.approx(0.4)
    # Mirror: just past u = 1 reads the last column again.
    assert AlphaMap("m", image, "closest", "mirror").sample(np.array([1.1, 0.1])) == pytest.approx(0.4)


def test_linear_blends_texel_centres():
    image = np.array([[0.0, 1.0]], dtype=np.float32)
    amap = AlphaMap("m", image, "linear", "extend")
    assert amap.sample(np.array([0.25, 0.5])) == pytest.approx(0.0)  # the first centre
    assert amap.sample(np.array([0.5, 0.5])) == pytest.approx(0.5)
    assert amap.sample(np.array([0.75, 0.5])) == pytest.approx(1.0)
    # Clip blends with zero outside the image.
    assert AlphaMap("m", image, "linear", "clip").sample(np.array([1.0, 0.5])) == pytest.approx(0.5)


def test_transfer_bakes_a_step():
    step = (np.linspace(0, 1, alpha.TRANSFER_SIZE) > 0.5).astype(np.float32)
    amap = AlphaMap("m", np.array([[0.3, 0.7]], np.float32), "closest", "repeat", step)
    assert amap.sample(np.array([[0.2, 0.5], [0.8, 0.5]])).tolist() == [0.0, 1.0]


def test_constant_and_opaque():
    assert AlphaMap.constant("c", 0.5).sample(np.array([3.0, -2.0])) == pytest.approx(0.5)
    assert AlphaMap.constant("c", 1.0).opaque
    assert not AlphaMap.constant("c", 0.5).opaque
    assert AlphaMap.constant("a", 0.5).digest == AlphaMap.constant("b", 0.5).digest
    assert AlphaMap.constant("a", 0.5).digest != AlphaMap.constant("a", 0.25).digest


def test_bad_maps_are_refused():
    with pytest.raises(InputError, match="interpolation"):
        AlphaMap("m", np.ones((2, 2)), "cubic")
    with pytest.raises(InputError, match="NaN"):
        AlphaMap("m", np.full((2, 2), np.nan))
    with pytest.raises(InputError, match="material index"):
        Surface(np.zeros((2, 3, 2)), np.array([0, 1]), (AlphaMap.constant("c", 0.5),))


def test_surfaces_concatenate_with_shared_maps():
    half = AlphaMap.constant("a", 0.5)
    a = Surface(np.zeros((2, 3, 2)), np.array([0, -1]), (half,))
    b = Surface(np.ones((1, 3, 2)), np.array([0]), (AlphaMap.constant("b", 0.5),))
    both = Surface.concatenate([a, b])
    assert len(both.maps) == 1 and both.material.tolist() == [0, -1, 0]
    assert both.see_through and not Surface.opaque(3).see_through


def test_hits_word_is_the_product_of_transmittances():
    alphas = np.array([0.5, 0.3, 0.8])
    words = np.round(-np.log(1.0 - alphas) * alpha.OPTICAL_SCALE).astype(np.uint64).sum()
    got = alpha.hits_visibility(np.array([words], dtype=np.uint32))[0]
    assert got == pytest.approx(alpha.transmittance(alphas), abs=1e-4)
    assert alpha.hits_visibility(np.array([alpha.HIT_OPAQUE | 5], dtype=np.uint32))[0] == 0.0
    assert alpha.hits_visibility(np.array([0], dtype=np.uint32))[0] == 1.0


def test_reference_surface_round_trips(tmp_path):
    """A reference keeps its see-through materials through save and load; an opaque one
    stores none of the fields."""
    from addon.core.scene import look_at
    from addon.reference.data import ReferenceData

    w, h = 8, 6
    leaf = AlphaMap("leaf", np.eye(4, dtype=np.float32), "linear", "clip",
                    np.linspace(0.0, 1.0, alpha.TRANSFER_SIZE) ** 3)
    surface = Surface(np.random.default_rng(1).uniform(size=(3, 3, 2)), np.array([0, -1, 1]),
                      (leaf, AlphaMap.constant("curtain", 0.5)))

    def reference(surface):
        return ReferenceData(position=np.zeros((h, w, 3)), normal=np.zeros((h, w, 3)), hit=np.zeros((h, w), bool),
                             shadowed=np.zeros((h, w)), unshadowed=np.zeros((h, w)), triangles=np.zeros((3, 3, 3)),
                             light_matrix=np.eye(4), emission="omni", camera_matrix=look_at((0, -5, 1), (0, 0, 0)),
                             camera_fov_deg=50.0, resolution=(w, h), surface=surface)

    loaded = ReferenceData.load(reference(surface).save(tmp_path / "alpha.npz")).surface
    assert loaded is not None and [m.digest for m in loaded.maps] == [m.digest for m in surface.maps]
    assert np.array_equal(loaded.material, surface.material) and np.array_equal(loaded.uvs, surface.uvs)
    plain = reference(None).save(tmp_path / "plain.npz")
    with np.load(plain) as npz:
        assert "material" not in npz.files
    assert not ReferenceData.load(plain).scene_surface().see_through


def test_the_judgement_leaves_fractional_pixels_to_the_soft_error():
    from addon.core import metrics

    unshadowed = np.ones((1, 4))
    shadowed = np.array([[0.0, 1.0, 0.5, 0.5]])  # shadow, lit, and a curtain's half light twice
    evaluable = np.ones((1, 4), bool)
    judged = metrics.judge(np.array([[0.0, 1.0, 0.0, 0.5]]), shadowed, unshadowed, evaluable)
    assert judged.figure.error_pct == 0.0 and judged.figure.evaluated_pixels == 2
    assert judged.fractional_pixels == 2
    assert judged.fractional_soft_error_pct == pytest.approx(25.0)  # |0 - 0.5| and 0, halved
    assert judged.soft_error_pct == pytest.approx(12.5)
    opaque = metrics.judge(np.array([[0.0, 0.0, 1.0, 1.0]]), np.array([[0.0, 1.0, 1.0, 0.0]]), unshadowed, evaluable)
    assert opaque.fractional_pixels == 0 and opaque.fractional_soft_error_pct is None
    assert opaque.figure.error_pct == pytest.approx(50.0) == opaque.soft_error_pct
