"""gpu_shaders/ray_share.frag (scripts/ray_cost.py's pass) against its numpy oracle: each
sample's weighed share of an area light's points whose segment no triangle crosses, the
same whether the walks finish in one turn or are cut into many."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import light_shape, ray_tree
from addon.render.passes.exact import EXACT_EPS
from scripts.ray_cost import shares

pytestmark = pytest.mark.gl


def _scene():
    """A floor 2 m below a 1.2 x 0.8 m area light (its frame), 40 small triangles between."""
    rng = np.random.default_rng(7)
    ys, xs = np.mgrid[0:10, 0:12]
    position = np.stack([(xs - 5.5) * 0.3, (ys - 4.5) * 0.3, np.full(xs.shape, -2.0)], axis=-1)
    normal = np.broadcast_to([0.0, 0.0, 1.0], position.shape).copy()
    hit = np.ones(xs.shape, dtype=bool)
    hit[0, :3] = False  # off geometry: no light share to compute
    centres = rng.uniform([-1.5, -1.2, -1.6], [1.5, 1.2, -0.4], (40, 1, 3))
    triangles = centres + rng.normal(scale=0.18, size=(40, 3, 3))
    points = light_shape.stratified_points(light_shape.Area("rectangle", 1.2, 0.8), 16)
    return triangles, position, normal, hit, points


def _oracle(triangles, position, normal, hit, points):
    out = np.ones(hit.shape)
    for y, x in zip(*np.nonzero(hit)):
        p, n = position[y, x].astype(np.float32).astype(np.float64), normal[y, x]
        lit = total = 0.0
        for q in points.astype(np.float32).astype(np.float64):
            d = q - p
            length = np.linalg.norm(d)
            weight = max(d @ n, 0.0) * max(d[2], 0.0) / length ** 4
            total += weight
            lit += 0.0 if ray_tree.crossings(triangles.astype(np.float32), p, d, EXACT_EPS).any() else weight
        out[y, x] = lit / total if total > 0.0 else 1.0
    return out


@pytest.mark.parametrize("budget", [None, 40])
def test_shares_match_the_oracle_in_one_turn_or_many(gl_backend, budget):
    scene = _scene()
    expected = _oracle(*scene)
    with gl_backend.ctx:
        got = shares(gl_backend.ctx, *scene, **({} if budget is None else {"budget": budget}))
    assert 0.2 < np.mean(expected[scene[3]] < 1.0) < 0.95  # penumbrae, umbrae and light
    assert (got.turns == 1) if budget is None else (got.turns > 5)
    differ = np.abs(got.visibility - expected) > 1e-5
    assert np.count_nonzero(differ) <= 2  # float32 may decide a segment through an edge either way
    assert np.all(got.visibility[~scene[3]] == 1.0)
