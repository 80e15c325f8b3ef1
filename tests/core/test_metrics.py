"""The error figure against the reference (addon/core/metrics.py, docs/design.md section 5)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core import metrics as M
from addon.core.scene import LightSpec, look_at, translation


# ---------------------------------------------------------------- reference visibility


def test_reference_visibility_threshold_at_half():
    """Visible iff shadowed / unshadowed >= 0.5 (the threshold itself counts as lit)."""
    un = np.full(6, 2.0)
    sh = np.array([0.0, 0.999, 1.0, 1.001, 2.0, 2.5])
    assert M.reference_visibility(sh, un).tolist() == [False, False, True, True, True, True]


def test_reference_visibility_needs_unshadowed_light_above_eps():
    """Where unshadowed <= eps the pixel is never visible (no division by ~0)."""
    eps = M.UNSHADOWED_EPS
    un = np.array([0.0, eps, eps * 1.5, -1.0, 1e-3])
    sh = np.array([0.0, eps, eps * 1.5, -1.0, 1e-3])
    with np.errstate(all="raise"):
        got = M.reference_visibility(sh, un)
    assert got.tolist() == [False, False, True, False, True]
    # A custom eps moves the cut-off.
    assert M.reference_visibility(sh, un, eps=1e-2).tolist() == [False] * 5


def test_reference_visibility_keeps_image_shape():
    """(H, W) in, (H, W) bool out."""
    got = M.reference_visibility(np.ones((3, 4)), np.ones((3, 4)))
    assert got.shape == (3, 4) and got.dtype == bool and got.all()


# ---------------------------------------------------------------- evaluable mask


def _pixels():
    """Five pixels around an omni light at (0, 0, 2), row layout (1, 5)."""
    pos = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 0.0, 4.0]]])
    normal = np.array([[[0, 0, 1.0], [0, 0, -1.0], [0, 0, 1.0], [0, 0, 1.0], [0, 0, -1.0]]])
    hit = np.array([[True, True, False, True, True]])
    unshadowed = np.array([[1.0, 1.0, 1.0, 0.0, 1.0]])
    return pos, normal, hit, unshadowed


def test_evaluable_mask_omni():
    """Pixel 0 counts; 1 faces away from the light, 2 missed, 3 gets no light;
    4 is above the light and faces it, so it counts for an omni light."""
    pos, normal, hit, unshadowed = _pixels()
    light = LightSpec("omni", translation((0.0, 0.0, 2.0)))
    got = M.evaluable_mask(pos, normal, hit, unshadowed, light)
    assert got.tolist() == [[True, False, False, False, True]]


def test_evaluable_mask_hemi_excludes_behind_the_axis():
    """The same pixels for a hemi light pointing down: the pixel above it is out."""
    pos, normal, hit, unshadowed = _pixels()
    light = LightSpec("hemi", look_at((0.0, 0.0, 2.0), (0.0, 0.0, 0.0)))
    got = M.evaluable_mask(pos, normal, hit, unshadowed, light)
    assert got.tolist() == [[True, False, False, False, False]]
    # A receiver exactly level with the light (on the emission boundary) is out too.
    side = M.evaluable_mask(np.array([[5.0, 0.0, 2.0]]), np.array([[-1.0, 0.0, 0.0]]), np.array([True]),
                            np.array([1.0]), light)
    assert side.tolist() == [False]


def test_evaluable_mask_excludes_non_finite_positions():
    """NaN or inf positions never count, even if flagged as hits."""
    light = LightSpec("omni", translation((0.0, 0.0, 2.0)))
    pos = np.array([[np.nan, 0.0, 0.0], [0.0, np.inf, 0.0], [0.0, 0.0, 0.0]])
    normal = np.tile([0.0, 0.0, 1.0], (3, 1))
    got = M.evaluable_mask(pos, normal, np.ones(3, bool), np.ones(3), light)
    assert got.tolist() == [False, False, True]


def test_evaluable_mask_grazing_normal_is_out():
    """A receiver whose normal is perpendicular to the light direction does not face it."""
    light = LightSpec("omni", translation((0.0, 0.0, 2.0)))
    got = M.evaluable_mask(np.array([[1.0, 0.0, 2.0]]), np.array([[0.0, 0.0, 1.0]]), np.array([True]),
                           np.array([1.0]), light)
    assert got.tolist() == [False]


@pytest.mark.parametrize("emission", ["omni", "sun"])
def test_evaluable_mask_leaves_out_receivers_within_rounding_of_edge_on(emission):
    """Tilted by 2.6e-6 rad towards the light (sun_field's hay bale face), a receiver is out;
    by 1e-4 it counts. The rule reads the cosine, so the normal's length plays no part."""
    light = LightSpec(emission, look_at((0.0, 0.0, 50.0), (0.0, 0.0, 0.0)))
    pos = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    normal = np.array([[1.0, 0.0, 2.6e-6], [1.0, 0.0, 1e-4], [10.0, 0.0, 1e-3]])
    got = M.evaluable_mask(pos, normal, np.ones(3, bool), np.ones(3), light)
    assert got.tolist() == [False, True, True]
    assert 2.6e-6 < M.GRAZING_COS < 1e-4


def _ring(light_pos, angles_deg, distance: float = 5.0):
    """Receivers `distance` from the light at `angles_deg` from world -Z (in the x-z plane), facing it."""
    pos = []
    for a in np.radians(angles_deg):
        direction = np.array([math.sin(a), 0.0, -math.cos(a)])  # angle a from the -Z axis
        pos.append(np.asarray(light_pos, dtype=float) + distance * direction)
    pos = np.array(pos)
    normal = np.asarray(light_pos, dtype=float) - pos
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return pos, normal


def test_evaluable_mask_spot_keeps_only_the_cone():
    """A 60 degree spot pointing down: receivers within 30 degrees of the axis count, those
    beyond do not, though each faces the light and gets light."""
    light = LightSpec("spot", look_at((0.0, 0.0, 4.0), (0.0, 0.0, 0.0)), spot_size=math.radians(60.0))
    angles = [0.0, 10.0, 29.99, 30.01, 31.0, 60.0, 100.0]
    pos, normal = _ring((0.0, 0.0, 4.0), angles)
    got = M.evaluable_mask(pos, normal, np.ones(len(pos), bool), np.ones(len(pos)), light)
    assert got.tolist() == [True, True, True, False, False, False, False]
    # The same receivers under a hemi light: everything in front of the light counts.
    hemi = LightSpec("hemi", light.matrix_world)
    assert M.evaluable_mask(pos, normal, np.ones(len(pos), bool), np.ones(len(pos)), hemi).tolist() == \
        [True, True, True, True, True, True, False]


def test_evaluable_mask_spot_cone_follows_its_axis_and_keeps_other_rules():
    """A tilted spot: the cone test uses the light's axis, not world -Z; hit, facing and
    unshadowed still apply inside the cone; a receiver at the apex is out."""
    apex = np.array([1.0, 2.0, 3.0])
    light = LightSpec("spot", look_at(apex, apex + np.array([1.0, 0.0, 0.0])), spot_size=math.radians(40.0))
    on_axis = apex + np.array([3.0, 0.0, 0.0])
    off_axis = apex + 3.0 * np.array([math.cos(math.radians(25.0)), math.sin(math.radians(25.0)), 0.0])
    pos = np.array([on_axis, on_axis, on_axis, on_axis, off_axis, apex])
    normal = np.array([[-1.0, 0, 0], [-1.0, 0, 0], [1.0, 0, 0], [-1.0, 0, 0], [-1.0, 0, 0], [-1.0, 0, 0]])
    hit = np.array([True, False, True, True, True, True])
    unshadowed = np.array([1.0, 1.0, 1.0, 0.0, 1.0, 1.0])
    got = M.evaluable_mask(pos, normal, hit, unshadowed, light)
    assert got.tolist() == [True, False, False, False, False, False]


def test_evaluable_mask_spot_image_shape():
    """(H, W, 3) positions give an (H, W) mask; the cone cuts a disc out of a floor."""
    light = LightSpec("spot", look_at((0.0, 0.0, 2.0), (0.0, 0.0, 0.0)), spot_size=math.radians(90.0))
    xs = np.linspace(-4.0, 4.0, 9)
    gx, gy = np.meshgrid(xs, xs)
    pos = np.stack([gx, gy, np.zeros_like(gx)], axis=-1)
    normal = np.broadcast_to([0.0, 0.0, 1.0], pos.shape)
    got = M.evaluable_mask(pos, normal, np.ones(gx.shape, bool), np.ones(gx.shape), light)
    assert got.shape == (9, 9)
    # 45 degree half angle from 2 m up: the lit disc has radius 2 m (its rim excluded).
    assert np.array_equal(got, np.hypot(gx, gy) < 2.0 - 1e-9)


def test_evaluable_mask_sun_uses_its_direction_everywhere():
    """A sun travelling along (1, 0, -1): a receiver faces it when its normal points
    against that direction, wherever it is (the lamp's position plays no part)."""
    sun = LightSpec("sun", look_at((0.0, 0.0, 0.0), (1.0, 0.0, -1.0)))
    np.testing.assert_allclose(sun.axis, np.array([1.0, 0.0, -1.0]) / math.sqrt(2.0), atol=1e-12)
    pos = np.array([[0.0, 0.0, 0.0], [50.0, 0.0, 80.0], [-3.0, 9.0, 40.0], [0.0, 0.0, 0.0], [5.0, 5.0, 5.0],
                    [0.0, 0.0, 0.0]])
    normal = np.array([[0.0, 0.0, 1.0],  # a floor: lit from above
                       [0.0, 0.0, 1.0],  # a floor far above the lamp: still faces the sun
                       [-1.0, 0.0, 0.0],  # a wall facing -x, the way the light comes from
                       [1.0, 0.0, 0.0],  # a wall facing +x: away from the sun
                       [0.0, 0.0, -1.0],  # a ceiling: away
                       [0.0, 1.0, 0.0]])  # a wall parallel to the light: grazing, out
    n = len(pos)
    got = M.evaluable_mask(pos, normal, np.ones(n, bool), np.ones(n), sun)
    assert got.tolist() == [True, True, True, False, False, False]
    # An omni light at the lamp's origin lies below that floor: judged by position, it is out.
    omni = LightSpec("omni", sun.matrix_world)
    assert M.evaluable_mask(pos, normal, np.ones(n, bool), np.ones(n), omni)[1] == False  # noqa: E712


def test_evaluable_mask_sun_keeps_hit_unshadowed_and_finite_rules():
    """Misses, unlit and non-finite pixels never count under a sun either."""
    sun = LightSpec("sun", look_at((0.0, 0.0, 10.0), (0.0, 0.0, 0.0)))
    pos = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])
    normal = np.tile([0.0, 0.0, 1.0], (4, 1))
    got = M.evaluable_mask(pos, normal, np.array([True, False, True, True]), np.array([1.0, 1.0, 0.0, 1.0]), sun)
    assert got.tolist() == [True, False, False, False]


# ---------------------------------------------------------------- error figure


def test_error_figure_hand_made_example():
    """4 evaluated pixels: 1 false shadow, 1 false lit, 2 agree; mismatches outside the
    evaluated set do not count."""
    est = np.array([[True, False, True, False], [False, True, True, False]])
    ref = np.array([[True, True, False, False], [True, False, False, True]])
    ev = np.array([[True, True, True, True], [False, False, False, False]])
    fig = M.error_figure(est, ref, ev)
    assert fig.evaluated_pixels == 4
    assert fig.false_shadow_pct == pytest.approx(25.0)
    assert fig.false_lit_pct == pytest.approx(25.0)
    assert fig.error_pct == pytest.approx(50.0)


def test_error_figure_counts_direction_of_error():
    """All estimate-dark-but-reference-lit pixels are false shadow, the reverse false lit."""
    ref = np.array([True, True, True, False, False, True, False, False])
    est = np.array([False, False, False, True, False, True, False, False])
    fig = M.error_figure(est, ref, np.ones(8, bool))
    assert (fig.false_shadow_pct, fig.false_lit_pct, fig.error_pct) == pytest.approx((37.5, 12.5, 50.0))


def test_error_figure_zero_for_identical_maps():
    """Identical estimate and reference: no error."""
    rng = np.random.default_rng(0)
    lit = rng.random((16, 16)) < 0.5
    fig = M.error_figure(lit, lit.copy(), rng.random((16, 16)) < 0.7)
    assert (fig.error_pct, fig.false_shadow_pct, fig.false_lit_pct) == (0.0, 0.0, 0.0)
    assert fig.evaluated_pixels > 0


def test_error_figure_nothing_evaluated():
    """No evaluated pixel: a zero figure with 0 pixels, not a division by zero."""
    fig = M.error_figure(np.ones(4, bool), np.zeros(4, bool), np.zeros(4, bool))
    assert fig == M.ErrorFigure(0.0, 0.0, 0.0, 0)


# ---------------------------------------------------------------- mismatch image


def test_mismatch_image_paints_only_evaluated_mismatches():
    """False shadow red, false lit light red, every other pixel grey (R = G = B)."""
    grey = np.linspace(0.0, 2.0, 8).reshape(2, 4)
    est = np.array([[True, False, True, False], [True, False, True, False]])
    ref = np.array([[False, True, True, False], [True, True, False, True]])
    ev = np.array([[True, True, True, True], [True, False, False, True]])
    img = M.mismatch_image(grey, est, ref, ev)
    assert img.shape == (2, 4, 3) and img.dtype == np.uint8
    false_shadow = ev & ref & ~est
    false_lit = ev & ~ref & est
    assert false_shadow.tolist() == [[False, True, False, False], [False, False, False, True]]
    assert false_lit.tolist() == [[True, False, False, False], [False, False, False, False]]
    assert np.all(img[false_shadow] == (230, 20, 20))
    assert np.all(img[false_lit] == (255, 120, 120))
    others = ~(false_shadow | false_lit)
    assert np.all(img[others][:, 0] == img[others][:, 1]) and np.all(img[others][:, 1] == img[others][:, 2])
    # Red pixels are clearly red: R well above G and B.
    reds = img[false_shadow | false_lit].astype(int)
    assert np.all(reds[:, 0] - reds[:, 1] >= 100)


def test_mismatch_image_grey_is_monotone():
    """Brighter source, brighter grey, within the 0.15..0.85 band; inf saturates and an
    all-black source gives one uniform grey."""
    src = np.array([[0.0, 0.1, 0.5, 1.0, np.inf]])
    same = np.zeros((1, 5), bool)
    img = M.mismatch_image(src, same, same, same)
    g = img[0, :4, 0].astype(int)
    assert np.all(np.diff(g) > 0)
    assert img.min() >= int(0.15 * 255) - 1 and img.max() <= int(0.85 * 255) + 1
    assert np.all(img[0, 4] == img[0, 3])  # inf is clipped like the brightest pixel
    black = M.mismatch_image(np.zeros((2, 2)), np.zeros((2, 2), bool), np.zeros((2, 2), bool), np.zeros((2, 2), bool))
    assert np.all(black == black[0, 0, 0])


def test_mismatch_image_nan_source_pixel_is_defined_grey():
    """A NaN pixel in the grey source must still come out as a defined grey inside the
    0.15..0.85 band (like a black pixel), not an undefined float->uint8 cast of NaN."""
    src = np.array([[0.0, 0.5, np.nan, 1.0]])
    same = np.zeros((1, 4), bool)
    with np.errstate(invalid="raise"):
        img = M.mismatch_image(src, same, same, same)
    assert np.all(img[0, 2] == img[0, 0])


def test_float32_radial_depth_is_far_below_the_bias_at_every_ratio():
    """The storage rule of docs/stability.md: float32 keeps the stored radial distance
    within a tenth of the smallest bias even at near/far = 1e-6, while 24-bit fixed
    point fails from 1e-4 on; that is why depth is stored as R32F."""
    from scripts import depth_precision as precision

    bias = precision.constant_bias(4096)
    for ratio in precision.RATIOS:
        assert precision.relative_errors(ratio)["float32"] < 0.1 * bias
    assert precision.relative_errors(1e-4)["fixed24"] > 0.1 * bias
