"""The variants of the depth and shadow-test programs: plain (no warp) and fixed-kind.

They exist for speed on software rasterisers; these tests check that they really
drop the code they claim to, are picked only when a frame allows it, and give the
same frames as the generic programs, including when variants alternate in one backend.
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from addon.core.errors import BackendError
from addon.core.scene import SceneBuilder
from addon.render.backends.moderngl.backend import ModernGLBackend
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from addon.render.backends.moderngl.glsl import glsl_header
from addon.render.shaders import (
    COMPUTE_PROGRAMS,
    DEPTH_PLAIN_PROGRAM,
    DEPTH_PROGRAM,
    FIXED_KIND_DEFINE,
    GBUFFER_PROGRAM,
    NO_WARP_DEFINE,
    SCATTER_MODE_DEFINE,
    SHADOW_TEST_PLAIN_PROGRAM,
    SHADOW_TEST_PROGRAM,
    VARIANT_PROGRAMS,
    load_source,
    program_variant,
    scatter_variant,
)
from addon.render.frame import Measure
from tests.support import glsl
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


def test_variant_choice_follows_the_warp_uniform():
    assert program_variant(DEPTH_PROGRAM, {"ow_warp_size": 0}) is DEPTH_PLAIN_PROGRAM
    assert program_variant(DEPTH_PROGRAM, {}) is DEPTH_PLAIN_PROGRAM
    assert program_variant(DEPTH_PROGRAM, {"ow_warp_size": 128}) is DEPTH_PROGRAM
    assert program_variant(SHADOW_TEST_PROGRAM, {"ow_warp_size": 0}) is SHADOW_TEST_PLAIN_PROGRAM
    assert program_variant(SHADOW_TEST_PROGRAM, {"ow_warp_size": 64}) is SHADOW_TEST_PROGRAM


@pytest.mark.parametrize("base", [DEPTH_PROGRAM, SHADOW_TEST_PROGRAM], ids=lambda i: i.name)
@pytest.mark.parametrize("warp_size", [0, 64])
def test_variant_choice_fixes_only_paraboloid_and_cube_frames(base, warp_size):
    def pick(**uniforms):
        return program_variant(base, {"ow_warp_size": warp_size, **uniforms})

    generic = pick()
    assert FIXED_KIND_DEFINE not in generic.defines
    for kind in (0, 1):
        fixed = pick(ow_layer_kind=kind, ow_projective=0, ow_unfold_split=-1)
        assert fixed.defines[FIXED_KIND_DEFINE] == str(kind)
        assert pick(ow_layer_kind=kind) is fixed  # built once
        # A projective (spot, sun) or unfold frame keeps the generic program.
        assert pick(ow_layer_kind=kind, ow_projective=1) is generic
        assert pick(ow_layer_kind=kind, ow_unfold_split=30) is generic
    assert pick(ow_layer_kind=2) is generic  # the unfold kind
    with pytest.raises(BackendError):
        program_variant(GBUFFER_PROGRAM, {})


def test_every_variant_has_its_own_name():
    names = [iface.name for iface in VARIANT_PROGRAMS]
    # 3 programs x (generic, 2 kinds) x (warped, plain), and the footprint point sprites x 2 kinds x 2
    assert len(set(names)) == len(names) == 22
    scatter_names = [iface.name for iface in COMPUTE_PROGRAMS]
    # the generic scatter and 3 modes x 3 kinds, the sample statistics, the barrier, the list advance, the segments'
    # walk, the 12 warp steps, the list linking x 3 kinds
    assert len(set(scatter_names)) == len(scatter_names) == 29


def test_scatter_variant_fixes_mode_and_kind():
    for mode in (0, 1, 2):
        generic = scatter_variant({"ow_scatter_mode": mode})
        assert generic.defines[SCATTER_MODE_DEFINE] == str(mode) and FIXED_KIND_DEFINE not in generic.defines
        assert scatter_variant({"ow_scatter_mode": mode, "ow_layer_kind": 2}) is generic  # unfold
        for kind in (0, 1):
            fixed = scatter_variant({"ow_scatter_mode": mode, "ow_layer_kind": kind})
            assert fixed.defines[FIXED_KIND_DEFINE] == str(kind) and fixed is not generic
    with pytest.raises(BackendError, match="scatter mode"):
        scatter_variant({"ow_scatter_mode": 3})


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


def test_fixed_kind_variants_compile_the_other_paths_out(gl_backend):
    """The spot/sun path is chosen only under `#ifndef OW_FIXED_KIND`: every read of its
    switch (`ow_projective`) sits there, so a fixed kind leaves the path unreachable and the
    compiler drops what only it calls (the projective matrix's readers among them). The
    uniforms themselves all stay declared: a std140 block keeps every member active, so
    this is checked on the source, and the fixed variants must compile."""
    for base in (DEPTH_PROGRAM, SHADOW_TEST_PROGRAM):
        generic = program_variant(base, {})
        assert FIXED_KIND_DEFINE not in generic.defines
        gl_backend.program(generic)
        for stage in (base.vertex_file, base.fragment_file):
            body = load_source(stage)
            code = [line.split("//")[0] for line in glsl.without_blocks(body, "#ifndef", FIXED_KIND_DEFINE).splitlines()]
            outside = [line for line in code if re.search(r"\bow_projective\b", line)]
            assert not outside, (stage, outside)
        assert any(re.search(r"\bow_projective\b", load_source(stage)) for stage in (base.vertex_file, base.fragment_file))
        for kind in (0, 1):
            fixed = program_variant(base, {"ow_layer_kind": kind})
            assert FIXED_KIND_DEFINE in fixed.defines
            gl_backend.program(fixed)


@pytest.mark.parametrize("settings", [ShadowSettings("dpsm", 128), ShadowSettings("cube", 96),
                                      ShadowSettings("dpsm", 128, warp="notw"),
                                      ShadowSettings("cube", 96, warp="notw")],
                         ids=["dpsm", "cube", "dpsm+notw", "cube+notw"])
def test_fixed_kind_variants_match_the_generic_programs(gl_backend, settings, monkeypatch):
    """Folding the kind to a constant changes no pixel and no texel."""
    import sys

    scene = _scene()
    samples, _, _ = view_samples(scene)
    tris = scene.world_triangles()
    fixed = ShadowPipeline(gl_backend).render(scene.light, tris, samples, settings, measure=Measure(keep_atlas=True))
    backend = ModernGLBackend()
    try:
        # Keep the warp choice, drop the kind: every frame takes the generic kind code, in
        # whichever render modules pick a variant.
        def generic_kind(iface, uniforms, points=False):
            return program_variant(iface, {**uniforms, "ow_layer_kind": -1}, points)

        pickers = [module for name, module in sorted(sys.modules.items()) if name.startswith("addon.render.")
                   and getattr(module, "program_variant", None) is program_variant]
        assert pickers
        for module in pickers:
            monkeypatch.setattr(module, "program_variant", generic_kind)
        generic = ShadowPipeline(backend).render(scene.light, tris, samples, settings, measure=Measure(keep_atlas=True))
    finally:
        backend.release()
    assert np.array_equal(fixed.visibility, generic.visibility)
    assert np.array_equal(fixed.atlas, generic.atlas)
    assert 0.0 < fixed.visibility[fixed.flags == 0].mean() < 1.0  # some shadow, some light
