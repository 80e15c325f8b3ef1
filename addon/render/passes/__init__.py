"""The passes of a frame, each written once over the primitives of render/device.py.

Each function takes the `backend.ShadowBackend` whose state it reads and writes:
atlas (the atlas and the depth pass), footprints (the ray table and the footprint and
exact map passes), samples (view samples, warp tables, count scatters and the planning
reductions), warp (the NoTW warp built on the GPU), exact (the irregular z-buffer's lists
and rounds), segments (a sized light's exact marks by segments through a tree), edges (the edge-distance map), shadow_test (the visibility of every sample)
and alpha (see-through maps and the veil).
"""
from . import alpha, atlas, edges, exact, footprints, samples, segments, shadow_test, warp  # noqa: F401
