"""How much resolution could ANY count-driven warp give where a plain map errs?

Study script for docs/warping.md (issue 3). For one preset and one resolution it:
1. renders the plain dual-paraboloid map and finds the pixels that disagree with Cycles;
2. computes, per view sample, the local sample density of the plain map (samples per
   texel, averaged over a (2k+1)^2 texel window);
3. reports the area gain an ideal warp would give those pixels. A perfect density-
   equalising warp spreads the N samples evenly over all T texels, so a sample whose
   plain density is d gets (T / N) * d times the texel area it had, and the square root
   of that in linear resolution. Real warps (separable, smoothed, with a floor) get less.

Run: .venv/bin/python scripts/ideal_warp_bound.py room_omni [1024]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.compare import light_from_reference, samples_from_reference  # noqa: E402
from addon.core import frames, metrics, projection, warping  # noqa: E402
from addon.reference.cache import load_or_capture  # noqa: E402
from addon.render.backends.moderngl.backend import ModernGLBackend  # noqa: E402
from addon.render.pipeline import ShadowPipeline, ShadowSettings  # noqa: E402

WINDOW = 8  # half-width in texels of the density window


def box_mean(counts: np.ndarray, k: int) -> np.ndarray:
    """Mean of a (2k+1)^2 window around every texel (zero outside the map)."""
    padded = np.pad(counts, ((k + 1, k), (k + 1, k)))
    csum = padded.cumsum(0).cumsum(1)
    n = 2 * k + 1
    return (csum[n:, n:] - csum[:-n, n:] - csum[n:, :-n] + csum[:-n, :-n]) / n ** 2


def main(preset: str, resolution: int) -> None:
    ref = load_or_capture(preset, (640, 480))
    light = light_from_reference(ref)
    samples = samples_from_reference(ref)
    backend = ModernGLBackend()
    try:
        result = ShadowPipeline(backend).render(light, ref.triangles.astype(np.float64), samples,
                                                ShadowSettings("dpsm", resolution, cull=False))
    finally:
        backend.release()
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
    wrong = ((result.visibility > 0.5) != metrics.reference_visibility(ref.shadowed, ref.unshadowed)) & evaluable
    offsets = ref.position.astype(np.float64) - light.position
    slots = frames.pick_slot("dpsm", offsets @ light.rotation)
    density = np.full(evaluable.shape, np.nan)
    layers = frames.light_layers(light, "dpsm")
    for layer in layers:
        chosen = evaluable & (slots == layer.slot)
        if not chosen.any():
            continue
        uv = projection.project(layer.kind, layer.to_local(offsets[chosen])) * 0.5 + 0.5
        local = box_mean(warping.scatter_counts(uv, resolution), WINDOW)
        texel = np.clip((uv * resolution).astype(int), 0, resolution - 1)
        density[chosen] = local[texel[:, 1], texel[:, 0]]
    texels_per_sample = len(layers) * resolution ** 2 / evaluable.sum()
    gain = density[wrong] * texels_per_sample
    everywhere = density[evaluable] * texels_per_sample
    print(f"{preset} dpsm {resolution}: {wrong.sum()} wrong of {evaluable.sum()} evaluated pixels "
          f"({100.0 * wrong.sum() / evaluable.sum():.3f} %), {texels_per_sample:.2f} texels per sample")
    print(f"  ideal area gain at the wrong pixels: median {np.median(gain):.2f} "
          f"(quartiles {np.percentile(gain, 25):.2f}-{np.percentile(gain, 75):.2f}), "
          f"linear {np.sqrt(np.median(gain)):.2f}")
    print(f"  ideal area gain over all samples: median {np.median(everywhere):.2f}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "room_omni", int(sys.argv[2]) if len(sys.argv) > 2 else 1024)
