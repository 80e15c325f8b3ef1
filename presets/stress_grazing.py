"""An omni light 2 cm above a 40 m floor: nearly every receiver is lit at more than 89 degrees."""

DESCRIPTION = ("A 40x12 m floor with an omni light 0.02 m above it at one end; low blocks and a 10 cm kerb along the "
               "floor cast shadows tens of metres long.")
STRESSES = ("grazing receivers: the light direction makes more than 89 degrees with the floor's normal beyond 1.15 m "
            "from the light (89.97 degrees at 40 m), so one texel spreads over metres of floor: slope and "
            "normal-offset bias must avoid acne without losing the long shadows of occluders only 5-30 cm tall.")

LIGHT = (0.0, 0.0, 0.02)


def build(b) -> None:
    b.plane("floor", (18.0, 0.0, 0.0), 40.0, 12.0)  # x from -2 to 38
    blocks = [(3.0, -1.0, 0.05), (6.0, 1.5, 0.1), (10.0, -2.5, 0.2), (15.0, 0.5, 0.15), (22.0, 3.0, 0.3),
              (28.0, -3.5, 0.25)]
    for i, (x, y, h) in enumerate(blocks):
        b.box(f"block_{i}", (x, y, h / 2.0), (0.4, 0.4, h), rotate_z_deg=15.0 * i)
    b.box("kerb", (12.0, 4.5, 0.05), (6.0, 0.15, 0.1), rotate_z_deg=8.0)
    b.point_light(LIGHT, energy=5000.0)
    b.camera((-1.5, -4.0, 1.6), (14.0, 1.0, 0.0), fov_deg=60.0)
