"""The camera sits inside an occluding box that is open only toward the scene."""

DESCRIPTION = ("A 1.2x1.8x1.6 m hood (a box with its +y face open) floats 0.3 m over a 30x30 m yard; the camera is "
               "inside it and looks out through the opening at pillars and a wall lit by an omni light.")
STRESSES = ("the camera inside an occluder: the hood's inner walls frame the view from 0.8 m away (the yard reaches "
            "15 m), are lit only through the opening (shadow edges on receivers right at the lens), and the hood "
            "shadows the yard behind the camera; culling must keep the occluder that contains the camera. Receivers "
            "this close to the lens magnify each texel over many pixels, so maps without a crop/warp show perspective"
            " aliasing on the hood's shadow edges.")

HOOD_MIN = (-0.6, -9.0, 0.3)
HOOD_MAX = (0.6, -7.2, 1.9)


def _hood():
    (x0, y0, z0), (x1, y1, z1) = HOOD_MIN, HOOD_MAX
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    tris = [
        (0, 2, 1), (0, 3, 2),  # bottom
        (4, 5, 6), (4, 6, 7),  # top
        (0, 1, 5), (0, 5, 4),  # back (y0)
        (1, 2, 6), (1, 6, 5),  # x+
        (3, 0, 4), (3, 4, 7),  # x-
        # the +y face (y1) is open: the camera looks out through it
    ]
    return v, tris


def build(b) -> None:
    b.plane("yard", (0.0, 0.0, 0.0), 30.0, 30.0)
    verts, tris = _hood()
    b.mesh("hood", verts, tris)
    b.box("wall", (0.0, 6.0, 1.5), (12.0, 0.4, 3.0))
    for i, x in enumerate((-3.0, 0.0, 3.0)):
        b.box(f"pillar_{i}", (x, 0.0, 1.25), (0.5, 0.5, 2.5), rotate_z_deg=10.0 * i)
    b.box("block", (-1.5, -4.0, 0.5), (1.0, 1.0, 1.0), rotate_z_deg=30.0)
    b.point_light((3.0, 2.0, 6.0), energy=5000.0)
    b.camera((0.0, -8.9, 1.1), (0.0, 0.0, 0.9), fov_deg=100.0)
