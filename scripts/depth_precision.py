"""Depth-precision study: how well normalised radial depth survives storage.

    python scripts/depth_precision.py    prints the markdown table of docs/stability.md

The depth pass stores d = (L - near) / (far - near) and the test reads back
L' = near + d (far - near). The relative error |L' - L| / L must stay well below the
shadow test's constant bias, which is 0.3 texel footprints, i.e. 0.3 * alpha of L
(alpha = one texel's angle; 4/res at a paraboloid's centre, the smallest it gets).
"""
from __future__ import annotations

import numpy as np

RATIOS = (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 0.0)
BITS_24 = float(2**24 - 1)


def relative_errors(ratio: float, count: int = 20001) -> dict[str, float]:
    """Largest relative distance error of float32 and of 24-bit fixed-point storage.

    Distances are spread log-uniformly from near to far (far = 1); ratio = near / far,
    0 meaning the light sits inside the scene's bounds (near = 0).
    """
    far = 1.0
    near = ratio * far
    start = max(near, 1e-7)
    distance = np.geomspace(start, far, count)
    depth = (distance - near) / (far - near)
    as_float = near + depth.astype(np.float32).astype(np.float64) * (far - near)
    as_fixed = near + np.round(depth * BITS_24) / BITS_24 * (far - near)
    return {
        "float32": float(np.max(np.abs(as_float - distance) / distance)),
        "fixed24": float(np.max(np.abs(as_fixed - distance) / distance)),
    }


def constant_bias(resolution: int, constant: float = 0.3) -> float:
    """The shadow test's smallest constant bias relative to L: constant * 4 / res."""
    return constant * 4.0 / resolution


def table(resolution: int = 4096) -> str:
    """Markdown table: errors against the smallest bias at `resolution`."""
    bias = constant_bias(resolution)
    lines = [f"| near / far | float32 max rel. error | 24-bit max rel. error | bias at {resolution} | float32 safe | 24-bit safe |",
             "|---|---|---|---|---|---|"]
    for ratio in RATIOS:
        err = relative_errors(ratio)
        label = "0 (light inside)" if ratio == 0 else f"{ratio:.0e}"
        lines.append(f"| {label} | {err['float32']:.1e} | {err['fixed24']:.1e} | {bias:.1e} "
                     f"| {'yes' if err['float32'] < 0.1 * bias else 'no'} | {'yes' if err['fixed24'] < 0.1 * bias else 'no'} |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(table())
