"""Occluders (and the floor) placed with negative-determinant world matrices."""

DESCRIPTION = ("An omni light 2.5 m over a floor that is mirrored in y; the same L-shaped prism is placed five times:"
               " as is, mirrored in x, flipped upside down, scaled by -1 in all axes and by (-1.5, 0.7, 1) turned 30 "
               "degrees.")
STRESSES = ("negative object scale: mirrored world matrices (determinant < 0) reverse the triangle winding, so face "
            "normals computed from the winding point inward; anything that relies on winding (back-face culling, "
            "plane offsets, normal bias) must not drop or mis-bias these occluders. The shadows must match the "
            "un-mirrored geometry's mirror images.")

# An L-shaped prism: the L in the xy plane (outer corner at the origin), 0.5 m tall.
_L = [(0.0, 0.0), (1.0, 0.0), (1.0, 0.3), (0.3, 0.3), (0.3, 0.8), (0.0, 0.8)]


def _prism(height: float = 0.5):
    n = len(_L)
    verts = [(x, y, 0.0) for x, y in _L] + [(x, y, height) for x, y in _L]
    # Caps: the L split into 4 triangles from corner 0 / corner 3 (counter-clockwise from above).
    top = [(0, 1, 2), (0, 2, 3), (0, 3, 4), (0, 4, 5)]
    tris = [(a + n, b + n, c + n) for a, b, c in top] + [(a, c, b) for a, b, c in top]
    for i in range(n):
        j = (i + 1) % n
        tris += [(i, j, j + n), (i, j + n, i + n)]
    return verts, tris


def _matrix(diag, offset, turn_deg: float = 0.0):
    import math

    c, s = math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg))
    sx, sy, sz = diag
    return [[c * sx, -s * sy, 0.0, offset[0]],
            [s * sx, c * sy, 0.0, offset[1]],
            [0.0, 0.0, sz, offset[2]],
            [0.0, 0.0, 0.0, 1.0]]


PLACEMENTS = {
    "prism_plain": ((1.0, 1.0, 1.0), (-2.5, -1.0, 0.0), 0.0),
    "prism_mirror_x": ((-1.0, 1.0, 1.0), (2.5, -1.0, 0.0), 0.0),
    "prism_flip_z": ((1.0, 1.0, -1.0), (-2.0, 1.5, 1.2), 0.0),  # hangs upside down, bottom at 0.7 m
    "prism_all_negative": ((-1.0, -1.0, -1.0), (1.5, 2.2, 1.0), 0.0),  # z from 0.5 to 1.0
    "prism_skew_mirror": ((-1.5, 0.7, 1.0), (0.5, -2.5, 0.0), 30.0),
}


def build(b) -> None:
    # The floor mirrored in y: its winding (and winding normal) point down.
    b.mesh("floor_mirrored", [(-6.0, -6.0, 0.0), (6.0, -6.0, 0.0), (6.0, 6.0, 0.0), (-6.0, 6.0, 0.0)],
           [(0, 1, 2), (0, 2, 3)], _matrix((1.0, -1.0, 1.0), (0.0, 0.0, 0.0)))
    verts, tris = _prism()
    for name, (diag, offset, turn) in PLACEMENTS.items():
        b.mesh(name, verts, tris, _matrix(diag, offset, turn))
    b.point_light((0.0, 0.0, 2.5))
    b.camera((5.0, -6.0, 4.5), (0.0, 0.0, 0.3), fov_deg=62.0)
