"""The light's own size (core/light_shape.py) and its place in LightSpec and the metrics."""
from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core import metrics
from addon.core.errors import InputError
from addon.core.light_shape import (
    POINT,
    Area,
    Sphere,
    SunDisk,
    shape_from_dict,
    stratified_points,
    stratified_unit_square,
    unit_disk,
)
from addon.core.scene import LightSpec, translation

SHAPES = (POINT, Sphere(0.25), SunDisk(math.radians(3.0)), Area("rectangle", 1.2, 0.8),
          Area("ellipse", 1.0, 0.5, math.radians(60.0)))


@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.describe())
def test_shape_round_trips_through_its_dict(shape):
    assert shape_from_dict(shape.as_dict()) == shape


def test_missing_shape_is_a_hard_point():
    assert shape_from_dict(None) is POINT and not POINT.sized
    with pytest.raises(InputError, match="unknown light shape"):
        shape_from_dict({"kind": "torus"})
    with pytest.raises(InputError, match="light shape"):
        shape_from_dict({"kind": "sphere", "diameter": 1.0})


@pytest.mark.parametrize("bad", [lambda: Sphere(-0.1), lambda: Sphere(float("nan")), lambda: SunDisk(math.pi),
                                 lambda: Area("triangle", 1.0, 1.0), lambda: Area("rectangle", -1.0, 1.0)])
def test_bad_sizes_are_refused(bad):
    with pytest.raises(InputError):
        bad()


def test_zero_sizes_are_not_sized():
    assert not Sphere(0.0).sized and not SunDisk(0.0).sized and not Area("rectangle", 0.0, 0.0).sized
    assert Sphere(0.01).sized and Area("ellipse", 0.1, 0.0).sized


def test_the_shape_must_fit_the_emission():
    matrix = translation((0.0, 0.0, 3.0))
    LightSpec("omni", matrix, shape=Sphere(0.2))
    LightSpec("hemi", matrix, shape=Area("rectangle", 1.0, 1.0))
    LightSpec("sun", matrix, shape=SunDisk(0.01))
    for emission, shape in (("omni", Area("rectangle", 1.0, 1.0)), ("sun", Sphere(0.2)), ("omni", SunDisk(0.1))):
        with pytest.raises(InputError, match="cannot have the shape"):
            LightSpec(emission, matrix, shape=shape)
    assert LightSpec("omni", matrix, shape=Sphere(0.2)).sized and not LightSpec("omni", matrix).sized


def test_stratified_square_puts_one_point_per_cell():
    for n in (1, 7, 64, 100):
        uv = stratified_unit_square(n)
        assert uv.shape == (n, 2) and np.all((uv >= 0.0) & (uv < 1.0))
        cols = math.ceil(math.sqrt(n))
        rows = math.ceil(n / cols)
        cells = set(map(tuple, np.floor(uv * [cols, rows]).astype(int)))
        assert len(cells) == n
    assert np.array_equal(stratified_unit_square(64), stratified_unit_square(64))  # fixed, not random
    with pytest.raises(InputError):
        stratified_unit_square(0)


def test_concentric_map_keeps_areas():
    # A uniform grid of the square maps to a disk whose rings hold points in proportion
    # to their area: the inner half radius holds a quarter.
    g = (np.stack(np.meshgrid(np.arange(200), np.arange(200)), -1).reshape(-1, 2) + 0.5) / 200
    xy = unit_disk(g)
    r = np.linalg.norm(xy, axis=1)
    assert r.max() <= 1.0 + 1e-12
    assert abs(np.mean(r < 0.5) - 0.25) < 0.01


def test_points_lie_on_their_emitter_and_fill_it():
    n = 256
    rect = stratified_points(Area("rectangle", 1.2, 0.8), n)
    assert np.all(np.abs(rect[:, 0]) <= 0.6) and np.all(np.abs(rect[:, 1]) <= 0.4) and np.all(rect[:, 2] == 0)
    assert np.abs(rect[:, :2].mean(axis=0)).max() < 0.02
    assert rect[:, 0].max() > 0.55 and rect[:, 1].min() < -0.35  # reaches the corners' sides
    ell = stratified_points(Area("ellipse", 1.0, 0.5), n)
    assert np.all((ell[:, 0] / 0.5) ** 2 + (ell[:, 1] / 0.25) ** 2 <= 1.0 + 1e-9)
    disk = stratified_points(Sphere(0.3), n)
    assert np.all(np.linalg.norm(disk[:, :2], axis=1) <= 0.3 + 1e-12)
    sun = stratified_points(SunDisk(math.radians(10.0)), n)
    assert np.allclose(np.linalg.norm(sun, axis=1), 1.0)
    assert np.all(sun[:, 2] >= math.cos(math.radians(5.0)) - 1e-12)
    assert np.all(stratified_points(POINT, 4) == 0.0)


def test_a_sized_judgement_counts_the_penumbra_and_reports_the_noise():
    # Reference visibility 0.4 on half the pixels (a penumbra), 1 elsewhere; the estimate
    # is lit everywhere. A hard light's figure leaves the fractional half out, a sized one
    # counts it as the pixels on the wrong side of 0.5.
    un = np.ones((4, 4))
    sh = np.ones((4, 4))
    sh[:2] = 0.4
    ev = np.ones((4, 4), bool)
    estimate = np.ones((4, 4))
    hard = metrics.judge(estimate, sh, un, ev)
    sized = metrics.judge(estimate, sh, un, ev, sized=True, noise=np.full((4, 4), 0.01))
    assert hard.figure.error_pct == 0.0 and hard.reference_noise_pct is None
    assert sized.figure.error_pct == pytest.approx(50.0) and sized.figure.false_lit_pct == pytest.approx(50.0)
    assert sized.soft_error_pct == pytest.approx(30.0) == hard.soft_error_pct
    assert sized.reference_noise_pct == pytest.approx(1.0)
    assert sized.columns()["reference_noise_pct"] == pytest.approx(1.0)
