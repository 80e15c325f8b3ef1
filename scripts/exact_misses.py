"""Why `exact` and Cycles disagree on a preset, pixel by pixel (issue 26).

    .venv/bin/python scripts/exact_misses.py PRESET [PRESET ...] [--size 640x480] [--resolution 1024]

A PRESET may also be a cached reference file (`.npz`, as `omniwarp compare --blend` keeps
one per file and light in its cache folder) of a hard light; its triangles alone are
drawn (hair and points are not).

For every evaluated, non-fractional pixel where `exact` (dpsm+notw lists; sm's for a spot
or a sun) and the cached Cycles reference disagree, the segment from the light to Cycles'
own position of the pixel is cast in float64 against the reference's triangles. A pixel
is then:
- `reference`: float64 agrees with `exact` (Cycles' float32 decided otherwise);
- `ours`: float64 agrees with Cycles.
Each line gives the nearest crossing's fraction f of the segment (1 at the sample) and how
far, relative to the segment's length, the segment passes from that triangle's edge
(negative: inside by that much).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.compare import light_from_reference, samples_from_reference  # noqa: E402
from addon.core import metrics  # noqa: E402
from addon.core.scene import parse_size  # noqa: E402
from addon.reference.cache import load_or_capture  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from addon.render.backends.moderngl.backend import ModernGLBackend  # noqa: E402
from addon.render.pipeline import ShadowPipeline, ShadowSettings  # noqa: E402
from addon.render.passes.exact import EXACT_EPS  # noqa: E402


def nearest_crossing(light: np.ndarray, point: np.ndarray, tris: np.ndarray) -> tuple[float, float] | None:
    """Over the triangles whose plane cuts the segment light -> point before the receiver
    margin: (f, edge margin) of the one the segment passes deepest inside, or nearest to."""
    d = point - light
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    denom = normals @ d
    ok = np.abs(denom) > 1e-300
    f = np.where(ok, np.einsum("tk,tk->t", normals, tris[:, 0] - light) / np.where(ok, denom, 1.0), -1.0)
    cut = ok & (f > 0.0) & (f < 1.0 - EXACT_EPS)
    if not cut.any():
        return None
    crossing = light + f[cut, None] * d
    t, n = tris[cut], normals[cut]
    inside = np.ones(len(t), dtype=bool)
    nearest = np.full(len(t), np.inf)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        edge = t[:, b] - t[:, a]
        inside &= np.einsum("tk,tk->t", np.cross(edge, crossing - t[:, a]), n) >= 0.0
        s = np.clip(np.einsum("tk,tk->t", crossing - t[:, a], edge) / np.einsum("tk,tk->t", edge, edge), 0.0, 1.0)
        nearest = np.minimum(nearest, np.linalg.norm(crossing - (t[:, a] + s[:, None] * edge), axis=1))
    margin = np.where(inside, -nearest, nearest) / np.linalg.norm(d)
    k = int(np.argmin(margin))
    return float(f[cut][k]), float(margin[k])


def _exact_settings(light, resolution: int) -> ShadowSettings:
    """`exact` over the lists of dpsm+notw for a point light, of sm for a spot or a sun."""
    if light.emission in ("spot", "sun"):
        return ShadowSettings("sm", resolution, exact=True)
    return ShadowSettings("dpsm", resolution, warp="notw", exact=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("presets", nargs="+")
    parser.add_argument("--size", type=parse_size, default=(640, 480))
    parser.add_argument("--resolution", type=int, default=1024)
    args = parser.parse_args(argv)
    backend = ModernGLBackend()
    try:
        for preset in args.presets:
            ref = ReferenceData.load(preset) if preset.endswith(".npz") else load_or_capture(preset, args.size)
            light = light_from_reference(ref)
            evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
            ratio = metrics.reference_ratio(ref.shadowed, ref.unshadowed)
            decisive = evaluable & ~((ratio > metrics.FRACTIONAL_BAND[0]) & (ratio < metrics.FRACTIONAL_BAND[1]))
            vis = ShadowPipeline(backend).render(light, ref.triangles.astype(np.float64), samples_from_reference(ref),
                                                 _exact_settings(light, args.resolution)).visibility
            bad = decisive & ((vis > 0.5) != (ratio >= 0.5))
            tris = ref.triangles.astype(np.float64)
            origin = np.asarray(light.position, dtype=np.float64)
            counts = {"reference": 0, "ours": 0}
            print(f"{preset}: {int(bad.sum())} of {int(decisive.sum())} pixels disagree")
            for y, x in zip(*np.nonzero(bad)):
                crossing = nearest_crossing(origin, ref.position[y, x].astype(np.float64), tris)
                blocked = crossing is not None and crossing[1] <= 0.0
                exact_lit = bool(vis[y, x] > 0.5)
                side = "reference" if blocked != exact_lit else "ours"
                counts[side] += 1
                what = "no crossing" if crossing is None else f"f {crossing[0]:.6f} edge margin {crossing[1]:+.1e}"
                print(f"  ({y}, {x}) exact {'lit' if exact_lit else 'shadowed'}, Cycles "
                      f"{'shadowed' if exact_lit else 'lit'}: {what} -> {side}")
            print(f"  {preset}: {counts['reference']} the reference's, {counts['ours']} ours")
    finally:
        backend.release()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
