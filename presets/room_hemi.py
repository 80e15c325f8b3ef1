"""Room lit by a hemispherical ceiling light pointing down."""

DESCRIPTION = "Closed 8x6x3 m room, hemispherical light just under the ceiling pointing down, furniture."
STRESSES = "hemispherical emission: one paraboloid side, at most five cube faces; shadows on floor and walls near the horizon of the light"


def build(b) -> None:
    b.box("room", (0.0, 0.0, 1.5), (8.0, 6.0, 3.0), inward=True)
    b.box("table_top", (0.9, -0.4, 0.75), (1.8, 1.0, 0.06))
    for i, (x, y) in enumerate([(0.1, -0.8), (1.7, -0.8), (0.1, 0.0), (1.7, 0.0)]):
        b.box(f"table_leg_{i}", (x, y, 0.36), (0.06, 0.06, 0.72))
    b.box("cabinet", (-2.8, 1.9, 1.0), (1.2, 0.8, 2.0), rotate_z_deg=8.0)
    b.box("stool", (-0.9, 0.9, 0.3), (0.45, 0.45, 0.6), rotate_z_deg=35.0)
    b.box("beam", (0.0, 1.2, 2.55), (7.0, 0.2, 0.3))
    b.hemi_light((-0.3, -0.2, 2.9), (-0.3, -0.2, 0.0))
    b.camera((3.5, -2.7, 2.0), (-0.8, 0.8, 0.6), fov_deg=75.0)
