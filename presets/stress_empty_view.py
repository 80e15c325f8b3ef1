"""The camera looks up at the empty sky: no view sample hits geometry."""

DESCRIPTION = ("A yard with crates under an omni light; the camera stands at 1.7 m and looks almost straight up, "
               "above every object, so it sees only the sky.")
STRESSES = ("an empty view: zero hit samples, so zero evaluated pixels; the planner must draw no layer (or a harmless"
            " default), the DV crop and warps must not divide by an empty count map, and every field of the row must "
            "stay finite (error_pct 0 on 0 pixels).")

CAMERA = (0.0, 0.0, 1.7)
TARGET = (1.0, 0.5, 20.0)


def build(b) -> None:
    b.plane("yard", (0.0, 0.0, 0.0), 20.0, 20.0)
    for i, (x, y) in enumerate([(2.0, 1.0), (-2.5, 0.5), (0.5, -3.0)]):
        b.box(f"crate_{i}", (x, y, 0.5), (1.0, 1.0, 1.0), rotate_z_deg=20.0 * i)
    b.box("shed", (-4.0, 4.0, 0.75), (3.0, 2.0, 1.5))
    b.point_light((1.0, -1.0, 3.0))
    b.camera(CAMERA, TARGET, fov_deg=50.0)
