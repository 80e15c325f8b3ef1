"""The shared GLSL library against the numpy core, evaluated per texel on tiny targets.

A small harness program includes the library, reads inputs from a float texture
and writes results to another; the numpy functions in addon/core are the oracle.
"""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import frames, projection
from addon.render.shaders import Uniform
from tests.support import glsl

pytestmark = pytest.mark.gl

HARNESS = ('#include "lib/projection.glsl"\n#include "lib/layers.glsl"\n'
           "void main() {\n  vec4 inp = texelFetch(ow_input, ivec2(gl_FragCoord.xy), 0);\n"
           "  vec4 outp = vec4(0.0);\n%s\n  ow_out = outp;\n}\n")


def _run(gl_backend, body: str, inputs: np.ndarray, uniforms=()) -> np.ndarray:
    """Evaluate `body` (GLSL using `vec4 inp` and setting `vec4 outp`) for each input row."""
    vs, fs = glsl.program("harness", HARNESS % body, uniforms=(Uniform(t, n) for t, n, _ in uniforms))
    return glsl.evaluate(gl_backend.ctx, vs, fs, inputs, uniforms)


def _random_dirs(rng, n, half=None):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if half == "front":
        d[:, 2] = np.abs(d[:, 2])
    return d


def test_paraboloid_projection_matches_numpy(gl_backend):
    """ow_paraboloid_project and _unproject agree with the numpy core on random rays."""
    rng = np.random.default_rng(1)
    dirs = _random_dirs(rng, 200, "front") * rng.uniform(0.01, 100.0, size=(200, 1))
    got = _run(gl_backend, "outp.xy = ow_paraboloid_project(inp.xyz);", dirs)
    assert np.allclose(got[:, :2], projection.paraboloid_project(dirs), atol=2e-6)
    xy = rng.uniform(-0.7, 0.7, size=(200, 2))
    got = _run(gl_backend, "outp.xyz = ow_paraboloid_unproject(inp.xy);", xy)
    assert np.allclose(got[:, :3], projection.paraboloid_unproject(xy), atol=2e-6)


def test_cube_projection_and_texel_angle_match_numpy(gl_backend):
    """Cube projection and the texel-angle bound agree with the numpy core."""
    rng = np.random.default_rng(2)
    pts = np.column_stack([rng.uniform(-1, 1, 100), rng.uniform(-1, 1, 100), np.ones(100)]) * rng.uniform(0.1, 50, (100, 1))
    got = _run(gl_backend, "outp.xy = ow_cube_project(inp.xyz);", pts)
    assert np.allclose(got[:, :2], projection.cube_project(pts), atol=2e-6)
    xy = rng.uniform(-1, 1, size=(100, 2))
    for kind in (projection.PARABOLOID, projection.CUBE):
        got = _run(gl_backend, f"outp.x = ow_texel_angle({kind}, inp.xy, 512.0);", xy)
        assert np.allclose(got[:, 0], projection.texel_angle(kind, xy, 512), rtol=1e-5)


@pytest.mark.parametrize("param", ["dpsm", "cube"])
def test_layer_choice_matches_numpy(gl_backend, param):
    """ow_pick_slot picks the same layer as frames.pick_slot, including axis-aligned ties."""
    rng = np.random.default_rng(3)
    dirs = np.concatenate([_random_dirs(rng, 300), np.eye(3), -np.eye(3), [[1, 1, 0], [0, -1, 1], [1, 1, 1]]])
    code = 0 if param == "dpsm" else 1
    got = _run(gl_backend, f"outp.x = float(ow_pick_slot({code}, inp.xyz));", dirs)
    assert np.array_equal(got[:, 0].astype(int), frames.pick_slot(param, dirs))


def test_unfold_projection_matches_numpy(gl_backend):
    """ow_unfold_project/_unproject and the unfold texel angle agree with the numpy core,
    over the whole sphere (both hemispheres) and both poles."""
    rng = np.random.default_rng(4)
    dirs = np.concatenate([_random_dirs(rng, 300), [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]])
    pts = dirs * rng.uniform(0.01, 100.0, size=(len(dirs), 1))
    got = _run(gl_backend, "outp.xy = ow_unfold_project(inp.xyz);", pts)
    assert np.allclose(got[:, :2], projection.unfold_project(pts), atol=3e-6)
    xy = projection.unfold_project(dirs[:-3])
    got = _run(gl_backend, "outp.xyz = ow_unfold_unproject(inp.xy);", xy)
    assert np.allclose(got[:, :3], projection.unfold_unproject(xy), atol=3e-6)
    got = _run(gl_backend, f"outp.x = ow_texel_angle({projection.UNFOLD}, inp.xy, 512.0); outp.y = inp.x;", xy)
    # (outp.y keeps the input sampler alive: the unfold bound is constant)
    assert np.allclose(got[:, 0], projection.texel_angle(projection.UNFOLD, xy, 512), rtol=1e-5)


def test_unfold_layer_choice_is_the_nearer_pole(gl_backend):
    """ow_pick_slot for unfold (code 3) is the nearer pole, as frames.pick_slot says."""
    rng = np.random.default_rng(5)
    dirs = np.concatenate([_random_dirs(rng, 300), np.eye(3), -np.eye(3)])
    got = _run(gl_backend, "outp.x = float(ow_pick_slot(3, inp.xyz));", dirs)
    assert np.array_equal(got[:, 0].astype(int), frames.pick_slot("unfold", dirs))
