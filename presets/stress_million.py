"""A 1,002,528-triangle heightfield (708x708 quads) under an omni light."""

import numpy as np

DESCRIPTION = ("A 24x24 m rolling heightfield of 708x708 quads (1,002,528 triangles, built vectorised) with three "
               "pillars; an omni light 4.5 m up (2 m over the highest hill), the camera looking down across the "
               "hills.")
STRESSES = ("a 1M-triangle mesh: the CPU side (sanitising, seam splitting, tessellation, culling) and the vertex "
            "upload must scale; hills shadow each other, so terrain self-shadowing at small triangle sizes (3.4 cm, "
            "about 2-3 texels at 1024) also tests bias. Documented degradation: near the onsets of the hills' "
            "self-shadows the receivers are grazing, and the normal-offset bias lifts some of them out of their "
            "shadow (false lit).")

QUADS = 708
SIZE = 24.0


def heightfield(n: int = QUADS, size: float = SIZE):
    """Vertices ((n+1)^2, 3) and triangles (2 n^2, 3) of the terrain, deterministic."""
    xs = np.linspace(-size / 2.0, size / 2.0, n + 1)
    gx, gy = np.meshgrid(xs, xs, indexing="xy")
    gz = (0.9 * np.sin(0.55 * gx) * np.cos(0.45 * gy) + 0.35 * np.sin(1.3 * gx + 0.7 * gy)
          + 0.15 * np.cos(2.1 * gy - 0.4 * gx)) + 1.0
    verts = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)
    idx = np.arange((n + 1) * (n + 1), dtype=np.int64).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return verts, tris


def build(b) -> None:
    verts, tris = heightfield()
    b.mesh("terrain", verts, tris)
    for i, (x, y) in enumerate([(-3.0, 2.0), (2.5, -1.5), (0.5, 4.0)]):
        b.box(f"pillar_{i}", (x, y, 2.0), (0.4, 0.4, 4.0))
    b.point_light((0.5, -0.3, 4.5), energy=5000.0)
    b.camera((14.0, -14.0, 10.0), (0.0, 0.0, 1.0), fov_deg=60.0)
