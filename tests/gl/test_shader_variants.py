"""The plain (no-warp) variants of the depth and shadow-test programs.

They exist for speed on software rasterisers; these tests check that they really
drop the warp code, are picked only without a warp, and give the same frames as the
full programs, including when both kinds alternate in one backend.
"""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.scene import SceneBuilder
from addon.render.moderngl_backend import ModernGLBackend
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from addon.render.shaders import (
    DEPTH_PLAIN_PROGRAM,
    DEPTH_PROGRAM,
    NO_WARP_DEFINE,
    SHADOW_TEST_PLAIN_PROGRAM,
    SHADOW_TEST_PROGRAM,
    glsl_header,
    warp_variant,
)
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


def test_variant_choice_follows_the_warp_uniform():
    assert warp_variant(DEPTH_PROGRAM, {"ow_warp_size": 0}) is DEPTH_PLAIN_PROGRAM
    assert warp_variant(DEPTH_PROGRAM, {}) is DEPTH_PLAIN_PROGRAM
    assert warp_variant(DEPTH_PROGRAM, {"ow_warp_size": 128}) is DEPTH_PROGRAM
    assert warp_variant(SHADOW_TEST_PROGRAM, {"ow_warp_size": 0}) is SHADOW_TEST_PLAIN_PROGRAM
    assert warp_variant(SHADOW_TEST_PROGRAM, {"ow_warp_size": 64}) is SHADOW_TEST_PROGRAM


def test_plain_variants_share_the_interface_but_not_the_name():
    for full, plain in ((DEPTH_PROGRAM, DEPTH_PLAIN_PROGRAM), (SHADOW_TEST_PROGRAM, SHADOW_TEST_PLAIN_PROGRAM)):
        assert plain.name != full.name  # backends cache programs by name
        assert (plain.uniforms, plain.samplers, plain.vertex_in) == (full.uniforms, full.samplers, full.vertex_in)
        assert f"#define {NO_WARP_DEFINE} 1" in glsl_header(plain, "fragment")
        assert NO_WARP_DEFINE not in glsl_header(full, "fragment")


def test_plain_variants_compile_the_warp_out(gl_backend):
    """The GLSL compiler drops unused samplers: the warp tables vanish only from the plain programs."""
    for full, plain in ((DEPTH_PROGRAM, DEPTH_PLAIN_PROGRAM), (SHADOW_TEST_PROGRAM, SHADOW_TEST_PLAIN_PROGRAM)):
        assert "ow_warp_rows" in gl_backend.program(full)
        assert "ow_warp_rows" not in gl_backend.program(plain)


def _scene():
    b = SceneBuilder("variants", (48, 36))
    b.plane("floor", (0, 0, 0), 8, 8)
    b.box("box", (0.5, 0.3, 0.6), (0.8, 0.8, 1.2))
    b.point_light((0.2, -0.4, 3.0))
    b.camera((4.0, -5.0, 4.0), (0.0, 0.0, 0.5))
    return b.finish()


def test_alternating_plain_and_warped_frames_match_fresh_backends(gl_backend):
    """A backend that drew a plain frame must still draw a warped one with the warp (and back).

    moderngl binds a vertex array to one program, so a cache shared by the two
    shadow-test variants once rendered warped frames with the plain program.
    """
    scene = _scene()
    samples, _, _ = view_samples(scene)
    tris = scene.world_triangles()
    plain = ShadowSettings("dpsm", 128)
    warped = ShadowSettings("dpsm", 128, warp="notw")

    def fresh(settings):
        backend = ModernGLBackend()
        try:
            return ShadowPipeline(backend).render(scene.light, tris, samples, settings).visibility
        finally:
            backend.release()

    expected_plain, expected_warped = fresh(plain), fresh(warped)
    assert not np.array_equal(expected_plain, expected_warped)  # the warp changes some pixel
    pipe = ShadowPipeline(gl_backend)
    for settings, expected in ((plain, expected_plain), (warped, expected_warped), (plain, expected_plain)):
        got = pipe.render(scene.light, tris, samples, settings).visibility
        assert np.array_equal(got, expected)
