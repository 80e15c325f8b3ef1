"""A wide field under a low side sun, seen from a standing height across its length."""

import math

DESCRIPTION = ("A 200x200 m field: a picket fence, a sign post, a bench, hay bales and two trees near the camera; "
               "a low stone wall, a row of poplars, box trees, a hedge, a barn and a silo up to 175 m away; a sun "
               "30 degrees high shines from the left, about perpendicular to the view; the camera stands 1.7 m up "
               "and looks across the field.")
STRESSES = ("a directional (sun) light over a deep view: the fence's 8 cm slats cast fine shadows 4-32 m from "
            "the camera, while the poplars, trees and the barn cast shadows up to 175 m away; a uniform "
            "orthographic map over the whole view wastes most texels on the far field, which a perspective shadow "
            "map (PSM) redistributes; a light direction perpendicular to the view direction is PSM's best case")

SUN_ELEVATION_DEG = 30.0
SUN_AZIMUTH_DEG = 10.0  # from +x towards +y: the light travels mostly along +x, across the view (+y)

# Trees: (x, y, trunk height, crown size); crowns are boxes turned by a varying angle.
_TREES = [(-13.0, -74.0, 3.0, 5.0), (-10.0, -58.0, 3.5, 6.0),  # near: shadows 14-35 m from the camera
          (-38.0, -40.0, 3.5, 4.5), (-22.0, -28.0, 4.0, 5.0), (-45.0, -10.0, 3.0, 4.0), (-15.0, 5.0, 4.5, 5.5),
          (-30.0, 20.0, 3.5, 5.0), (-52.0, 35.0, 4.0, 6.0), (-8.0, 38.0, 3.0, 4.5), (-25.0, 55.0, 4.5, 5.5),
          (-40.0, 75.0, 4.0, 6.0), (-12.0, 80.0, 3.5, 5.0), (5.0, 62.0, 4.0, 5.0), (12.0, -35.0, 3.5, 4.0),
          (30.0, -20.0, 4.0, 5.5), (48.0, -5.0, 3.0, 4.5), (18.0, 12.0, 4.5, 5.0), (55.0, 25.0, 4.0, 6.0),
          (8.0, 28.0, 3.0, 4.0), (60.0, 60.0, 4.5, 5.5), (42.0, 82.0, 4.0, 5.0), (-60.0, 60.0, 3.5, 5.0)]


def _gable_roof(b, name: str, center, length: float, width: float, rise: float) -> None:
    """A gable roof (triangular prism, ridge along y, outward winding) whose eaves sit at center z."""
    cx, cy, cz = center
    hx, hy = width / 2.0, length / 2.0
    verts = [(cx - hx, cy - hy, cz), (cx + hx, cy - hy, cz), (cx, cy - hy, cz + rise),
             (cx - hx, cy + hy, cz), (cx + hx, cy + hy, cz), (cx, cy + hy, cz + rise)]
    tris = [(0, 1, 2), (3, 5, 4),  # gable ends (counter-clockwise seen from outside)
            (0, 5, 3), (0, 2, 5),  # west slope
            (1, 5, 2), (1, 4, 5),  # east slope
            (0, 4, 1), (0, 3, 4)]  # underside
    b.mesh(name, verts, tris)


def _silo(b, name: str, x: float, y: float, radius: float, height: float, sides: int = 16) -> None:
    """A closed cylinder (prism with `sides` faces) standing on the ground."""
    verts, tris = [], []
    for i in range(sides):
        a = 2.0 * math.pi * i / sides
        verts += [(x + radius * math.cos(a), y + radius * math.sin(a), 0.0),
                  (x + radius * math.cos(a), y + radius * math.sin(a), height)]
    top = len(verts)
    verts.append((x, y, height))
    for i in range(sides):
        j = (i + 1) % sides
        tris += [(2 * i, 2 * j, 2 * j + 1), (2 * i, 2 * j + 1, 2 * i + 1), (2 * i + 1, 2 * j + 1, top)]
    b.mesh(name, verts, tris)


def build(b) -> None:
    b.plane("ground", (0.0, 0.0, 0.0), 200.0, 200.0, subdivisions=20)
    # A picket fence along the view, left of the camera: posts every 2.5 m, two rails, slats.
    fence_x, y0, y1 = -4.0, -86.0, -56.0
    n_posts = int((y1 - y0) / 2.5) + 1
    for i in range(n_posts):
        b.box(f"fence_post_{i}", (fence_x, y0 + 2.5 * i, 0.6), (0.12, 0.12, 1.2))
    for k, z in enumerate((0.35, 0.95)):  # rails touch the posts' +x side, slats the rails'
        b.box(f"fence_rail_{k}", (fence_x + 0.09, (y0 + y1) / 2.0, z), (0.06, y1 - y0, 0.08))
    n_slats = int((y1 - y0) / 0.25)
    for i in range(n_slats):
        b.box(f"fence_slat_{i}", (fence_x + 0.135, y0 + 0.125 + 0.25 * i, 0.5), (0.03, 0.08, 1.0))
    # Near the camera: a bench (turned -15 degrees), a sign post and hay bales.
    turn = math.radians(-15.0)

    def bench_part(name: str, local_x: float, local_y: float, z: float, size) -> None:
        x = 3.5 + local_x * math.cos(turn) - local_y * math.sin(turn)
        y = -78.0 + local_x * math.sin(turn) + local_y * math.cos(turn)
        b.box(name, (x, y, z), size, rotate_z_deg=math.degrees(turn))

    bench_part("bench_seat", 0.0, 0.0, 0.45, (0.5, 2.0, 0.06))
    bench_part("bench_back", 0.28, 0.0, 0.8, (0.06, 2.0, 0.45))
    for i, local_y in enumerate((-0.8, 0.8)):
        bench_part(f"bench_leg_{i}", 0.0, local_y, 0.21, (0.45, 0.08, 0.42))
    b.box("sign_post", (1.2, -72.0, 1.25), (0.1, 0.1, 2.5))
    b.box("sign_board", (1.2, -72.0, 2.2), (0.8, 0.04, 0.5), rotate_z_deg=30.0)
    for i, (x, y, turn) in enumerate([(7.0, -70.0, 10.0), (9.5, -66.0, 40.0), (6.0, -61.0, 75.0),
                                      (-1.5, -64.0, 20.0)]):
        b.box(f"hay_bale_{i}", (x, y, 0.6), (1.2, 2.0, 1.2), rotate_z_deg=turn)
    # Far: trees, a hedge, a barn with a gable roof, a silo.
    for i, (x, y, trunk, crown) in enumerate(_TREES):
        b.box(f"tree_{i}_trunk", (x, y, trunk / 2.0), (0.5, 0.5, trunk))
        b.box(f"tree_{i}_crown", (x, y, trunk + crown / 2.0 - 0.3), (crown, crown, crown),
              rotate_z_deg=17.0 * i)
    # A row of poplars along the view: shadows one after another from 40 m to 170 m.
    for i in range(12):
        y = -45.0 + 12.0 * i
        b.box(f"poplar_{i}_trunk", (-16.0, y, 1.5), (0.4, 0.4, 3.0))
        b.box(f"poplar_{i}_crown", (-16.0, y, 6.0), (2.2, 2.2, 6.5), rotate_z_deg=23.0 * i)
    # A low dry-stone wall along the view: one long shadow edge receding from 30 m to 70 m.
    b.box("stone_wall", (11.0, -40.0, 0.5), (0.6, 40.0, 1.0), rotate_z_deg=3.0)
    b.box("hedge", (-20.0, 45.0, 1.0), (40.0, 1.2, 2.0), rotate_z_deg=-8.0)
    b.box("barn", (28.0, 40.0, 3.5), (12.0, 22.0, 7.0))
    _gable_roof(b, "barn_roof", (28.0, 40.0, 7.0), 23.0, 13.0, 4.0)
    _silo(b, "silo", 40.0, 28.0, 2.5, 14.0)

    el, az = math.radians(SUN_ELEVATION_DEG), math.radians(SUN_AZIMUTH_DEG)
    direction = (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el))
    b.sun_light(direction, strength=4.0, origin=(0.0, 0.0, 30.0))
    b.camera((0.0, -88.0, 1.7), (0.0, 0.0, -3.0), fov_deg=60.0, clip_end=400.0)
