"""gpu_shaders/lib/blockers.glsl against its numpy oracle (core/blockers.py): the segment
from a light-centred sample to the light against spheres, round pieces (closed, and open
at a curve's end) and ribbons, and whether the sample lies on the piece, on random cases
and on the cases that decide: tangent, behind the light, the open end, a ribbon's near
hits, the sample's own surface."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.blockers import OWN_SLACK, _on_piece, _segment_capsule
from tests.support import glsl

pytestmark = pytest.mark.gl

EPS = 1e-4
# One case a column: row 0 the sample p (light-centred), row 1 a and ra, row 2 b and rb
# (a sphere: a == b), row 3 the sample's normal and 1 for a ribbon, rows 4 and 5 the
# curve's directions at a and b, rows 6 and 7 the planes that end the curve (zero: none).
# Out: whether the segment to the light meets the piece, and whether p lies on it.
HARNESS = """#include "lib/blockers.glsl"
void main() {
  int column = int(gl_FragCoord.x);
  vec4 p = texelFetch(ow_input, ivec2(column, 0), 0);
  vec4 a = texelFetch(ow_input, ivec2(column, 1), 0);
  vec4 b = texelFetch(ow_input, ivec2(column, 2), 0);
  vec4 n = texelFetch(ow_input, ivec2(column, 3), 0);
  vec3 ta = texelFetch(ow_input, ivec2(column, 4), 0).xyz;
  vec3 tb = texelFetch(ow_input, ivec2(column, 5), 0).xyz;
  vec4 cut_a = texelFetch(ow_input, ivec2(column, 6), 0);
  vec4 cut_b = texelFetch(ow_input, ivec2(column, 7), 0);
  bool ribbon = n.w > 0.5;
  bool hit = dot(p.xyz, p.xyz) > 0.0
             && ow_segment_piece(p.xyz, -p.xyz, a.xyz, b.xyz, a.w, b.w, %r, ribbon, cut_a, cut_b, ta, tb);
  bool on = ow_on_piece(p.xyz, n.xyz, a.xyz, b.xyz, a.w, b.w, ribbon, cut_a, cut_b);
  ow_out = vec4(hit ? 1.0 : 0.0, on ? 1.0 : 0.0, 0.0, 1.0);
}
""" % (EPS,)


def _f32(x):
    return np.asarray(x, dtype=np.float32).astype(np.float64)  # what the GPU reads


def _tangents(a, b, tangents):
    return (np.asarray(b) - a, np.asarray(b) - a) if tangents is None else tangents


def _planes(a, b, flags):
    """(M, 2, 4): the piece's own ends as its curve's (flags 2: at a, 4: at b), else none."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    direction = b - a
    length = np.linalg.norm(direction, axis=1, keepdims=True)
    unit = np.divide(direction, length, out=np.zeros_like(direction), where=length > 0.0)
    out = np.zeros((len(a), 2, 4))
    for side, bit, normal, at in ((0, 2, unit, a), (1, 4, -unit, b)):
        keep = (np.asarray(flags) & bit) != 0
        out[keep, side, :3] = normal[keep]
        out[keep, side, 3] = -np.einsum("ij,ij->i", normal[keep], at[keep])
    return out


def _glsl(gl_backend, p, n, a, b, ra, rb, flags, tangents=None):
    vs, fs = glsl.program("blockers_harness", HARNESS)
    ta, tb = _tangents(a, b, tangents)
    rows = np.zeros((8, len(p), 4))
    rows[0, :, :3] = p
    rows[1, :, :3], rows[1, :, 3] = a, ra
    rows[2, :, :3], rows[2, :, 3] = b, rb
    rows[3, :, :3], rows[3, :, 3] = n, np.asarray(flags) & 1
    rows[4, :, :3], rows[5, :, :3] = ta, tb
    rows[6:8] = _planes(_f32(a), _f32(b), flags).transpose(1, 0, 2)
    out = glsl.evaluate(gl_backend.ctx, vs, fs, rows.astype(np.float32))
    return out[:, 0] > 0.5, out[:, 1] > 0.5


def _oracle(p, n, a, b, ra, rb, flags, tangents=None):
    ta, tb = (_f32(t) for t in _tangents(a, b, tangents))
    p, n, a, b, ra, rb = (_f32(x) for x in (p, n, a, b, ra, rb))
    flags = np.asarray(flags, dtype=int)
    ribbon, planes = (flags & 1) != 0, _f32(_planes(a, b, flags))
    hit = _segment_capsule(p, np.zeros_like(p), a, b, ra, rb, EPS, ribbon, planes, (ta, tb))
    return hit, _on_piece(p, n, a, b, ra, rb, ribbon, planes)


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


KINDS = ["sphere", "round", "open", "ribbon", "bent ribbon"]


@pytest.mark.parametrize("kind", KINDS)
def test_random_cases_match_the_oracle(gl_backend, kind):
    rng = np.random.default_rng(11 + KINDS.index(kind))
    n = 256
    p = rng.normal(size=(n, 3)) * 3.0
    sphere = kind == "sphere"
    a = p * rng.uniform(0.0, 1.0, (n, 1)) + rng.normal(size=(n, 3)) * (0.25 if sphere else 0.4)  # near them
    b = a + (0.0 if sphere else rng.normal(size=(n, 3)) * 0.5)
    ra = rng.uniform(0.05, 0.4, n)
    rb = ra if sphere else rng.uniform(0.05, 0.4, n)
    flags = np.full(n, {"sphere": 0, "round": 0, "open": 6, "ribbon": 7, "bent ribbon": 1}[kind])
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    # A bent ribbon's stretch ends across directions turned from its own (a curve's joints).
    tangents = None if kind != "bent ribbon" else tuple((b - a) + rng.normal(size=(n, 3)) * 0.2 for _ in range(2))
    hit, _ = _glsl(gl_backend, p, normal, a, b, ra, rb, flags, tangents)
    expected, _ = _oracle(p, normal, a, b, ra, rb, flags, tangents)
    differ = hit != expected
    assert 0.05 * n < expected.sum() < 0.8 * n  # both verdicts well represented
    # float32 may decide a grazing case either way, and nothing else.
    if differ.any():
        assert np.all(_margin(p[differ], a[differ], b[differ], ra[differ], rb[differ]) < 1e-3)
    assert differ.sum() <= 3


@pytest.mark.parametrize("ribbon", [False, True])
def test_points_on_a_piece_match_the_oracle(gl_backend, ribbon):
    """Samples on and near a piece's surface (round) or its plane facing the camera
    (ribbon), their normals as Cycles gives them or turned: the same verdicts."""
    rng = np.random.default_rng(5 + ribbon)
    n = 256
    a = rng.normal(size=(n, 3))
    b = a + rng.normal(size=(n, 3)) * 0.5
    ra, rb = rng.uniform(0.05, 0.2, n), rng.uniform(0.05, 0.2, n)
    u = rng.uniform(-0.2, 1.2, n)
    axis = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    side = np.cross(axis, rng.normal(size=(n, 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    radius = ra + np.clip(u, 0.0, 1.0) * (rb - ra)
    off = radius * rng.choice([0.5, 0.97, 1.0, 1.03, 1.3], n)
    p = a + u[:, None] * (b - a) + side * off[:, None]
    if ribbon:
        normal = np.cross(axis, side)  # the camera ray's: the plane holds the axis and p
    else:
        normal = side
    normal = normal + rng.normal(size=(n, 3)) * rng.choice([0.0, 0.05, 0.5], n)[:, None]
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    flags = np.full(n, (1 if ribbon else 0) + 2 + 4)
    _, on = _glsl(gl_backend, p, normal, a, b, ra, rb, flags)
    _, expected = _oracle(p, normal, a, b, ra, rb, flags)
    assert 0.1 * n < expected.sum() < 0.9 * n
    assert np.count_nonzero(on != expected) <= 2


def test_the_cases_that_decide(gl_backend):
    up = np.array([0.0, 0.0, 1.0])
    cases = [  # p, normal, a, b, ra, rb, flags, (meets, lies on)
        ([0.0, 0.0, 4.0], up, [0.3, 0.0, 2.0], [0.3, 0.0, 2.0], 0.2, 0.2, 0, (False, False)),  # beside a sphere
        ([0.0, 0.0, 4.0], up, [0.1, 0.0, 2.0], [0.1, 0.0, 2.0], 0.2, 0.2, 0, (True, False)),  # through it
        ([0.0, 0.0, 4.0], up, [0.0, 0.0, -1.0], [0.0, 0.0, -1.0], 0.5, 0.5, 0, (False, False)),  # behind the light
        # On its surface, lit side: on it with the normal either way along the radius (Cycles
        # turns the true normal to the camera), not with one across it.
        ([0.0, 0.0, 3.0], up, [0.0, 0.0, 4.0], [0.0, 0.0, 4.0], 1.0, 1.0, 0, (False, True)),
        ([0.0, 0.0, 3.0], [1.0, 0.0, 0.0], [0.0, 0.0, 4.0], [0.0, 0.0, 4.0], 1.0, 1.0, 0, (False, False)),
        ([0.0, 0.0, 5.0], up, [0.0, 0.0, 4.0], [0.0, 0.0, 4.0], 1.0, 1.0, 0, (True, True)),  # on it, far side
        ([0.0, 0.0, 4.0], up, [-1.0, 0.0, 1.0], [1.0, 0.0, 3.0], 0.1, 0.1, 0, (True, False)),  # a piece across
        ([0.0, 0.0, 4.0], up, [-1.0, 0.25, 1.0], [1.0, 0.25, 3.0], 0.1, 0.1, 0, (False, False)),  # beside it
        # A piece that ends short of the segment: its curve's end plane cuts the passage.
        ([0.0, 0.0, 4.0], up, [1.0, 0.0, 2.0], [0.05, 0.0, 2.0], 0.1, 0.1, 4, (False, False)),
        ([0.0, 0.0, 4.0], up, [1.0, 0.0, 2.0], [0.05, 0.0, 2.0], 0.1, 0.1, 0, (True, False)),  # closed: met
        # A ribbon across the segment near the sample: nearer than twice its radius, ignored.
        ([0.0, 0.0, 4.0], up, [-1.0, 0.0, 3.85], [1.0, 0.0, 3.85], 0.1, 0.1, 1, (False, False)),
        ([0.0, 0.0, 4.0], up, [-1.0, 0.0, 3.7], [1.0, 0.0, 3.7], 0.1, 0.1, 1, (True, False)),
    ]
    p, n, a, b = (np.array([c[i] for c in cases], dtype=float) for i in range(4))
    ra, rb = np.array([c[4] for c in cases]), np.array([c[5] for c in cases])
    flags = np.array([c[6] for c in cases])
    expected = [c[7] for c in cases]
    hit, on = _glsl(gl_backend, p, n, a, b, ra, rb, flags)
    assert list(zip(hit.tolist(), on.tolist())) == expected
    theirs = _oracle(p, n, a, b, ra, rb, flags)
    assert list(zip(theirs[0].tolist(), theirs[1].tolist())) == expected
    assert OWN_SLACK < 0.5  # the margins above hold the slack
