"""Dual sphere-unfolding: one draw call, nearer-pole halves, seam complements."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.frames import light_layers
from addon.core.plan import plan_frame
from addon.core import samples as SS
from addon.core import projection, tessellate
from addon.core.errors import InputError
from addon.core.scene import LightSpec, SceneBuilder, look_at
from addon.render import unfold as pl
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from addon.render.frame import Measure
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


def _area(tris):
    return float(np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1).sum() / 2)


def _stream_halves(tris_world, light):
    plan = plan_frame(light, "unfold", None, SS.measure(None, light, np.zeros((1, 1, 3)), np.zeros((1, 1), bool)), 10.0)
    stream, split, _ = pl._unfold_stream(tris_world - light.position, plan, ShadowSettings("unfold", 64))
    positions = stream[:, :3].astype(np.float64)
    return positions[:split].reshape(-1, 3, 3), positions[split:].reshape(-1, 3, 3), plan


def test_whole_triangle_goes_to_its_nearer_pole_and_the_other_half_gets_its_far_piece():
    """A triangle mostly below the light (pole of half 0 is the light's -Z) is drawn
    whole into half 0; half 1 receives only its piece above the seam plane."""
    light = LightSpec("omni", np.eye(4))
    tri = np.array([[[1.0, 0.0, -2.0], [0.0, 1.0, -2.0], [1.0, 1.0, 0.5]]])  # centroid below, tip above
    half0, half1, _ = _stream_halves(tri, light)
    # Half 0: the whole triangle (tessellated, so compare areas), tip above the seam included.
    assert _area(half0) == pytest.approx(_area(tri), rel=1e-5) and half0[..., 2].max() > 0.49  # tip at 109 degrees: within UNFOLD_WHOLE_MAX_ANGLE
    # Half 1: the part with z >= 0, reaching past the seam by the overlap angle (and no more
    # than the part within twice that angle below it).
    overlap = pl.seam_overlap(projection.UNFOLD, 64)
    elevation = np.arcsin(half1[..., 2] / np.linalg.norm(half1, axis=2))
    above = tessellate.clip_halfspace(tri, tri[..., 2])
    band = tessellate.clip_halfspace(tri, tri[..., 2] + np.sin(2.0 * overlap) * np.linalg.norm(tri, axis=2))
    assert _area(above) * (1 - 1e-5) <= _area(half1) <= _area(band) * (1 + 1e-5)
    assert np.all(elevation >= -2.0 * overlap)
    below = np.array([[[1.0, 0.0, -2.0], [0.0, 1.0, -2.0], [-1.0, -1.0, -2.0]]])
    half0, half1, _ = _stream_halves(below, light)
    assert len(half0) >= 1 and len(half1) == 0


def test_triangle_over_the_opposite_pole_is_cut_at_the_seam():
    """A huge floor-like triangle above and below the light whose nearer pole's opposite
    pole it covers is not drawn whole (the projection is singular there)."""
    light = LightSpec("omni", np.eye(4))
    # Mostly below the light (nearer pole: -Z), yet it covers the +Z ray above the light.
    tri = np.array([[[-50.0, -50.0, -40.0], [50.0, -50.0, -40.0], [0.0, 60.0, 100.0]]])
    assert pl._contains_ray(tri, np.array([0.0, 0.0, 1.0]))[0]
    half0, half1, _ = _stream_halves(tri, light)
    # Cut at the seam, each piece reaching past it by the overlap angle only.
    reach = 2.0 * pl.seam_overlap(projection.UNFOLD, 64)
    assert np.all(np.arcsin(half0[..., 2] / np.linalg.norm(half0, axis=2)) <= reach)
    assert np.all(np.arcsin(half1[..., 2] / np.linalg.norm(half1, axis=2)) >= -reach)
    assert _area(half0) + _area(half1) >= _area(tri) * (1 - 1e-5)


def test_contains_ray():
    tri = np.array([[[-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [0.0, 1.0, 2.0]]])
    assert pl._contains_ray(tri, np.array([0.0, 0.0, 1.0]))[0]
    assert not pl._contains_ray(tri, np.array([0.0, 0.0, -1.0]))[0]
    assert not pl._contains_ray(tri + np.array([5.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))[0]


class _CountingBackend:
    """Forwards to a real backend and counts depth draws."""

    def __init__(self, inner):
        self._inner = inner
        self.draws = []

    def draw_layer(self, tile, vertices, uniforms, span=1):
        self.draws.append((tile, span, len(vertices)))
        return self._inner.draw_layer(tile, vertices, uniforms, span)

    def __getattr__(self, name):
        return getattr(self._inner, name)


@pytest.mark.parametrize("emission,halves", [("omni", 2), ("hemi", 1)])
def test_unfold_is_one_draw_call(gl_backend, emission, halves):
    """Both halves (or the one half of a hemispherical light) go out in one draw."""
    b = SceneBuilder("unfold_one_pass", (48, 36))
    b.plane("floor", (0, 0, 0), 10, 10)
    b.box("box", (0.5, 0.3, 0.5), (0.6, 0.6, 1.0))
    b.plane("ceiling", (0, 0, 4.0), 10, 10)
    if emission == "omni":
        b.point_light((0.0, 0.0, 2.0))
    else:
        b.hemi_light((0.0, 0.0, 2.0), (0.0, 0.0, 0.0))
    b.camera((4, -4, 3), (0, 0, 0.5), fov_deg=70)
    scene = b.finish()
    samples, lit, evaluable = view_samples(scene)
    backend = _CountingBackend(gl_backend)
    result = ShadowPipeline(backend).render(scene.light, scene.world_triangles(), samples,
                                            ShadowSettings("unfold", 256), measure=Measure(keep_atlas=True))
    assert result.passes == 1
    assert len(backend.draws) == 1 and backend.draws[0][1] == halves
    assert result.layout.tiles == halves
    assert np.all(np.isfinite(result.atlas))
    assert np.mean((result.visibility > 0.5)[evaluable] != lit[evaluable]) < 0.03


def test_unfold_layers_share_the_dpsm_poles():
    light = LightSpec("omni", look_at((1.0, 2.0, 3.0), (0.0, 0.0, 0.0)))
    for a, b in zip(light_layers(light, "unfold"), light_layers(light, "dpsm")):
        assert np.allclose(a.rotation, b.rotation)


def test_unfold_refuses_a_warp():
    with pytest.raises(InputError, match="unfold takes no warp"):
        ShadowSettings("unfold", 512, warp="notw")

