"""A product shot under a softbox: an area light over a chair and a vase on a table."""

DESCRIPTION = "A 1.2x0.8 m area light (softbox) above a table, a chair and a vase on a floor plane."
STRESSES = "an area light (one-sided, hemispherical emission) with a wide penumbra; contact shadows of thin legs"


def build(b) -> None:
    b.plane("floor", (0.0, 0.0, 0.0), 10.0, 10.0)
    b.box("table_top", (0.0, 0.0, 0.74), (1.4, 0.8, 0.04))
    for i, (x, y) in enumerate([(-0.62, -0.32), (0.62, -0.32), (-0.62, 0.32), (0.62, 0.32)]):
        b.box(f"table_leg_{i}", (x, y, 0.36), (0.05, 0.05, 0.72))
    b.box("vase", (0.2, 0.05, 0.91), (0.14, 0.14, 0.3), rotate_z_deg=30.0)
    b.box("seat", (-0.3, -0.9, 0.45), (0.45, 0.45, 0.04))
    for i, (x, y) in enumerate([(-0.5, -1.1), (-0.1, -1.1), (-0.5, -0.7), (-0.1, -0.7)]):
        b.box(f"chair_leg_{i}", (x, y, 0.22), (0.04, 0.04, 0.44))
    b.area_light((0.6, -0.4, 2.6), (0.0, 0.0, 0.6), 1.2, 0.8)
    b.camera((2.6, -3.4, 2.2), (0.0, -0.2, 0.5), fov_deg=55.0)
