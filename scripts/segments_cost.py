"""What a sized light's `exact` frame costs by segments through the tree
(render/passes/segments.py) and, on request, by its lists, on a cached Cycles reference.

    .venv/bin/python scripts/segments_cost.py REFERENCE.npz [--points 16,64,256] [--lists]
        [--json OUT.json]

REFERENCE is a reference file that `omniwarp compare --blend` cached for a sized light; its
triangles are the blockers (its hair and points are not read, so the frame takes the
segments). For each point count, one `exact` frame (dpsm+notw lists' plan, or sm for a
spot or sun; maps of 1024) through the pipeline on moderngl, waited for: its seconds, the
segments' turns, and the soft error against Cycles with the reference's noise
(core/metrics.judge). `--lists` adds the same frame by the lists' walk, and whether the two
visibilities agree.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.compare import samples_from_reference  # noqa: E402
from addon.core import metrics  # noqa: E402
from addon.core.errors import OmniWarpError  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from addon.render.backends.moderngl.backend import ModernGLBackend  # noqa: E402
from addon.render.frame import ShadowSettings  # noqa: E402
from addon.render.pipeline import ShadowPipeline  # noqa: E402
from addon.render.resident import ResidentScene  # noqa: E402

RESOLUTION = 1024


def frame(backend, ref: ReferenceData, points: int, segments: bool) -> dict:
    """One exact frame of `points` light points; its seconds, turns and errors."""
    light = ref.light_spec()
    if not light.shape.sized:
        raise OmniWarpError(f"the reference's light {ref.meta.get('light')!r} has no size")
    projective = light.emission in ("spot", "sun")
    settings = ShadowSettings("sm" if projective else "dpsm", RESOLUTION, warp="none" if projective else "notw",
                              exact=True, exact_samples=points, exact_segments=segments)
    scene = ResidentScene.of_triangles(np.asarray(ref.triangles, dtype=np.float64))
    start = time.perf_counter()
    visibility = ShadowPipeline(backend).render(light, scene, samples_from_reference(ref), settings).visibility
    seconds = time.perf_counter() - start
    backend.release_scene(scene)
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
    judged = metrics.judge(visibility, ref.shadowed, ref.unshadowed, evaluable, sized=True,
                           noise=ref.visibility_noise)
    noise = judged.reference_noise_pct
    return {"walk": "segments" if segments else "lists", "points": points, "seconds": round(seconds, 2),
            "turns": backend.segments.turns if segments else None,
            "soft_error_pct": round(judged.soft_error_pct, 3),
            "reference_noise_pct": None if noise is None else round(noise, 3), "visibility": visibility}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("reference", type=Path)
    parser.add_argument("--points", default="16,64,256", help="comma-separated light point counts (squares)")
    parser.add_argument("--lists", action="store_true", help="also run each frame by the lists' walk")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    try:
        counts = [int(p) for p in args.points.split(",") if p.strip()]
        ref = ReferenceData.load(args.reference)
        rows = []
        with ModernGLBackend() as backend:
            for points in counts:
                walks = [frame(backend, ref, points, True)]
                if args.lists:
                    walks.append(frame(backend, ref, points, False))
                    walks[1]["same_visibility"] = bool(np.array_equal(walks[0]["visibility"], walks[1]["visibility"]))
                for row in walks:
                    row.pop("visibility")
                    row.update(size=list(ref.hit.shape[::-1]), triangles=int(len(ref.triangles)),
                               renderer=backend.renderer())
                    print(json.dumps(row), flush=True)
                    rows.append(row)
    except (OmniWarpError, ValueError) as exc:  # a file that is not a reference, a bad count
        print(f"segments_cost: {exc}", file=sys.stderr)
        return 2
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
