"""A 10 km ground quad and 4 km walls made of single huge triangles, lit from 1 m up."""

DESCRIPTION = ("A 10x10 km ground quad (2 triangles) whose diagonal passes right under an omni light 1 m up; two 4 km"
               " long, 300 m tall walls (2 triangles each) meet in a corner 1.5 m from the light; a crate, a pole and"
               " a bar cast shadows.")
STRESSES = ("huge triangles: 10 km ground and 4 km wall edges seen from 1 m bend into long arcs on the paraboloid, so"
            " tessellation must refine only where it matters and stay within its budget; the ground diagonal passes "
            "under the light (its midpoint lands on the chord: the bend test must sample more than the midpoint); the"
            " walls straddle the seam z = 1 close to the light and must be split without cracks; the depth range runs"
            " from 0 to about 7 km (the ground's corners), so every receiver in view (within 6.5 m of the light) uses"
            " under 1e-3 of the normalised float32 depth range.")


def build(b) -> None:
    b.plane("ground", (0.0, 0.0, 0.0), 10000.0, 10000.0)  # diagonal (-5000,-5000)-(5000,5000)
    # Two huge vertical walls (single quads), z from 0 to 300 m, straddling the seam z = 1.
    b.mesh("wall_north", [(-2000.0, 1.5, 0.0), (2000.0, 1.5, 0.0), (2000.0, 1.5, 300.0), (-2000.0, 1.5, 300.0)],
           [(0, 2, 1), (0, 3, 2)])
    b.mesh("wall_west", [(-1.25, -2000.0, 0.0), (-1.25, 2000.0, 0.0), (-1.25, 2000.0, 300.0), (-1.25, -2000.0, 300.0)],
           [(0, 1, 2), (0, 2, 3)])
    b.box("crate", (1.0, 0.25, 0.3), (0.6, 0.6, 0.6), rotate_z_deg=20.0)
    b.box("pole", (0.75, -1.25, 1.25), (0.1, 0.1, 2.5))
    b.box("bar", (-0.25, -0.75, 1.75), (1.5, 0.08, 0.08), rotate_z_deg=-30.0)
    b.point_light((0.0, 0.0, 1.0))
    b.camera((6.5, -6.0, 3.0), (-0.5, 0.75, 0.4), fov_deg=70.0, clip_end=20000.0)
