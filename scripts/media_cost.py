"""The cost of a scene's media: each method's frame with the media (homogeneous ones and
density grids) and without them, in one run (issue 43).

    .venv/bin/python scripts/media_cost.py REFERENCE.npz [--methods exact,dpsm+notw,dpsm,cube]
                                           [--resolution 1024] [--frames 5]

REFERENCE is a cached reference of a file with homogeneous media (`omniwarp compare --blend
F --cache-dir C` leaves it under C). Per method it renders the scene as the reference has
it and the same scene with the media's triangles taken away, alternating frame by frame,
and prints a markdown table: median total, maps and shadow-test time, their ratio, and the
soft error against the reference of each. The moderngl backend, this machine.
"""
from __future__ import annotations

import argparse
import datetime
import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.compare import light_from_reference, resident_scene, samples_from_reference  # noqa: E402
from addon.core import metrics  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from addon.render.frame import settings_for  # noqa: E402
from addon.render.backends.moderngl.backend import ModernGLBackend  # noqa: E402
from addon.render.pipeline import ShadowPipeline  # noqa: E402
from addon.render.resident import ResidentScene  # noqa: E402
from addon.render.frame import Measure


def without_media(ref: ReferenceData) -> ResidentScene:
    """The reference's scene with its media's triangles and its density grids taken away."""
    surface = ref.surface
    keep = np.flatnonzero(surface.medium < 0) if surface is not None else np.arange(len(ref.triangles))  # no grids
    scene = ResidentScene.of_triangles(ref.triangles.astype(np.float64)[keep], key=f"no_media:{id(ref)}",
                                       surface=surface.take(keep) if surface is not None else None)
    return scene


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reference", type=Path)
    parser.add_argument("--methods", default="exact,dpsm+notw,dpsm,cube")
    parser.add_argument("--resolution", type=int, default=1024)
    parser.add_argument("--frames", type=int, default=5)
    args = parser.parse_args()
    ref = ReferenceData.load(args.reference)
    has_media = ref.surface is not None and ref.surface.has_media
    if not has_media and not ref.grids:
        print(f"{args.reference}: the reference holds no media and no density grids", file=sys.stderr)
        return 2
    light = light_from_reference(ref)
    samples = samples_from_reference(ref)
    pipeline = ShadowPipeline(ModernGLBackend())
    scenes = {"with media": resident_scene(ref), "without": without_media(ref)}
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
    media = ", ".join([f"{m.name} (sigma {', '.join(f'{v:.3g}' for v in m.sigma)} /m)"
                       for m in (ref.surface.media if has_media else ())]
                      + [f"grid {g.name} ({'x'.join(str(n) for n in g.density.shape[::-1])} voxels)" for g in ref.grids])
    print(f"- measured: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, "
          f"{pipeline.backend.renderer()}")
    print(f"- reference: {ref.meta.get('blend', ref.meta.get('preset'))}, {ref.resolution[0]}x{ref.resolution[1]}, "
          f"media: {media}; {int(np.count_nonzero(ref.surface.medium >= 0)) if has_media else 0} of "
          f"{len(ref.triangles)} triangles")
    print(f"- maps at {args.resolution}; medians of {args.frames} frames after a warm-up, the two scenes "
          "alternating frame by frame; soft error % against the reference (with its media), as "
          "`compare` measures it\n")
    print("| method | scene | total ms | maps ms | test ms | total / without | soft error % |")
    print("|---|---|---|---|---|---|---|")
    stages = ("total", "shadow_maps", "shadow_test")
    for method in args.methods.split(","):
        settings = settings_for(method, args.resolution, light.emission)
        for scene in scenes.values():
            pipeline.render(light, scene, samples, settings)  # warm-up: compile, allocate
        times: dict[str, list[dict]] = {name: [] for name in scenes}
        last = {}
        for _ in range(args.frames):
            for name, scene in scenes.items():
                last[name] = pipeline.render(light, scene, samples, settings, measure=Measure(sync_stages=True))
                times[name].append(last[name].time_ms)
        base = statistics.median(t["total"] for t in times["without"])
        for name in scenes:
            ms = [statistics.median(t[stage] for t in times[name]) for stage in stages]
            soft = metrics.judge(last[name].visibility, ref.shadowed, ref.unshadowed, evaluable, sized=light.sized,
                                 noise=ref.visibility_noise).soft_error_pct
            print(f"| {method} | {name} | {ms[0]:.1f} | {ms[1]:.1f} | {ms[2]:.1f} | {ms[0] / base:.2f} | {soft:.3f} |")
    for scene in scenes.values():
        pipeline.backend.release_scene(scene)
    pipeline.backend.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
