"""Geometry on the dual paraboloid's seam plane, on the light's vertical axis, and straddling the seam."""

DESCRIPTION = ("Closed 8x6x3 m room, omni light at (0.25, -0.5, 1.5): a shelf lying in the seam plane z = 1.5, boxes "
               "ending exactly on it from below and above, plates centred on the light's vertical axis above and "
               "below it, and a huge slanted panel crossing the seam.")
STRESSES = ("the dual-paraboloid seam: for a point light the seam plane is z = light z (the light's local -Z is world"
            " -Z). Vertices exactly on it (v_z = 0: box corners, the shelf), a shelf and two box faces lying in it "
            "(edge-on: 6 triangles skipped and counted), a vertex exactly on the axis above the light (v_z = -1 for "
            "the lower side: the paraboloid's singular point, must go to the upper side only) and below it, and huge "
            "room walls and a 7 m panel straddling the seam, which must be split without cracks. The camera sits at "
            "seam height, so the seam crosses the view.")

LIGHT = (0.25, -0.5, 1.5)  # float32-exact: the seam vertices stay exactly on the plane in Blender


def build(b) -> None:
    lx, ly, lz = LIGHT
    b.box("room", (0.0, 0.0, 1.5), (8.0, 6.0, 3.0), inward=True)
    # A 1.5 x 1 m shelf lying exactly in the seam plane (it subtends no solid angle).
    b.plane("shelf_in_seam", (2.75, 1.5, lz), 1.5, 1.0)
    # Boxes whose top face / bottom face lie exactly on the seam plane.
    b.box("crate_below_seam", (-1.5, 0.5, 1.0), (0.8, 0.8, 1.0), rotate_z_deg=15.0)   # z in [0.5, 1.5]
    b.box("crate_above_seam", (-1.0, -1.75, 1.875), (0.5, 0.5, 0.75))              # z in [1.5, 2.25]
    # Plates centred on the vertical axis through the light: subdivisions=2 puts a vertex
    # exactly above (v = +Z) and exactly below (v = -Z) the light.
    b.plane("axis_plate_above", (lx, ly, 2.5), 0.5, 0.5, subdivisions=2)
    b.plane("axis_plate_below", (lx, ly, 0.75), 0.375, 0.375, subdivisions=2)
    # A tall pole that crosses the seam right next to the light.
    b.box("pole", (lx + 0.5, ly + 0.25, 1.5), (0.125, 0.125, 2.5))
    # A huge slanted panel (2 triangles, 7 m long) crossing the seam behind the light.
    panel = [(-3.5, 1.25, 0.5), (3.5, 1.25, 0.5), (3.5, 2.75, 2.75), (-3.5, 2.75, 2.75)]
    b.mesh("slanted_panel", panel, [(0, 1, 2), (0, 2, 3)])
    b.point_light(LIGHT)
    b.camera((3.6, -2.6, lz), (-1.5, 1.0, 1.4), fov_deg=80.0)
