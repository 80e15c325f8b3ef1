"""A 0.1 mm occluder 1 mm from the light, shadowing a wall 100 m away (near/far about 1e-5)."""

DESCRIPTION = ("Omni light 2 m above a 110x80 m ground; a 0.1x0.2 mm plate 1 mm in front of it (+x) casts a 10x20 m "
               "shadow onto a wall 100 m away and a long wedge onto the ground; crates give context.")
STRESSES = ("a near/far ratio of about 1e-5 (nearest geometry 1 mm, farthest about 113 m): normalised radial depth in"
            " float32 must still separate the wall from its bias, the tiny occluder must land in the map (not clipped"
            " by a cube face's near plane), and its shadow's size is set by a 0.1 mm feature. The shadows 100 m away,"
            " seen at a grazing view angle, alias more than room_omni's: the same scene with the plate 100 times "
            "larger at 10 cm (ratio 1e-3) gives the same error_pct, so the excess is not depth precision.")

LIGHT = (0.0, 0.0, 2.0)


def build(b) -> None:
    lx, ly, lz = LIGHT
    b.plane("ground", (50.0, 0.0, 0.0), 110.0, 80.0)
    b.box("far_wall", (100.5, 0.0, 15.0), (1.0, 60.0, 30.0))
    # The tiny occluder: x in [1.0, 1.02] mm, y in +-0.05 mm, z in lz +- 0.1 mm.
    b.box("tiny_plate", (lx + 0.00101, ly, lz), (0.00002, 0.0001, 0.0002))
    for i, (x, y) in enumerate([(12.0, -4.0), (35.0, 6.0), (60.0, -9.0), (80.0, 12.0)]):
        b.box(f"crate_{i}", (x, y, 0.75), (2.0, 2.0, 1.5), rotate_z_deg=15.0 * i)
    b.point_light(LIGHT, energy=20000.0)
    b.camera((-4.0, -30.0, 14.0), (60.0, 0.0, 3.0), fov_deg=62.0, clip_end=400.0)
