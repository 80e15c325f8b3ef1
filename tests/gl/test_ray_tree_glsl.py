"""gpu_shaders/lib/ray_tree.glsl against its numpy oracle (core/ray_tree.py's walk): the
same verdict for random segments through a random scene, walked whole and walked in many
short turns that each go on from where the last one stopped."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import ray_tree
from addon.render.shaders import Uniform
from addon.render.shaders.constants import RAY_TREE_BLOCKED as BLOCKED, RAY_TREE_CLEAR as CLEAR, RAY_TREE_CUT as CUT, \
    RAY_TREE_WIDTH
from tests.support import glsl

pytestmark = pytest.mark.gl

EPS = 1e-4
# One case a column: row 0 the segment's start p, row 1 its vector d, row 2 the node to go
# on from and the budget. Out: the verdict, the node to go on from, the budget left.
HARNESS = """#include "lib/ray_tree.glsl"
void main() {
  int column = int(gl_FragCoord.x);
  vec3 p = texelFetch(ow_input, ivec2(column, 0), 0).xyz;
  vec3 d = texelFetch(ow_input, ivec2(column, 1), 0).xyz;
  vec4 state = texelFetch(ow_input, ivec2(column, 2), 0);
  int node = int(state.x);
  int budget = int(state.y);
  int verdict = ow_tree_walk(p, d, %r, node, budget);
  ow_out = vec4(float(verdict), float(node), float(budget), 1.0);
}
""" % (EPS,)
UNIFORMS = (Uniform("int", "ow_tree_leaves"),)
SAMPLERS = ("ow_input", "ow_tree_boxes", "ow_tree_tris")


def _cases(tris, count, seed):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-3.0, 3.0, (count, 3)).astype(np.float32)
    d = (rng.uniform(-3.0, 3.0, (count, 3)) - p).astype(np.float32)
    return p, d


def _run(gl_backend, tree, p, d, node, budget):
    vs, fs = glsl.program("ray_tree_harness", HARNESS, uniforms=UNIFORMS, samplers=SAMPLERS)
    rows = np.zeros((3, len(p), 4), dtype=np.float32)
    rows[0, :, :3], rows[1, :, :3] = p, d
    rows[2, :, 0], rows[2, :, 1] = node, budget
    boxes, corners = ray_tree.texels(tree, RAY_TREE_WIDTH)
    out = glsl.evaluate(gl_backend.ctx, vs, fs, rows, uniforms=[("int", "ow_tree_leaves", tree.leaves)],
                        name="ray_tree_harness", tables={"ow_tree_boxes": boxes, "ow_tree_tris": corners})
    return out[:, 0].astype(int), out[:, 1].astype(int), out[:, 2].astype(int)


def _scene(count, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(-2.0, 2.0, (count, 1, 3)) + rng.normal(scale=0.3, size=(count, 3, 3))


def test_the_walk_matches_its_oracle(gl_backend):
    tris = _scene(600, 1)
    tree = ray_tree.build(tris)
    p, d = _cases(tris, 512, 2)
    verdict, _, _ = _run(gl_backend, tree, p, d, np.ones(len(p)), 1 << 20)
    expected = np.array([ray_tree.walk(tree, p[k], d[k], EPS)[0] for k in range(len(p))])
    assert set(np.unique(verdict)) <= {CLEAR, BLOCKED}
    assert 0.1 * len(p) < expected.sum() < 0.9 * len(p)
    # float32 may decide a segment through an edge either way: a handful at most.
    assert np.count_nonzero((verdict == BLOCKED) != expected) <= 2


def test_a_walk_cut_into_short_turns_ends_as_the_whole_walk(gl_backend):
    tris = _scene(300, 5)
    tree = ray_tree.build(tris)
    p, d = _cases(tris, 256, 6)
    whole, _, _ = _run(gl_backend, tree, p, d, np.ones(len(p)), 1 << 20)
    node = np.ones(len(p))
    verdict = np.full(len(p), CUT)
    turns = 0
    while (verdict == CUT).any():
        going = verdict == CUT
        v, n, left = _run(gl_backend, tree, p[going], d[going], node[going], 7)
        assert np.all(left[v == CUT] <= 0)  # cut only when its budget is spent
        verdict[going], node[going] = v, n
        turns += 1
        assert turns < 10_000
    assert turns > 3  # the budget did cut the walks
    assert np.array_equal(verdict, whole)
