"""A room lit by a sized point light: a chair and a table whose legs stand on the floor."""

DESCRIPTION = "8x6x3 m room, a point light of 0.3 m radius over a table and a chair; a lamp's soft shadows."
STRESSES = "a sized light (issue 27): wide penumbrae under the table, contact shadows at the chair's legs"


def build(b) -> None:
    b.box("room", (0.0, 0.0, 1.5), (8.0, 6.0, 3.0), inward=True)
    b.box("table_top", (0.6, -0.2, 0.75), (1.6, 0.9, 0.05))
    for i, (x, y) in enumerate([(-0.15, -0.6), (1.35, -0.6), (-0.15, 0.2), (1.35, 0.2)]):
        b.box(f"table_leg_{i}", (x, y, 0.36), (0.06, 0.06, 0.72))
    b.box("seat", (-1.2, 0.6, 0.45), (0.45, 0.45, 0.04), rotate_z_deg=20.0)
    b.box("back", (-1.42, 0.68, 0.75), (0.04, 0.45, 0.6), rotate_z_deg=20.0)
    for i, (x, y) in enumerate([(-1.35, 0.35), (-0.98, 0.49), (-1.49, 0.72), (-1.12, 0.86)]):
        b.box(f"chair_leg_{i}", (x, y, 0.22), (0.04, 0.04, 0.44))
    b.box("shelf", (2.9, 2.2, 1.0), (1.4, 0.4, 2.0), rotate_z_deg=-6.0)
    b.point_light((0.2, 0.3, 2.3), radius=0.3)
    b.camera((3.4, -2.6, 2.1), (-0.4, 0.4, 0.4), fov_deg=70.0)
