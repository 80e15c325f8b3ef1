"""The ray caster every GL test checks against (tests/support/oracle.py) gives what testing
every ray against every triangle gives, nearest hit and lowest index among ties, though it
tests each chunk of triangles only against the rays that pass its bounding sphere."""
from __future__ import annotations

import numpy as np

from tests.support.oracle import CHUNK, ray_hits


def _every_pair(origins, dirs, tris, t_max=None, eps=1e-9):
    """Moller-Trumbore over every (ray, triangle) pair: the nearest, the first index among ties."""
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    pvec = np.cross(dirs[:, None, :], e2[None])
    det = np.einsum("tk,rtk->rt", e1, pvec)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tvec = origins[:, None, :] - v0[None]
    u = np.einsum("rtk,rtk->rt", tvec, pvec) * inv
    qvec = np.cross(tvec, e1[None])
    v = np.einsum("rk,rtk->rt", dirs, qvec) * inv
    t = np.einsum("tk,rtk->rt", e2, qvec) * inv
    limit = np.full(len(origins), np.inf) if t_max is None else t_max
    t = np.where(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > eps) & (t < limit[:, None]), t, np.inf)
    k = np.argmin(t, axis=1)
    best = t[np.arange(len(origins)), k]
    return best, np.where(np.isfinite(best), k, -1)


def test_a_soup_of_triangles_gives_every_pairs_answer():
    rng = np.random.default_rng(3)
    tris = rng.normal(size=(3 * CHUNK, 3, 3))
    origins, dirs = rng.normal(size=(300, 3)) * 3.0, rng.normal(size=(300, 3))
    t_max = rng.uniform(0.5, 8.0, 300)
    for limit in (None, t_max):
        got, want = ray_hits(origins, dirs, tris, t_max=limit), _every_pair(origins, dirs, tris, limit)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert np.isfinite(got[0]).sum() > 20  # the rays hit something


def test_ties_on_shared_edges_go_to_the_lowest_index():
    """Rays straight down through a grid's vertices meet several triangles at one distance."""
    rng = np.random.default_rng(4)
    xs = np.linspace(0.0, 1.0, 33)
    grid = np.stack(np.meshgrid(xs, xs, indexing="ij"), axis=-1)
    points = np.concatenate([grid, np.zeros(grid.shape[:2] + (1,))], axis=-1)
    quads = np.stack([points[:-1, :-1], points[:-1, 1:], points[1:, 1:], points[1:, :-1]], axis=2).reshape(-1, 4, 3)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])[rng.permutation(2 * len(quads))]
    origins = np.concatenate([rng.choice(xs, (500, 2)), np.ones((500, 1))], axis=1)
    dirs = np.tile([0.0, 0.0, -1.0], (500, 1))
    got, want = ray_hits(origins, dirs, tris), _every_pair(origins, dirs, tris)
    assert len(tris) > 4 * CHUNK and np.isfinite(want[0]).all()
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
