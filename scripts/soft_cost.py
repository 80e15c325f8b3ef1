"""The cost of soft shadows against the hard version of each method, in one run (issue 27).

    .venv/bin/python scripts/soft_cost.py REFERENCE.npz [--methods dpsm,dpsm+notw,exact,...]
                                          [--resolution 1024] [--frames 5] [--light-samples 16,36,64]
                                          [--exact-samples 16,64,256]

REFERENCE is a cached sized-light reference (`omniwarp reference --blend F --light L`
writes it under .cache/reference/). Per method it renders the light hard (its size
taken away) and sized with each light-sample count (the filter's taps, or for `exact` its
points per view sample), alternating frame by frame, and prints a markdown table: median
total, maps and shadow-test time, their ratio to hard, and the error against the
reference. The moderngl backend, this machine.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.compare import light_from_reference, resident_scene, samples_from_reference  # noqa: E402
from addon.core import metrics  # noqa: E402
from addon.core.light_shape import POINT  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from addon.render.frame import settings_for  # noqa: E402
from addon.render.backends.moderngl.backend import ModernGLBackend  # noqa: E402
from addon.render.pipeline import ShadowPipeline  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reference", type=Path)
    parser.add_argument("--methods", default="dpsm,dpsm+notw,cube,cube+notw")
    parser.add_argument("--resolution", type=int, default=1024)
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--light-samples", default="16,36,64")
    parser.add_argument("--exact-samples", default="16,64,256")
    args = parser.parse_args()
    ref = ReferenceData.load(args.reference)
    sized = light_from_reference(ref)
    if not sized.sized:
        print(f"{args.reference}: its light has no size", file=sys.stderr)
        return 2
    hard = dataclasses.replace(sized, shape=POINT)
    samples = samples_from_reference(ref)
    pipeline = ShadowPipeline(ModernGLBackend())
    scene = resident_scene(ref)
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, sized)
    counts = [int(v) for v in args.light_samples.split(",")]
    exact_counts = [int(v) for v in args.exact_samples.split(",")]
    print(f"- measured: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, "
          f"{pipeline.backend.renderer()}")
    print(f"- reference: {ref.meta.get('blend', ref.meta.get('preset'))}, light {ref.meta.get('light')} "
          f"({sized.shape.describe()}), {ref.resolution[0]}x{ref.resolution[1]}, {ref.meta.get('samples')} samples")
    print(f"- maps at {args.resolution}; medians of {args.frames} frames after a warm-up, the variants "
          "alternating frame by frame\n")
    print("| method | light | light samples | total ms | maps ms | test ms | total / hard | maps / hard | test / hard "
          "| error % | soft error % |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for method in args.methods.split(","):
        exact = settings_for(method, args.resolution, sized.emission).exact
        variants = [("hard", hard, 1)] + [("sized", sized, n) for n in (exact_counts if exact else counts)]
        key = "exact_samples" if exact else "light_samples"
        settings = [settings_for(method, args.resolution, sized.emission, **{key: n}) for _, _, n in variants]
        for (_, light, _), s in zip(variants, settings):
            pipeline.render(light, scene, samples, s)  # warm-up: compile, allocate
        times: list[list[dict]] = [[] for _ in variants]
        last = [None] * len(variants)
        for _ in range(args.frames):
            for i, ((_, light, _), s) in enumerate(zip(variants, settings)):
                last[i] = pipeline.render(light, scene, samples, s)
                times[i].append(last[i].time_ms)
        stages = ("total", "shadow_maps", "shadow_test")
        base = [statistics.median(t[stage] for t in times[0]) for stage in stages]
        for (kind, _, n), frames, result in zip(variants, times, last):
            ms = [statistics.median(t[stage] for t in frames) for stage in stages]
            judged = metrics.judge(result.visibility, ref.shadowed, ref.unshadowed, evaluable, sized=True)
            ratios = " | ".join(f"{a / b:.2f}" for a, b in zip(ms, base))
            print(f"| {method} | {kind} | {n if kind == 'sized' else ''} | {ms[0]:.1f} | {ms[1]:.1f} | {ms[2]:.1f} | "
                  f"{ratios} | {judged.figure.error_pct:.3f} | {judged.soft_error_pct:.3f} |", flush=True)
    pipeline.backend.release()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
