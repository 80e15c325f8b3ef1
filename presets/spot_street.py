"""A street seen along its length, lit by a spot light high up to one side and aimed down it."""

DESCRIPTION = ("A 100 m street between two rows of buildings with lamp posts, parked cars, bollards, a bench and a "
               "bin; a 125 degree spot light 35 m up over the middle of the street, 36 m ahead of the camera, aims "
               "straight down; the camera stands 1.6 m up in the street and looks along it.")
STRESSES = ("the depth range of a spot light: the lit street runs from 4 m in front of the camera to about 95 m "
            "away, so near shadows (bollards, bench, bin, cars) are large on screen and far ones (lamp posts, "
            "kerbs) small; a uniform shadow map spreads its texels evenly over the whole cone, which a perspective "
            "shadow map (PSM) redistributes towards the camera. The light lies in front of the camera plane, "
            "so in post-perspective space it stays a point light; its rays run roughly across the view "
            "direction, PSM's good case (Stamminger and Drettakis 2002, 3.3)")

# Buildings per side: (start y, length, height) in metres; the gaps are side streets.
_LEFT = [(-10.0, 9.0, 11.0), (2.0, 10.0, 15.0), (15.0, 7.0, 9.0), (25.0, 12.0, 17.0),
         (40.0, 8.0, 12.0), (51.0, 11.0, 19.0), (65.0, 9.0, 10.0), (77.0, 10.0, 14.0)]
_RIGHT = [(-10.0, 11.0, 12.0), (4.0, 8.0, 9.0), (15.0, 11.0, 14.0), (29.0, 9.0, 11.0),
          (41.0, 12.0, 16.0), (56.0, 8.0, 10.0), (67.0, 10.0, 13.0), (80.0, 8.0, 18.0)]
# Parked cars: (x, y of the car's centre, heading in degrees about Z).
_CARS = [(-4.6, 7.0, 0.0), (4.7, 13.0, 180.0), (-4.5, 24.0, 2.0), (4.6, 33.0, 178.0),
         (-4.7, 46.0, 0.0), (4.5, 58.0, 181.0), (-4.6, 70.0, -2.0)]


def _car(b, name: str, x: float, y: float, heading: float) -> None:
    """A car as two boxes: body and cabin (the cabin slightly towards the rear)."""
    b.box(f"{name}_body", (x, y, 0.75), (1.8, 4.4, 0.9), rotate_z_deg=heading)
    b.box(f"{name}_cabin", (x, y - 0.3 if abs(heading) < 90 else y + 0.3, 1.5), (1.6, 2.3, 0.6),
          rotate_z_deg=heading)


def build(b) -> None:
    b.plane("ground", (0.0, 37.0, 0.0), 44.0, 100.0, subdivisions=10)
    # Raised pavements along both sides (their 15 cm kerbs cast thin shadows).
    b.box("pavement_left", (-7.0, 37.0, 0.075), (2.0, 100.0, 0.15))
    b.box("pavement_right", (7.0, 37.0, 0.075), (2.0, 100.0, 0.15))
    for side, rows, x in (("left", _LEFT, -12.0), ("right", _RIGHT, 12.0)):
        for i, (y0, length, height) in enumerate(rows):
            b.box(f"house_{side}_{i}", (x, y0 + length / 2.0, height / 2.0), (8.0, length, height))
    # Lamp posts on both pavements, every 12 m, their arms reaching over the road.
    for i in range(7):
        for side, x, arm in (("left", -6.6, 0.8), ("right", 6.6, -0.8)):
            y = 3.0 + 12.0 * i + (6.0 if side == "right" else 0.0)
            b.box(f"lamp_{side}_{i}_pole", (x, y, 3.0), (0.18, 0.18, 6.0))
            b.box(f"lamp_{side}_{i}_arm", (x + arm, y, 5.95), (1.6, 0.14, 0.1))
    for i, (x, y, heading) in enumerate(_CARS):
        _car(b, f"car_{i}", x, y, heading)
    # Close to the camera: a row of bollards across the pavement edge, a bench and a bin.
    for i in range(5):
        b.box(f"bollard_{i}", (-3.6 + 1.2 * i, -1.0 + 0.5 * i, 0.45), (0.25, 0.25, 0.9))
    b.box("bench_seat", (-5.4, 0.0, 0.45), (0.6, 2.0, 0.08))
    b.box("bench_back", (-5.75, 0.0, 0.8), (0.08, 2.0, 0.5))
    for i, y in enumerate((-0.8, 0.8)):
        b.box(f"bench_leg_{i}", (-5.4, y, 0.2), (0.5, 0.1, 0.4))
    b.box("bin", (2.8, 0.5, 0.5), (0.5, 0.5, 1.0), rotate_z_deg=20.0)
    b.spot_light((3.0, 30.0, 35.0), (0.0, 27.0, 0.0), spot_size_deg=125.0, energy=60000.0)
    b.camera((1.0, -6.0, 1.6), (0.0, 60.0, 2.5), fov_deg=60.0, clip_end=250.0)
