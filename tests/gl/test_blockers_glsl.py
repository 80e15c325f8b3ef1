"""gpu_shaders/lib/blockers.glsl against its numpy oracle (core/blockers.py): the segment
from a light-centred sample to the light against spheres and strand pieces, on random
cases and on the cases that decide: tangent, behind the light, the sample's own surface."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.blockers import _segment_capsule
from tests.support import glsl

pytestmark = pytest.mark.gl

EPS = 1e-4
# One case a column: row 0 the sample p (light-centred) and the test (0 sphere, 1 capsule),
# row 1 a and ra, row 2 b and rb (a sphere: centre a, radius ra).
HARNESS = """#include "lib/blockers.glsl"
void main() {
  int column = int(gl_FragCoord.x);
  vec4 p = texelFetch(ow_input, ivec2(column, 0), 0);
  vec4 a = texelFetch(ow_input, ivec2(column, 1), 0);
  vec4 b = texelFetch(ow_input, ivec2(column, 2), 0);
  bool hit = (p.w < 0.5) ? ow_segment_sphere(p.xyz, a.xyz, a.w, %r)
                         : ow_segment_capsule(p.xyz, a.xyz, b.xyz, a.w, b.w, %r);
  ow_out = vec4(hit ? 1.0 : 0.0, 0.0, 0.0, 1.0);
}
""" % (EPS, EPS)


def _glsl(gl_backend, p, a, b, ra, rb, capsule):
    vs, fs = glsl.program("blockers_harness", HARNESS)
    rows = np.zeros((3, len(p), 4))
    rows[0, :, :3], rows[0, :, 3] = p, capsule
    rows[1, :, :3], rows[1, :, 3] = a, ra
    rows[2, :, :3], rows[2, :, 3] = b, rb
    return glsl.evaluate(gl_backend.ctx, vs, fs, rows.astype(np.float32))[:, 0] > 0.5


def _oracle(p, a, b, ra, rb):
    p32 = lambda x: np.asarray(x, dtype=np.float32).astype(np.float64)  # noqa: E731 - what the GPU reads
    return _segment_capsule(p32(p), np.zeros_like(p), p32(a), p32(b), p32(ra), p32(rb), EPS)


def _margin(p, a, b, ra, rb):
    """How far each case lies from deciding the other way: |gap - radius| over the scale."""
    s = np.linspace(EPS, 1.0, 2001)[:, None, None]
    u = np.linspace(0.0, 1.0, 201)[None, :, None]
    out = []
    for k in range(len(p)):
        seg = p[k] * (1.0 - s)
        axis = a[k] + u * (b[k] - a[k])
        radius = ra[k] + u[..., 0] * (rb[k] - ra[k])
        out.append(np.min(np.abs(np.linalg.norm(seg - axis, axis=2) - radius)) / (np.linalg.norm(p[k]) + 1.0))
    return np.array(out)


@pytest.mark.parametrize("capsule", [False, True])
def test_random_cases_match_the_oracle(gl_backend, capsule):
    rng = np.random.default_rng(11 + capsule)
    n = 256
    p = rng.normal(size=(n, 3)) * 3.0
    a = p * rng.uniform(0.0, 1.0, (n, 1)) + rng.normal(size=(n, 3)) * (0.4 if capsule else 0.25)  # near them
    b = a + (rng.normal(size=(n, 3)) * 0.5 if capsule else 0.0)
    ra, rb = rng.uniform(0.05, 0.4, n), rng.uniform(0.05, 0.4, n)
    if not capsule:
        rb = ra
    ours = _glsl(gl_backend, p, a, b, ra, rb, capsule)
    theirs = _oracle(p, a, b, ra, rb)
    differ = ours != theirs
    assert 0.2 * n < theirs.sum() < 0.8 * n
    # float32 may decide a grazing case either way, and nothing else.
    if differ.any():
        assert np.all(_margin(p[differ], a[differ], b[differ], ra[differ], rb[differ]) < 1e-4)
    assert differ.sum() <= 2


def test_the_cases_that_decide(gl_backend):
    p = np.array([[0.0, 0.0, 4.0]] * 6)
    a = np.array([[0.3, 0.0, 2.0],   # a sphere off the axis by more than its radius: lit
                  [0.1, 0.0, 2.0],   # within: shadowed
                  [0.0, 0.0, -1.0],  # behind the light: lit
                  [0.0, 0.0, 4.0],   # the sample's own sphere, the light outside it: lit
                  [-1.0, 0.0, 1.0],  # a piece across the segment: shadowed
                  [-1.0, 0.25, 1.0]])  # the same piece beside it by more than its radius: lit
    b = a.copy()
    b[4] = [1.0, 0.0, 3.0]
    b[5] = [1.0, 0.25, 3.0]
    ra = np.array([0.2, 0.2, 0.5, 1.0, 0.1, 0.1])
    rb = ra.copy()
    capsule = np.array([0, 0, 0, 0, 1, 1])
    # A sample on the sphere's surface facing the light (at the origin): its own sphere
    # does not shadow it; on the far side it would.
    p[3] = [0.0, 0.0, 3.0]
    expected = [False, True, False, False, True, False]
    assert _glsl(gl_backend, p, a, b, ra, rb, capsule).tolist() == expected
    assert _oracle(p, a, b, ra, rb).tolist() == expected
    # On the far side its own sphere does not shadow it either (Cycles' rays skip the
    # primitive they leave), nor does a piece it lies in; another sphere does.
    p[3] = [0.0, 0.0, 5.0]
    assert _glsl(gl_backend, p[3:4], a[3:4], b[3:4], ra[3:4], rb[3:4], capsule[3:4]).tolist() == [False]
    inside = np.array([[0.0, 0.0, 2.0], [0.05, 0.0, 2.0]])  # within the sphere; on a ribbon of the piece
    other = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 1.0]])
    ends = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 3.0]])
    own = _glsl(gl_backend, inside, np.array([[0.0, 0.0, 2.0], other[1]]), np.array([[0.0, 0.0, 2.0], ends[1]]),
                np.array([1.0, 0.1]), np.array([1.0, 0.1]), np.array([0, 1]))
    assert own.tolist() == [False, False]
    assert _glsl(gl_backend, inside[:1], other[:1], ends[:1], np.array([0.3]), np.array([0.3]),
                 np.array([0])).tolist() == [True]
