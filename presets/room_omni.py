"""Closed room with an omni light inside it; the camera sees the light."""

DESCRIPTION = "Closed 8x6x3 m room, omni light at 2.2 m, furniture; the camera sees the light."
STRESSES = "light inside the view (both paraboloid sides, up to 6 cube faces), the seam crossing the view, huge floor and wall quads"


def build(b) -> None:
    b.box("room", (0.0, 0.0, 1.5), (8.0, 6.0, 3.0), inward=True)
    b.box("table_top", (-0.8, 0.6, 0.75), (1.6, 0.9, 0.06))
    for i, (x, y) in enumerate([(-1.5, 0.2), (-0.1, 0.2), (-1.5, 1.0), (-0.1, 1.0)]):
        b.box(f"table_leg_{i}", (x, y, 0.36), (0.06, 0.06, 0.72))
    b.box("crate", (1.6, -1.2, 0.4), (0.8, 0.8, 0.8), rotate_z_deg=25.0)
    b.box("pillar", (-2.4, -1.4, 1.5), (0.35, 0.35, 3.0))
    b.box("shelf", (2.6, 2.2, 0.9), (1.6, 0.4, 1.8), rotate_z_deg=-10.0)
    b.box("lamp_shade", (0.5, 0.3, 2.62), (0.5, 0.5, 0.04))
    b.point_light((0.5, 0.3, 2.2))
    b.camera((3.6, -2.6, 1.9), (-1.0, 1.0, 0.9), fov_deg=78.0)
