"""What an area light's exact shadow costs by segments through a tree (core/ray_tree.py,
lib/ray_tree.glsl, gpu_shaders/ray_share.frag) instead of the exact pass's lists, on a
cached Cycles reference, and how far it lies from Cycles.

    .venv/bin/python scripts/ray_cost.py REFERENCE.npz [--points 256] [--json OUT.json]

REFERENCE is a reference file that `omniwarp compare --blend` cached for an area light of
full spread (no spot, no sphere or sun yet); its triangles are the blockers (its hair and
points are not read). Per view sample, one segment to each of the light's points
(core/light_shape.stratified_points, as the exact pass takes them), weighed as that pass
weighs them. The turns (each at most RAY_TREE_BUDGET units of work a sample: llvmpipe cuts
longer loops) go on until every sample has all its points. Prints the tree's build time,
the GPU time of all turns, the turns, the mean visits a segment, and the soft error against
Cycles with its noise (core/metrics.judge).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.core import light_shape, metrics, ray_tree  # noqa: E402
from addon.core.errors import InputError, OmniWarpError  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from addon.render.backends.moderngl.glsl import glsl_header  # noqa: E402
from addon.render.backends.moderngl.uniforms import BLOCK_BINDING  # noqa: E402
from addon.render.passes.exact import EXACT_EPS  # noqa: E402
from addon.render.shaders import ProgramInterface, Uniform, load_source  # noqa: E402
from addon.render.shaders.constants import RAY_TREE_BUDGET, RAY_TREE_WIDTH  # noqa: E402
from addon.render.shaders.uniform_block import BlockState, UniformBlock  # noqa: E402

IFACE = ProgramInterface(
    name="ray_share", vertex_file="fullscreen.vert", fragment_file="ray_share.frag",
    vertex_in=(("vec2", "ow_corner"),), fragment_out=(("vec4", "ow_state_out"), ("vec4", "ow_sums_out")),
    uniforms=(Uniform("int", "ow_tree_leaves"), Uniform("int", "ow_points"), Uniform("float", "ow_tree_eps"),
              Uniform("int", "ow_budget")),
    samplers=("ow_samples", "ow_normals", "ow_state_in", "ow_sums_in", "ow_points_table", "ow_tree_boxes",
              "ow_tree_tris"))
RENDERER = "moderngl (EGL)"


@dataclass
class Shares:
    visibility: np.ndarray  # (H, W): lit weight over all weight, 1 off geometry
    build_s: float  # the tree on the host
    gpu_s: float  # all turns, each waited for
    turns: int
    visits: np.ndarray  # (H, W): units of work (boxes and triangles) a sample spent


def shares(ctx, triangles: np.ndarray, position: np.ndarray, normal: np.ndarray, hit: np.ndarray,
           points: np.ndarray, budget: int = RAY_TREE_BUDGET) -> Shares:
    """Each sample's share of an area light (its frame: centre at the origin, emitting along
    -Z; `points` (N, 3) on it) through `triangles` (T, 3, 3), all in that frame."""
    import moderngl

    start = time.perf_counter()
    tree = ray_tree.build(triangles)
    boxes, corners = ray_tree.texels(tree, RAY_TREE_WIDTH)
    build_s = time.perf_counter() - start
    h, w = hit.shape
    made: list = []

    def texture(data: np.ndarray):
        data = np.ascontiguousarray(data, dtype="f4")
        made.append(ctx.texture((data.shape[1], data.shape[0]), 4, data.tobytes(), dtype="f4"))
        made[-1].filter = (moderngl.NEAREST, moderngl.NEAREST)
        return made[-1]

    samples = np.zeros((h, w, 4), dtype=np.float32)
    samples[..., :3], samples[..., 3] = position, hit
    normals = np.zeros((h, w, 4), dtype=np.float32)
    normals[..., :3] = normal
    table = np.zeros((1, len(points), 4), dtype=np.float32)
    table[0, :, :3] = points
    bound = {"ow_samples": texture(samples), "ow_normals": texture(normals), "ow_points_table": texture(table),
             "ow_tree_boxes": texture(boxes), "ow_tree_tris": texture(corners)}
    first = np.zeros((h, w, 4), dtype=np.float32)
    first[..., 1] = 1.0  # node 1: a new walk
    pairs = [(texture(first), texture(np.zeros((h, w, 4)))) for _ in range(2)]
    made += [ctx.framebuffer(list(pair)) for pair in pairs]
    fbos = made[-2:]
    vertex = glsl_header(IFACE, "vertex") + load_source(IFACE.vertex_file)
    fragment = glsl_header(IFACE, "fragment") + load_source(IFACE.fragment_file)
    made.append(ctx.program(vertex_shader=vertex, fragment_shader=fragment))
    prog = made[-1]
    state = BlockState(UniformBlock.of(IFACE))
    state.update({"ow_tree_leaves": tree.leaves, "ow_points": len(points), "ow_tree_eps": EXACT_EPS,
                  "ow_budget": int(budget)})
    made.append(ctx.buffer(state.data))
    made[-1].bind_to_uniform_block(BLOCK_BINDING)
    made.append(ctx.buffer(np.array([[-1, -1], [3, -1], [-1, 3]], dtype="f4").tobytes()))
    made.append(ctx.vertex_array(prog, [(made[-1], "2f", "ow_corner")]))
    vao = made[-1]
    try:
        gpu_s, turns, current = 0.0, 0, 0
        state_now = first
        while True:
            turn = dict(bound, ow_state_in=pairs[current][0], ow_sums_in=pairs[current][1])
            for unit, name in enumerate(IFACE.samplers):
                turn[name].use(unit)
                prog[name].value = unit
            current = 1 - current
            fbos[current].use()
            tick = time.perf_counter()
            vao.render()
            ctx.finish()
            gpu_s += time.perf_counter() - tick
            turns += 1
            state_before, state_now = state_now, np.frombuffer(pairs[current][0].read(), dtype="f4").reshape(h, w, 4)
            if not np.any((state_now[..., 0] < len(points)) & hit):
                break
            if np.array_equal(state_now[..., :2], state_before[..., :2]):
                raise RuntimeError(f"ray_cost: turn {turns} moved no walk on (a budget of {budget} is too small)")
        sums = np.frombuffer(pairs[current][1].read(), dtype="f4").reshape(h, w, 4).astype(np.float64)
    finally:
        for obj in reversed(made):
            obj.release()
    lit = sums[..., 1] > 0.0
    visibility = np.where(lit, sums[..., 0] / np.where(lit, sums[..., 1], 1.0), 1.0)
    return Shares(visibility, build_s, gpu_s, turns, state_now[..., 2].astype(np.float64))


def run(ref: ReferenceData, points: int) -> dict:
    """The measurement on one reference (see the module's docstring)."""
    import moderngl

    shape = ref.light_shape()
    if not isinstance(shape, light_shape.Area) or shape.spread < math.pi - 1e-6:
        raise InputError(f"needs an area light of full spread; this reference's light is {shape!r}")
    m = np.asarray(ref.light_matrix, dtype=np.float64)
    centre, axes = m[:3, 3], m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    frame = {"triangles": (np.asarray(ref.triangles, dtype=np.float64) - centre) @ axes,
             "position": (np.asarray(ref.position, dtype=np.float64) - centre) @ axes,
             "normal": np.asarray(ref.normal, dtype=np.float64) @ axes}
    ctx = moderngl.create_standalone_context(backend="egl")
    try:
        got = shares(ctx, hit=np.asarray(ref.hit, dtype=bool),
                     points=light_shape.stratified_points(shape, points), **frame)
    finally:
        ctx.release()
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, ref.light_spec())
    judged = metrics.judge(got.visibility, ref.shadowed, ref.unshadowed, evaluable, sized=True,
                           noise=getattr(ref, "visibility_noise", None))
    segments = max(1, int(np.count_nonzero(ref.hit)) * points)
    noise = judged.reference_noise_pct
    return {"triangles": int(len(frame["triangles"])), "size": list(ref.hit.shape[::-1]), "points": points,
            "build_s": round(got.build_s, 3), "gpu_s": round(got.gpu_s, 3), "turns": got.turns,
            "visits_per_segment": round(float(got.visits[ref.hit].sum()) / segments, 1),
            "soft_error_pct": round(judged.soft_error_pct, 3),
            "reference_noise_pct": None if noise is None else round(noise, 3), "renderer": RENDERER}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("reference", type=Path)
    parser.add_argument("--points", type=int, default=256)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    if args.points < 1:
        parser.error("--points must be at least 1")
    try:
        result = run(ReferenceData.load(args.reference), args.points)
    except OmniWarpError as exc:  # a file that is not a reference, a light it cannot take
        print(f"ray_cost: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(result))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
