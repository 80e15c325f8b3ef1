"""Hair and points as the GPU keeps them (resident.set_pieces): each curve's pieces stay
together with their run, what cannot be drawn is counted out, and the texels carry what
lib/vertex_pull.glsl reads."""
from __future__ import annotations

import numpy as np

from addon.core.blockers import Spheres, Strands, pieces
from addon.render.resident import ResidentScene


def _scene():
    rng = np.random.default_rng(4)
    strands = Strands(rng.normal(size=(40, 3)), rng.uniform(0.01, 0.02, 40), np.arange(0, 41, 5))
    spheres = Spheres(rng.normal(size=(6, 3)) * 3.0, np.r_[rng.uniform(0.05, 0.1, 4), 0.0, np.nan])
    held = pieces(spheres, strands)
    scene = ResidentScene()
    part = scene.set_pieces("fur", held)
    return held, scene, part


def test_curves_stay_whole_and_know_their_run():
    held, scene, part = _scene()
    assert part.pieces and scene.pieces == len(held) - 2 and scene.triangles == 0
    assert part.counts.nonfinite == 1 and part.counts.degenerate == 1  # the NaN and the 0 radius
    data = part.piece_data
    first, count = data[:, 2].astype(int), data[:, 3].astype(int)
    index = np.arange(len(data))
    assert np.all((first <= index) & (index < first + count))  # each piece lies in its run
    # A run is a whole curve: as many pieces as the curve had, ends joined within it.
    a = part.local[:, 0] + part.origin
    b = part.local[:, 1] + part.origin
    sizes = np.bincount(held.curve, minlength=held.curve.max() + 1)
    for start in np.unique(first):
        n = count[start]
        assert n in sizes
        assert np.allclose(b[start:start + n - 1], a[start + 1:start + n])


def test_the_texels_carry_radii_and_runs():
    _, _, part = _scene()
    texels = part.vertex_texels().reshape(-1, 4)
    data = part.piece_data
    assert np.allclose(texels[0:6 * len(data):6, 3], data[:, 0])  # a's hi texel: ra
    assert np.allclose(texels[1:6 * len(data):6, 3], data[:, 2])  # a's lo texel: the run's first
    assert np.allclose(texels[2:6 * len(data):6, 3], data[:, 1])  # b's hi texel: rb
    assert np.allclose(texels[3:6 * len(data):6, 3], data[:, 3])  # b's lo texel: the run's count
    lo, hi = ResidentScene.bounds(_scene()[1])
    assert np.all(hi - lo > 0.0)


def test_pieces_are_not_triangles_for_the_host():
    _, scene, _ = _scene()
    assert len(scene.world_triangles()) == 0  # measurement and unfold see no pieces
