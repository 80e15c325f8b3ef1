"""Hair and points at scale (issue 42): the host's cost of a frame with 100,000 strands
or 1,000,000 points, beside a mesh of as many triangles as they have pieces.

    python scripts/pieces_scale.py [--strands N] [--points N] [--method dpsm] [--frames 3] [--out FILE.md]

Per scene: the time to sample and set the pieces (once), the first frame (upload and
compile), and of the steady frames the median `prepare` stage (the host's per-frame
work: sync, plan, chunk runs) and the whole frame, on the moderngl backend.
"""
from __future__ import annotations

import argparse
import datetime
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.core.blockers import Spheres, Strands, pieces  # noqa: E402
from addon.core.camera import CameraSpec  # noqa: E402
from addon.core.scene import LightSpec, look_at  # noqa: E402
from addon.render.frame import ViewSamples, settings_for  # noqa: E402
from addon.render.backends.moderngl.backend import ModernGLBackend  # noqa: E402
from addon.render.pipeline import ShadowPipeline  # noqa: E402
from addon.render.resident import ResidentScene  # noqa: E402
from addon.render.frame import Measure


def groom(count: int, seed: int = 1) -> Strands:
    """`count` strands of 12 points rising from a 1 m patch and bending over, 1 mm radius."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, 12)[None, :, None]
    roots = np.concatenate([rng.uniform(-0.5, 0.5, (count, 2)), np.full((count, 1), 0.2)], axis=1)[:, None, :]
    bend = np.concatenate([rng.normal(size=(count, 2)) * 0.1, np.zeros((count, 1))], axis=1)[:, None, :]
    points = roots + bend * t * t + np.array([0.0, 0.0, 0.3]) * t
    return Strands(points.reshape(-1, 3), np.full(count * 12, 0.001), np.arange(0, count * 12 + 1, 12))


def scatter(count: int, seed: int = 2) -> Spheres:
    rng = np.random.default_rng(seed)
    centres = np.concatenate([rng.uniform(-1.0, 1.0, (count, 2)), rng.uniform(0.05, 0.6, (count, 1))], axis=1)
    return Spheres(centres, rng.uniform(0.002, 0.006, count))


def slivers(count: int, seed: int = 3) -> np.ndarray:
    """`count` small triangles over the same patch: the mesh of as many primitives."""
    rng = np.random.default_rng(seed)
    centres = np.concatenate([rng.uniform(-1.0, 1.0, (count, 2)), rng.uniform(0.05, 0.6, (count, 1))], axis=1)
    return centres[:, None, :] + rng.normal(size=(count, 3, 3)) * 0.004


def ground_samples(w: int = 160, h: int = 120) -> ViewSamples:
    x, y = np.meshgrid(np.linspace(-1.2, 1.2, w), np.linspace(0.9, -0.9, h))
    positions = np.stack([x, y, np.zeros_like(x)], axis=-1)
    camera = CameraSpec(look_at((0.0, -0.5, 5.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0)), 50.0, (w, h))
    normals = np.broadcast_to([0.0, 0.0, 1.0], positions.shape).copy()
    return ViewSamples(positions, normals, np.ones((h, w), bool), camera)


def measure(pipe: ShadowPipeline, label: str, build, method: str, frames: int) -> dict:
    ground = np.array([[[-3, -3, 0], [3, -3, 0], [3, 3, 0]], [[-3, -3, 0], [3, 3, 0], [-3, 3, 0]]], float)
    start = time.perf_counter()
    scene = ResidentScene.of_triangles(ground)
    count = build(scene)
    set_ms = (time.perf_counter() - start) * 1e3
    light = LightSpec("omni", look_at((0.3, 0.2, 2.5), (0.0, 0.0, 0.0)))
    samples = ground_samples()
    settings = settings_for(method, 1024, "omni")
    start = time.perf_counter()
    pipe.render(light, scene, samples, settings).visibility
    first_ms = (time.perf_counter() - start) * 1e3
    steady = [pipe.render(light, scene, samples, settings, measure=Measure(sync_stages=True)) for _ in range(frames)]
    pipe.backend.release_scene(scene)
    return {"scene": label, "primitives": count, "set_ms": set_ms, "first_ms": first_ms,
            "prepare_ms": statistics.median(f.time_ms["prepare"] for f in steady),
            "total_ms": statistics.median(f.time_ms["total"] for f in steady)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--strands", type=int, default=100_000)
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--method", default="dpsm")
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    pipe = ShadowPipeline(ModernGLBackend())

    def with_strands(scene):
        held = pieces(None, groom(args.strands))
        scene.set_pieces("hair", held)
        return len(held)

    def with_points(scene):
        held = pieces(scatter(args.points), None)
        scene.set_pieces("points", held)
        return len(held)

    rows = [measure(pipe, f"{args.strands:,} strands of 12 points", with_strands, args.method, args.frames),
            measure(pipe, f"{args.points:,} points", with_points, args.method, args.frames)]
    for row in list(rows):
        count = row["primitives"]
        rows.append(measure(pipe, f"mesh of {count:,} triangles",
                            lambda scene, n=count: (scene.set_geometry("mesh", slivers(n)), n)[1],
                            args.method, args.frames))
    lines = [f"# Hair and points at scale ({args.method} @ 1024, moderngl: {pipe.backend.renderer()}, "
             f"{datetime.date.today().isoformat()})", "",
             "| scene | pieces or triangles | set (ms, once) | first frame (ms) | prepare (ms, steady) | frame (ms, steady) |",
             "|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['scene']} | {row['primitives']:,} | {row['set_ms']:.0f} | {row['first_ms']:.0f} | "
                     f"{row['prepare_ms']:.2f} | {row['total_ms']:.0f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
