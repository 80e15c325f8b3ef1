"""The GLSL warp and the GPU count-map scatter against the numpy core, on tiny targets."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import warping as W
from addon.core.scene import SceneBuilder
from addon.render.backend import pack_warp_table
from addon.render.pipeline import ShadowPipeline, ShadowSettings, ViewSamples
from addon.render.shaders import Uniform
from tests.support import glsl

pytestmark = pytest.mark.gl

CROP = (0.25, 0.5, 2.0, 4.0)  # the harness's crop: (lo, scale)


def _harness(gl_backend, body: str, inputs: np.ndarray, warp: W.Warp, slot: int) -> np.ndarray:
    """Evaluate `body` per input row with the warp tables of `warp` stored at `slot`."""
    vs, fs = glsl.program("warp_harness",
                          '#include "lib/mapping.glsl"\nvoid main() {\n'
                          "  vec4 inp = texelFetch(ow_input, ivec2(gl_FragCoord.xy), 0);\n  vec4 outp = vec4(0.0);\n"
                          + body + "\n  ow_out = outp;\n}\n",
                          uniforms=(Uniform("int", "ow_slot"), Uniform("int", "ow_size"), Uniform("vec4", "ow_crop")),
                          samplers=("ow_input", "ow_warp_rows", "ow_warp_cols"))
    size = warp.size
    rows = np.zeros((6 * size, size + 1), "f4")
    cols = np.zeros((6 * size, size + 1), "f4")
    rows[slot * size:(slot + 1) * size] = warp.rows
    cols[slot * size:(slot + 1) * size] = warp.cols
    crops = np.tile(np.float32([0.0, 0.0, 1.0, 1.0]), (6, 1))
    crops[slot] = CROP  # a warped layer's passes read its crop from the rows table
    rows, cols = pack_warp_table(rows, crops=crops), pack_warp_table(cols)
    n = len(inputs)
    data = np.zeros((1, n, 4), "f4")
    data[0, :, :inputs.shape[1]] = inputs
    ctx = gl_backend.ctx
    with ctx:
        prog = ctx.program(vertex_shader=vs, fragment_shader=fs)
        textures = [ctx.texture((n, 1), 4, data.tobytes(), dtype="f4"),
                    ctx.texture((size + 1, 6 * size), 4, rows.tobytes(), dtype="f4"),
                    ctx.texture((size + 1, 6 * size), 4, cols.tobytes(), dtype="f4")]
        out = ctx.texture((n, 1), 4, dtype="f4")
        fbo = ctx.framebuffer(color_attachments=[out])
        vbo = ctx.buffer(np.array([[-1, -1], [3, -1], [-1, 3]], "f4").tobytes())
        vao = ctx.vertex_array(prog, [(vbo, "2f", "ow_corner")])
        try:
            for i, (name, tex) in enumerate(zip(("ow_input", "ow_warp_rows", "ow_warp_cols"), textures)):
                tex.use(i)
                if name in prog:  # unused samplers are optimised away
                    prog[name].value = i
            textures.append(glsl.uniform_buffer(  # released with the textures
                ctx, "warp_harness", (Uniform("int", "ow_slot"), Uniform("int", "ow_size"), Uniform("vec4", "ow_crop")),
                {"ow_slot": slot, "ow_size": size, "ow_crop": CROP}))
            fbo.use()
            fbo.viewport = (0, 0, n, 1)
            vao.render()
            return np.frombuffer(out.read(), "f4").reshape(n, 4).astype(np.float64)
        finally:
            for obj in [vao, vbo, fbo, out, prog] + textures:
                obj.release()


@pytest.fixture(scope="module")
def clustered_warp():
    rng = np.random.default_rng(11)
    uv = np.concatenate([rng.normal([0.3, 0.6], 0.05, (4000, 2)), rng.random((1000, 2))]).clip(0, 0.999)
    return W.build_notw(uv, 16)


def test_glsl_warp_matches_numpy(gl_backend, clustered_warp):
    """ow_warp, its slopes, the row-only warp and ow_unwarp agree with Warp in float32 precision."""
    q = np.random.default_rng(4).uniform(-0.05, 1.05, (300, 2))
    got = _harness(gl_backend,
                   "vec2 s; outp.xy = ow_warp(ow_warp_rows, ow_warp_cols, ow_slot, ow_size, inp.xy, s); outp.zw = s;",
                   q, clustered_warp, slot=3)
    assert np.allclose(got[:, :2], clustered_warp.forward(q), atol=2e-6)
    su, sv = clustered_warp.slopes(q)
    inside = np.all((q > 0.001) & (q < 0.999), axis=1)
    assert np.allclose(got[inside, 2], su[inside], rtol=1e-4) and np.allclose(got[inside, 3], sv[inside], rtol=1e-4)
    rows_only = _harness(gl_backend, "outp.xy = ow_apply_row_warp(ow_warp_rows, ow_slot, ow_size, inp.xy);",
                         q, clustered_warp, slot=3)
    expected_u = q[:, 0] + W.family_offset(clustered_warp.rows, q[:, 0], q[:, 1])
    assert np.allclose(rows_only[:, 0], expected_u, atol=2e-6)
    w = np.random.default_rng(5).uniform(0.0, 1.0, (300, 2))
    back = _harness(gl_backend, "outp.xy = ow_unwarp(ow_warp_rows, ow_warp_cols, ow_slot, ow_size, inp.xy);",
                    w, clustered_warp, slot=3)
    assert np.allclose(back[:, :2], clustered_warp.inverse(w), atol=2e-5)


def test_glsl_mapping_matches_numpy(gl_backend, clustered_warp):
    """Crop plus warp forward, and back to projection coordinates."""
    mapping = W.LayerMapping(np.array([0.25, 0.5]), np.array([0.75, 0.75]), clustered_warp)
    xy = np.random.default_rng(6).uniform([-0.45, 0.05], [0.45, 0.45], (200, 2))
    got = _harness(gl_backend,
                   "float m; outp.xy = ow_map_forward(ow_warp_rows, ow_warp_cols, ow_slot, ow_size, ow_crop, inp.xy, m);"
                   " outp.zw = ow_map_inverse(ow_warp_rows, ow_warp_cols, ow_slot, ow_size, ow_crop, outp.xy);",
                   xy, clustered_warp, slot=0)
    assert np.allclose(got[:, :2], mapping.forward(xy), atol=3e-6)
    assert np.allclose(got[:, 2:], xy, atol=3e-5)
    mag = _harness(gl_backend,
                   "ow_map_forward(ow_warp_rows, ow_warp_cols, ow_slot, ow_size, ow_crop, inp.xy, outp.x);",
                   xy, clustered_warp, slot=0)
    assert np.allclose(mag[:, 0], mapping.magnification(xy), rtol=1e-4)


def test_glsl_texel_reach_matches_numpy(gl_backend, clustered_warp):
    """ow_texel_reach on the crop-and-warp Jacobian equals LayerMapping.reach, so the
    GLSL Jacobian is oriented as numpy's (the smallest singular value alone would not
    tell a matrix from its transpose)."""
    mapping = W.LayerMapping(np.array([0.25, 0.5]), np.array([0.75, 0.75]), clustered_warp)
    rng = np.random.default_rng(7)
    xy = rng.uniform([-0.45, 0.05], [0.45, 0.45], (300, 2))
    angle = rng.uniform(0.0, 2.0 * np.pi, 300)
    g = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    got = _harness(gl_backend,
                   "mat2 j; ow_map_forward_jacobian(ow_warp_rows, ow_warp_cols, ow_slot, ow_size, ow_crop, inp.xy, j);"
                   " outp.x = ow_texel_reach(j, inp.zw);",
                   np.concatenate([xy, g], axis=1), clustered_warp, slot=0)
    expected = mapping.reach(xy, g)
    assert np.allclose(got[:, 0], expected, rtol=1e-4)
    swapped = W.texel_reach(np.swapaxes(mapping.jacobian(xy), -1, -2), g)
    assert not np.allclose(got[:, 0], swapped, rtol=1e-3)  # the test can tell the orientation


def _light_over_floor(size: tuple[int, int]):
    """A light at the origin over a floor; the tests below bring their own samples."""
    b = SceneBuilder("s", size)
    b.plane("floor", (0, 0, -1), 4, 4)
    b.point_light((0, 0, 0))
    b.camera((0, 0, 3), (0, 0, 0))
    return b.finish()


def _aimed_samples(scene, texels: np.ndarray, res: int):
    """Samples on directions aimed at texel centres of the front paraboloid of a res^2 map."""
    from addon.core import frames, projection

    layer = frames.light_layers(scene.light, "dpsm")[0]
    xy = (texels + 0.5) / res * 2 - 1
    dirs = projection.paraboloid_unproject(xy) @ layer.rotation
    return layer, xy, dirs


def test_gpu_scatter_matches_numpy_count_map(gl_backend):
    """The compute scatter counts exactly what numpy's bincount counts."""
    scene = _light_over_floor((8, 8))
    rng = np.random.default_rng(8)
    # Directions aimed at texel centres of a 16^2 paraboloid map, many per texel.
    layer, xy, dirs = _aimed_samples(scene, rng.integers(3, 13, size=(40, 40, 2)), 16)
    samples = ViewSamples(dirs * 2.0, -dirs, np.ones((40, 40), bool), scene.camera)
    pipe = ShadowPipeline(gl_backend)
    settings = ShadowSettings("dpsm", 16, warp="none")
    result = pipe.render(scene.light, scene.world_triangles(), samples, settings)
    gpu = pipe.count_maps(scene.light, result.plan, {}, 16, 0)[layer.slot]
    expected = W.scatter_counts((xy * 0.5 + 0.5).reshape(-1, 2), 16)
    assert gpu.sum() == 1600
    assert np.array_equal(gpu, expected)


def test_weighted_scatter_sums_importance_as_numpy_does(gl_backend):
    """With importance weights the analysis scatter sums them (numpy's weighted
    bincount); the statistics scatter still counts each sample once."""
    scene = _light_over_floor((8, 8))
    rng = np.random.default_rng(9)
    texels = rng.integers(3, 13, size=(40, 40, 2))
    layer, xy, dirs = _aimed_samples(scene, texels, 16)
    weights = rng.integers(1, 50, size=(40, 40)).astype(np.float64)
    samples = ViewSamples(dirs * 2.0, -dirs, np.ones((40, 40), bool), scene.camera, importance=weights)
    pipe = ShadowPipeline(gl_backend)
    result = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("dpsm", 16, warp="none"))
    uv = (xy * 0.5 + 0.5).reshape(-1, 2)
    summed = pipe.count_maps(scene.light, result.plan, {}, 16, 0, weighted=True)[layer.slot]
    counted = pipe.count_maps(scene.light, result.plan, {}, 16, 0)[layer.slot]
    assert summed.sum() == weights.sum()
    assert np.array_equal(summed, W.scatter_counts(uv, 16, weights.reshape(-1)))
    assert np.array_equal(counted, W.scatter_counts(uv, 16))


def test_importance_moves_resolution_to_the_weighted_samples(gl_backend):
    """A uniform weight leaves the NoTW warp as it is, to rounding (the analysis scales
    the counts to a peak of 1); weighting one half of the samples gives that half more texels."""
    scene = _light_over_floor((8, 8))
    rng = np.random.default_rng(10)
    texels = rng.integers(2, 30, size=(48, 48, 2))
    layer, xy, dirs = _aimed_samples(scene, texels, 32)
    hit = np.ones((48, 48), bool)
    settings = ShadowSettings("dpsm", 256, warp="notw", cull=False)
    pipe = ShadowPipeline(gl_backend)

    def mapping(importance):
        samples = ViewSamples(dirs * 2.0, -dirs, hit, scene.camera, importance=importance)
        chosen = pipe.render(scene.light, scene.world_triangles(), samples, settings).mappings[layer.slot]
        chosen.warp.rows  # read from the GPU before the next frame's warp replaces its tables
        return chosen

    plain = mapping(None)
    tripled = mapping(np.full((48, 48), 3.0))
    # Built in float32 on the GPU: the same to float32 rounding.
    assert np.allclose(plain.warp.rows, tripled.warp.rows, rtol=0, atol=1e-6)
    assert np.allclose(plain.warp.cols, tripled.warp.cols, rtol=0, atol=1e-6)
    left = xy[..., 0] < 0.0
    weighted = mapping(np.where(left, 40.0, 1.0))
    # Where the border between the halves (x = 0) lands in the map: the share of each
    # row the left half gets, about a half with plain counts.
    border = np.stack([np.zeros(15), np.linspace(-0.7, 0.7, 15)], axis=1)
    assert abs(plain.forward(border)[:, 0].mean() - 0.5) < 0.05
    assert weighted.forward(border)[:, 0].min() > 0.8
    points = xy.reshape(-1, 2)[~left.reshape(-1)]
    assert np.median(weighted.magnification(points) / plain.magnification(points)) < 0.5


@pytest.mark.parametrize("bad, problem", [
    (np.full((4, 5), 2.0), "shape"),
    (np.where(np.eye(4, dtype=bool), np.nan, 1.0), "finite"),
    (np.full((4, 4), 0.5), "in [1"),
    (np.full((4, 4), 1e6), "in [1"),
    (np.full((4, 4), 3e9), "in [1"),
])
def test_bad_importance_is_refused_by_name(gl_backend, bad, problem):
    """A wrong shape or a weight outside [1, MAX_IMPORTANCE] is an InputError that says
    so, raised before anything is uploaded."""
    from addon.core.errors import InputError

    scene = _light_over_floor((4, 4))
    pos = np.tile([0.0, 0.0, -1.0], (4, 4, 1))
    samples = ViewSamples(pos, np.tile([0.0, 0.0, 1.0], (4, 4, 1)), np.ones((4, 4), bool), scene.camera,
                          importance=bad)
    with pytest.raises(InputError, match=problem.replace("[", r"\[")):
        ShadowPipeline(gl_backend).render(scene.light, scene.world_triangles(), samples,
                                          ShadowSettings("dpsm", 16, warp="notw"))


def test_importance_of_missed_pixels_is_never_read():
    """NaN weights on pixels that hit nothing are accepted: they are never uploaded."""
    pos = np.tile([0.0, 0.0, -1.0], (4, 4, 1))
    missed = ViewSamples(pos, pos, np.zeros((4, 4), bool), None, importance=np.full((4, 4), np.nan))
    assert missed.importance_weights() is not None


def test_importance_whose_sum_overflows_a_counter_is_refused():
    """Every sample may land in one texel of a 32-bit counter, so the hit weights may
    sum to 2^32 - 1 at most: 65,536 samples of the largest weight are one too many."""
    from addon.core.errors import InputError
    from addon.render.pipeline import MAX_IMPORTANCE, MAX_IMPORTANCE_TOTAL

    hit = np.ones((256, 256), bool)
    pos = np.tile([0.0, 0.0, -1.0], (256, 256, 1))
    full = ViewSamples(pos, pos, hit, None, importance=np.full((256, 256), MAX_IMPORTANCE))
    with pytest.raises(InputError, match="sum to 4294967296"):
        full.importance_weights()
    hit[0, 0] = False  # one sample fewer fits exactly
    fits = ViewSamples(pos, pos, hit, None, importance=np.full((256, 256), MAX_IMPORTANCE))
    assert fits.importance_weights()[hit].sum(dtype=np.float64) == MAX_IMPORTANCE_TOTAL - (MAX_IMPORTANCE - 1)


def test_one_dispatch_counts_every_cube_face_as_numpy_does(gl_backend):
    """The compute scatter fills each drawn layer's tile from one dispatch, cropped and
    warped, as numpy's projection, slot choice and bincount do."""
    from addon.core import frames, projection
    from addon.render.analysis import stack_tables as _stack_tables
    from addon.render.analysis import warp_of as _warp_of

    scene = _light_over_floor((64, 48))
    rng = np.random.default_rng(12)
    dirs = rng.normal(size=(48, 64, 3))
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    samples = ViewSamples(dirs * rng.uniform(0.5, 3.0, size=(48, 64, 1)), -dirs, np.ones((48, 64), bool),
                          scene.camera)
    pipe = ShadowPipeline(gl_backend)
    result = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("cube", 32, cull=False))
    assert len(result.plan.drawn) == 6
    size = 16
    local = dirs.reshape(-1, 3) @ scene.light.rotation
    slots = frames.pick_slot("cube", local)
    mappings = {}
    for layer in result.plan.drawn:
        lo = rng.uniform(0.0, 0.2, 2)
        rows = W.offsets_from_counts(rng.uniform(0.0, 5.0, size=(size, size)))
        cols = W.offsets_from_counts(rng.uniform(0.0, 5.0, size=(size, size)))
        mappings[layer.slot] = W.LayerMapping(lo, lo + 0.75, _warp_of(rows, cols, size))
    gl_backend.set_warp_tables(*_stack_tables(mappings, size))
    cropped = pipe.count_maps(scene.light, result.plan, {s: W.LayerMapping(m.lo, m.hi) for s, m in mappings.items()},
                              size, 0)
    warped = pipe.count_maps(scene.light, result.plan, mappings, size, 2)
    for layer in result.plan.drawn:
        xy = projection.project(layer.kind, layer.to_local(dirs.reshape(-1, 3)[slots == layer.slot]))
        mapping = mappings[layer.slot]
        uv_crop = (xy * 0.5 + 0.5 - mapping.lo) * mapping.scale
        # float32 on the GPU: a sample within rounding of a texel border may change sides;
        # allow two per face.
        assert cropped[layer.slot].sum() > 0
        assert np.abs(cropped[layer.slot] - W.scatter_counts(uv_crop, size)).sum() <= 2
        assert np.abs(warped[layer.slot] - W.scatter_counts(mapping.forward(xy), size)).sum() <= 2
