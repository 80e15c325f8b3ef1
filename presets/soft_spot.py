"""A reading corner under a sized spot light: an armchair, a side table and a standing lamp."""

DESCRIPTION = ("5x4x2.8 m room corner; a spot light of 0.3 m radius and a 100 degree cone, 2.4 m up, aimed at an "
               "armchair, a side table and a floor lamp's pole.")
STRESSES = ("a sized spot light (issue 27) through its own perspective map: wide penumbrae of the chair's back "
            "on the wall, contact shadows at the table's legs and the lamp's thin pole, a cone edge on the floor")


def build(b) -> None:
    b.plane("floor", (0.0, 0.0, 0.0), 5.0, 4.0)
    b.box("wall_back", (0.0, 2.05, 1.4), (5.0, 0.1, 2.8))
    b.box("wall_side", (-2.55, 0.0, 1.4), (0.1, 4.0, 2.8))
    # An armchair: seat, back and two arms on four short legs.
    b.box("chair_seat", (-0.9, 1.0, 0.42), (0.8, 0.75, 0.14), rotate_z_deg=15.0)
    b.box("chair_back", (-1.0, 1.38, 0.85), (0.8, 0.12, 0.75), rotate_z_deg=15.0)
    b.box("chair_arm_l", (-1.32, 0.92, 0.6), (0.1, 0.7, 0.24), rotate_z_deg=15.0)
    b.box("chair_arm_r", (-0.5, 1.12, 0.6), (0.1, 0.7, 0.24), rotate_z_deg=15.0)
    for i, (x, y) in enumerate([(-1.25, 0.72), (-0.55, 0.9), (-1.43, 1.35), (-0.73, 1.53)]):
        b.box(f"chair_leg_{i}", (x, y, 0.17), (0.05, 0.05, 0.34))
    # A side table: a round-ish top (an octagon of boxes would do; a turned square is enough)
    # on three thin legs.
    b.box("table_top", (0.35, 0.9, 0.55), (0.5, 0.5, 0.03), rotate_z_deg=45.0)
    for i, (x, y) in enumerate([(0.2, 0.78), (0.5, 0.78), (0.35, 1.08)]):
        b.box(f"table_leg_{i}", (x, y, 0.27), (0.03, 0.03, 0.54))
    b.box("book", (0.38, 0.88, 0.585), (0.22, 0.16, 0.04), rotate_z_deg=-20.0)
    # A floor lamp: a heavy base, a thin pole and a shade.
    b.box("lamp_base", (1.3, 1.5, 0.02), (0.3, 0.3, 0.04))
    b.box("lamp_pole", (1.3, 1.5, 0.8), (0.025, 0.025, 1.56))
    b.box("lamp_shade", (1.3, 1.5, 1.66), (0.36, 0.36, 0.24))
    b.spot_light((0.6, -0.9, 2.4), (-0.4, 1.0, 0.3), 100.0, radius=0.3)
    b.camera((1.9, -1.7, 1.6), (-0.5, 1.0, 0.5), fov_deg=65.0)
