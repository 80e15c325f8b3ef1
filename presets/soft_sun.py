"""A garden corner under a sun of a wide disk: a pergola, a bench and a picket fence."""

DESCRIPTION = ("A 30x30 m lawn: a pergola of posts and slats, a bench, a picket fence and a low wall; a sun 45 "
               "degrees high whose disk is 4 degrees across (an artist's soft sun); the camera stands 1.6 m up.")
STRESSES = ("a sun's angle (issue 27) through its orthographic map: penumbrae that widen with the distance "
            "from the caster (the pergola's slats 2.4 m up blur on the lawn, the bench's legs stay sharp at the "
            "ground), fine fence pickets")

import math

SUN_ELEVATION_DEG = 45.0
SUN_AZIMUTH_DEG = 35.0


def build(b) -> None:
    b.plane("lawn", (0.0, 0.0, 0.0), 30.0, 30.0)
    # Pergola: four posts, two beams and eight slats across them.
    for i, (x, y) in enumerate([(-1.5, 1.0), (1.5, 1.0), (-1.5, 3.5), (1.5, 3.5)]):
        b.box(f"post_{i}", (x, y, 1.2), (0.1, 0.1, 2.4))
    for i, x in enumerate((-1.5, 1.5)):
        b.box(f"beam_{i}", (x, 2.25, 2.45), (0.12, 3.2, 0.1))
    for i in range(8):
        b.box(f"slat_{i}", (0.0, 1.05 + 0.34 * i, 2.55), (3.4, 0.06, 0.06))
    # A bench under it: seat, back and legs.
    b.box("bench_seat", (0.0, 2.2, 0.45), (1.6, 0.4, 0.05))
    b.box("bench_back", (0.0, 2.42, 0.75), (1.6, 0.04, 0.4))
    for i, (x, y) in enumerate([(-0.72, 2.05), (0.72, 2.05), (-0.72, 2.38), (0.72, 2.38)]):
        b.box(f"bench_leg_{i}", (x, y, 0.21), (0.05, 0.05, 0.42))
    # A picket fence along the lawn's left and a low wall behind.
    for i in range(24):
        b.box(f"picket_{i}", (-4.0, -2.0 + 0.25 * i, 0.5), (0.04, 0.09, 1.0))
    b.box("rail", (-4.0, 1.0, 0.75), (0.05, 6.2, 0.06))
    b.box("wall", (1.0, 6.0, 0.4), (8.0, 0.3, 0.8))
    el, az = math.radians(SUN_ELEVATION_DEG), math.radians(SUN_AZIMUTH_DEG)
    direction = (-math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az), -math.sin(el))
    b.sun_light(direction, angle_deg=4.0, origin=(0.0, 0.0, 10.0))
    b.camera((4.5, -3.5, 1.6), (-0.5, 2.5, 0.4), fov_deg=60.0)
