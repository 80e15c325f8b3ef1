"""The light inside a closed lantern whose only opening is a small window in its bottom."""

import math

DESCRIPTION = ("Omni light inside a closed 0.6 m lantern box (turned 20 degrees, hanging 1.3-1.9 m over a 10x10 m "
               "floor) whose only opening is a 0.3x0.2 m window in its bottom face: the floor is dark but for a "
               "1.4x0.9 m lit patch holding a stool's shadow.")
STRESSES = ("the light inside an object: every direction but the window's is blocked by geometry 0.2-0.5 m away, so "
            "any crack in a map (the paraboloid seam, cube-face edges, the lantern's edges and corners, the window "
            "frame) leaks light onto the dark floor as false lit pixels; near = 0 (the light is inside the scene's "
            "bounding box) and the lantern's outside faces point away from the light (not evaluated).")

CENTER = (0.0, 0.0, 1.6)
HALF = 0.3
WINDOW = (-0.05, 0.25, -0.15, 0.05)  # x0, x1, y0, y1 in the lantern's frame
LIGHT = (0.07, -0.05, 1.65)
TURN_DEG = 20.0


def _lantern():
    """Closed box with a window in the bottom face, outward winding, in its own frame."""
    h = HALF
    verts = [(-h, -h, -h), (h, -h, -h), (h, h, -h), (-h, h, -h), (-h, -h, h), (h, -h, h), (h, h, h), (-h, h, h)]
    x0, x1, y0, y1 = WINDOW
    verts += [(x0, y0, -h), (x1, y0, -h), (x1, y1, -h), (x0, y1, -h)]  # 8..11: window corners
    tris = [
        (4, 5, 6), (4, 6, 7),  # top
        (0, 1, 5), (0, 5, 4),  # y-
        (2, 3, 7), (2, 7, 6),  # y+
        (1, 2, 6), (1, 6, 5),  # x+
        (3, 0, 4), (3, 4, 7),  # x-
        # bottom (facing -z) with the window 8-9-10-11 cut out: a frame of 8 triangles
        (0, 8, 1), (1, 8, 9), (1, 9, 2), (2, 9, 10), (2, 10, 3), (3, 10, 11), (3, 11, 0), (0, 11, 8),
    ]
    return verts, tris


def build(b) -> None:
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    verts, tris = _lantern()
    a = math.radians(TURN_DEG)
    matrix = [[math.cos(a), -math.sin(a), 0.0, CENTER[0]],
              [math.sin(a), math.cos(a), 0.0, CENTER[1]],
              [0.0, 0.0, 1.0, CENTER[2]],
              [0.0, 0.0, 0.0, 1.0]]
    b.mesh("lantern", verts, tris, matrix)
    b.box("stool", (0.2, -0.1, 0.2), (0.2, 0.2, 0.4), rotate_z_deg=10.0)
    b.box("cabinet", (-2.0, 1.5, 0.6), (1.0, 0.5, 1.2))
    b.point_light(LIGHT)
    b.camera((2.8, -2.6, 2.4), (0.0, 0.2, 0.5), fov_deg=62.0)
