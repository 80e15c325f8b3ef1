"""Open courtyard lit from behind the camera: the light is outside the view."""

DESCRIPTION = "Open 30x30 m courtyard with walls and pillars; omni light high behind the camera, outside the view."
STRESSES = "light outside the view frustum: one paraboloid side or few cube faces suffice (IPSM case); long shadows on a large ground quad"


def build(b) -> None:
    b.plane("ground", (0.0, 0.0, 0.0), 30.0, 30.0)
    b.box("wall_north", (0.0, 7.0, 1.5), (14.0, 0.4, 3.0))
    b.box("wall_west", (-7.0, 0.0, 1.5), (0.4, 14.0, 3.0))
    for i in range(4):
        for j in range(3):
            b.box(f"pillar_{i}_{j}", (-4.5 + 3.0 * i, -3.0 + 3.0 * j, 1.25), (0.5, 0.5, 2.5))
    b.box("fountain", (1.0, 3.5, 0.4), (2.0, 2.0, 0.8), rotate_z_deg=45.0)
    b.point_light((13.0, -11.0, 9.0))
    b.camera((7.5, -7.5, 3.2), (-2.0, 2.0, 0.0), fov_deg=62.0)
