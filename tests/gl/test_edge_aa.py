"""Edge-distance antialiasing (unfold+aa): the GLSL passes against a numpy oracle."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.metrics import soft_error_pct
from addon.render.pipeline import ShadowPipeline, ShadowSettings, edge_aa_parameters
from addon.render.frame import Measure
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


def edge_distance_oracle(atlas: np.ndarray, tile: int, radius: int, eps: float) -> np.ndarray:
    """X then Z of the paper, one texel at a time, searches clipped to each tile."""
    height, width = atlas.shape
    x = np.full(atlas.shape, radius + 1.0)
    for j in range(height):
        for i in range(width):
            ti = (i // tile) * tile
            for d in range(1, radius + 1):
                for k in (i - d, i + d):
                    if ti <= k < ti + tile and atlas[j, k] <= atlas[j, i] - eps:
                        x[j, i] = min(x[j, i], d)
    z = np.full(atlas.shape, radius + 1.0)
    for j in range(height):
        tj = (j // tile) * tile
        for i in range(width):
            for h in range(j - radius, j + radius + 1):
                if tj <= h < tj + tile:
                    z[j, i] = min(z[j, i], abs(h - j) + x[h, i])
    return np.minimum(z, radius + 1.0)


def _scene():
    from addon.core.scene import SceneBuilder

    b = SceneBuilder("aa", (64, 48))
    b.plane("floor", (0, 0, 0), 10, 10)
    b.box("box", (0.6, 0.2, 0.6), (0.8, 0.8, 1.2))
    b.point_light((0.0, 0.0, 2.5))
    b.camera((4, -4, 3), (0, 0, 0.3), fov_deg=60)
    return b.finish()


def test_edge_passes_match_numpy(gl_backend):
    """The two GPU passes over a real unfold atlas equal the paper's X/Z recurrence."""
    scene = _scene()
    samples, _, _ = view_samples(scene)
    res = 32
    pipe = ShadowPipeline(gl_backend)
    result = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("unfold", res),
                         measure=Measure(keep_atlas=True))
    # At 32 texels the automatic eps would exceed the whole depth range; pick values
    # that make edges to find, and run the passes on the atlas just drawn.
    radius, eps = 3, 0.02
    gl_backend.edge_distance(radius, eps)
    with gl_backend.ctx:
        raw = gl_backend.textures["ow_edges"].read()  # the test reads the backend's own target
    got = np.frombuffer(raw, dtype="f4").reshape(result.atlas.shape)
    expected = edge_distance_oracle(result.atlas.astype(np.float64), res, radius, eps)
    assert np.any(expected <= radius)  # the box's silhouette makes edges to find
    assert np.array_equal(got, expected.astype(np.float32))


def test_aa_softens_but_never_flips_a_sample(gl_backend):
    """unfold+aa classifies every sample as unfold does; some lit samples near shadow
    edges are dimmed to a value in (0.5, 1)."""
    scene = _scene()
    samples, lit, evaluable = view_samples(scene)
    pipe = ShadowPipeline(gl_backend)
    plain = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("unfold", 256))
    soft = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("unfold", 256, edge_aa=True))
    assert np.array_equal(plain.visibility > 0.5, soft.visibility > 0.5)
    dimmed = (soft.visibility > 0.5) & (soft.visibility < 1.0)
    assert dimmed.sum() > 10
    assert soft_error_pct(soft.visibility, lit, evaluable) > soft_error_pct(plain.visibility, lit, evaluable)


@pytest.mark.parametrize("res,radius", [(256, 2), (512, 2), (1024, 4), (2048, 8), (4096, 16)])
def test_aa_parameters_follow_the_resolution(res, radius):
    r, eps = edge_aa_parameters(res, 1.0, 11.0)
    assert r == radius
    # eps covers a smooth 80-degree slope over R texels at the far distance (normalised).
    assert eps == pytest.approx(r * np.tan(np.radians(80.0)) * np.pi * 2.0 / res * 11.0 / 10.0)


def test_aa_is_an_unfold_option():
    from addon.core.errors import InputError

    with pytest.raises(InputError, match="unfold"):
        ShadowSettings("dpsm", 512, edge_aa=True)
