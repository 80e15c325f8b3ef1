"""gpu_shaders/lib/footprint.glsl against its numpy statement (addon/core/footprint.py).

A harness fragment program reads one triangle (and one ray) per texel column and
writes the paraboloid box, the cube box or the inside test. The boxes must match the
numpy ones to float32 rounding, and the inside test must agree wherever the ray is
not within rounding of an edge plane.
"""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import footprint as fp
from addon.render.shaders import SHADER_DIR, SHARED_DEFINES, Uniform
from tests.core.test_footprint import KINDS, _random_rotation, _triangle
from tests.support import glsl

pytestmark = pytest.mark.gl

MODES = {"paraboloid": 0, "cube": 1, "inside": 2}
HARNESS = """#include "lib/footprint.glsl"
void main() {
  int i = int(gl_FragCoord.x);
  vec3 v0 = texelFetch(ow_input, ivec2(i, 0), 0).xyz;
  vec3 v1 = texelFetch(ow_input, ivec2(i, 1), 0).xyz;
  vec3 v2 = texelFetch(ow_input, ivec2(i, 2), 0).xyz;
  vec4 extra = texelFetch(ow_input, ivec2(i, 3), 0);
  if (ow_mode == 0) {
    ow_out = ow_paraboloid_box(v0, v1, v2);
  } else if (ow_mode == 1) {
    ow_out = ow_cube_box(v0, v1, v2, extra.w);
  } else {
    vec3 n0, n1, n2;
    float s = ow_edge_planes(v0, v1, v2, 0.0, n0, n1, n2);
    ow_out = vec4(ow_inside(extra.xyz, n0, n1, n2, s) ? 1.0 : 0.0, s, 0.0, 0.0);
  }
}
"""


def _run(gl_backend, mode: str, tris: np.ndarray, extra: np.ndarray) -> np.ndarray:
    vs, fs = glsl.program("footprint_harness", HARNESS, uniforms=(Uniform("int", "ow_mode"),))
    data = np.zeros((4, len(tris), 4), dtype="f4")
    data[:3, :, :3] = np.transpose(tris, (1, 0, 2))
    data[3] = extra
    return glsl.evaluate(gl_backend.ctx, vs, fs, data, (("int", "ow_mode", MODES[mode]),))


def _triangles(seed: int, count: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.array([_triangle(rng, KINDS[i % len(KINDS)]) @ _random_rotation(rng).T for i in range(count)])


# Float32 boxes agree with the float64 ones to this, in map units (a texel at 1024 is
# 2e-3). A vertex 1e-4 from the light, clipped at the seam, puts the crossing point's
# direction at float32's relative error over 1e-4: about 1e-3, so those boxes need the
# texel of dilation the GPU pass adds.
TOLERANCE = {kind: 2e-3 if kind == "near_light" else 1e-4 for kind in KINDS}


def _near(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    """Empty boxes agree when both are empty; others to the float32 tolerance of their kind."""
    empty_got, empty_want = got[:, 0] > got[:, 1], ~np.isfinite(want[:, 0])
    both = ~empty_got & ~empty_want
    ok = empty_got == empty_want
    tolerance = np.array([TOLERANCE[KINDS[i % len(KINDS)]] for i in range(len(got))])
    ok[both] &= np.all(np.abs(got[both] - want[both]) <= tolerance[both, None], axis=1)
    return ok


# A small triangle's GLSL box bounds its arcs by their sag instead of their extremes
# (OW_SAG_CHORD in lib/footprint.glsl): it may exceed the exact box by c^2 / 4, c < 0.05.
SAG_SLACK = 0.25 * 0.05 ** 2


def _contains(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    """Boxes that hold the exact one (to float32 tolerance) and exceed it by at most the sag slack."""
    empty_got, empty_want = got[:, 0] > got[:, 1], ~np.isfinite(want[:, 0])
    both = ~empty_got & ~empty_want
    ok = empty_got == empty_want
    tolerance = np.array([TOLERANCE[KINDS[i % len(KINDS)]] for i in range(len(got))])[both, None]
    outward = (got[both] - want[both]) * np.array([-1.0, 1.0, -1.0, 1.0])  # > 0 where got is larger
    ok[both] &= np.all((outward >= -tolerance) & (outward <= SAG_SLACK + tolerance), axis=1)
    return ok


def test_paraboloid_boxes_hold_the_exact_boxes(gl_backend):
    tris = _triangles(1, 300)
    got = _run(gl_backend, "paraboloid", tris, np.zeros((len(tris), 4)))
    want = np.array([fp.paraboloid_box(t) for t in tris])
    ok = _contains(got, want)
    assert ok.all(), (np.flatnonzero(~ok)[:5], got[~ok][:3], want[~ok][:3])
    assert (~np.isfinite(want[:, 0])).sum() < len(tris) // 2  # most triangles are seen


def test_cube_boxes_match_numpy(gl_backend):
    tris = _triangles(2, 300)
    near = 1e-6 * np.abs(tris).reshape(len(tris), -1).max(axis=1)
    extra = np.zeros((len(tris), 4))
    extra[:, 3] = near
    got = _run(gl_backend, "cube", tris, extra)
    want = np.array([fp.cube_box(t, z) for t, z in zip(tris, near)])
    ok = _near(got, want)
    assert ok.all(), np.flatnonzero(~ok)[:5]


def test_inside_test_matches_numpy(gl_backend):
    rng = np.random.default_rng(3)
    tris = np.repeat(_triangles(3, 50), 20, axis=0)
    dirs = rng.normal(size=(len(tris), 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    extra = np.zeros((len(tris), 4))
    extra[:, :3] = dirs
    got = _run(gl_backend, "inside", tris, extra)
    normals, sign = fp.edge_planes(tris)
    want = np.array([fp.inside(d[None], n[None], s[None])[0, 0] for d, n, s in zip(dirs, normals, sign)])
    unit = normals / np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-300)
    clear = (np.min(np.abs(np.einsum("tk,tek->te", dirs, unit)), axis=1) > 1e-5) & (sign != 0.0)
    assert clear.sum() > 500
    assert np.array_equal(got[clear, 0] > 0.5, want[clear])
    assert want[clear].sum() > 20  # some rays do hit


def test_edge_on_margin_is_the_same_number_on_both_sides():
    """The host's count of what the GPU draws (parameterizations._measurer) uses OW_EDGE_ON's value:
    the shader gets it from the host's header, and spells out no value of its own."""
    text = (SHADER_DIR / "lib" / "footprint.glsl").read_text()
    assert "OW_EDGE_ON" in text and "const float OW_EDGE_ON" not in text
    assert float(SHARED_DEFINES["OW_EDGE_ON"]) == fp.GPU_EDGE_ON
