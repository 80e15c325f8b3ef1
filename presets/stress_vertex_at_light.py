"""A sliver triangle whose apex is exactly the light position, among ordinary occluders."""

DESCRIPTION = ("Omni light at (0.5, 0.25, 2.0) over a 12x12 m floor with a table, a crate and a pillar; a thin sliver"
               " triangle has its apex exactly at the light and rises behind it, away from the view.")
STRESSES = ("a vertex exactly at the light (L = 0): the sliver lies in a plane through the light, so it is edge-on "
            "(no solid angle) and must be dropped and counted (skipped_triangles = 1), never normalised into a NaN "
            "direction. Documented degradation of the REFERENCE: every shadow ray ends exactly on the sliver's apex, "
            "and Cycles counts some of those hits, so about 4 % of the evaluated pixels (4.1 % measured against the "
            "same scene without the sliver) are speckled dark in the Cycles image; that share shows up as false lit "
            "error in every method (the sliver itself gets no light and is not evaluated).")

LIGHT = (0.5, 0.25, 2.0)  # exactly representable in float32, so Blender keeps the vertex on the light


def build(b) -> None:
    b.plane("floor", (0.0, 0.0, 0.0), 12.0, 12.0)
    b.box("table_top", (-0.6, 0.9, 0.75), (1.6, 0.9, 0.06))
    for i, (x, y) in enumerate([(-1.3, 0.55), (0.1, 0.55), (-1.3, 1.25), (0.1, 1.25)]):
        b.box(f"table_leg_{i}", (x, y, 0.36), (0.06, 0.06, 0.72))
    b.box("crate", (1.7, -0.6, 0.4), (0.8, 0.8, 0.8), rotate_z_deg=25.0)
    b.box("pillar", (-1.8, -1.2, 1.25), (0.35, 0.35, 2.5))
    # The sliver: apex (vertex 0) at the light, the other corners in the plane x = 0.5,
    # rising behind the light (+y), away from the camera, which looks from -y. Its apex
    # angle is 1.2 degrees: Cycles' speckle share depends on it erratically (about 4 % of
    # the lit floor here, 14-40 % for other widths and for a wider fan; Blender 5.2.3).
    x, y, z = LIGHT
    b.mesh("sliver", [(x, y, z), (x, y + 1.0, z + 1.0), (x, y + 1.0, z + 1.03)], [(0, 1, 2)])
    b.point_light(LIGHT)
    b.camera((4.2, -4.6, 3.1), (-0.2, 0.6, 0.6), fov_deg=65.0)
