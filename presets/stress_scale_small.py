"""The room_omni layout scaled by 1e-3 Blender units."""

SCALE = 0.001

DESCRIPTION = ("room_omni's closed 8x6x3 m room with furniture and an omni light, every length scaled by 1e-3 (an "
               "8x6x3 mm room); light energy scaled by SCALE^2 and the camera's clip range by SCALE, so the image and"
               " the shadows are room_omni's.")
STRESSES = ("scene scale 1e-3: every tolerance (sanitising, seam splitting, bias, depth range, culling slack) must be"
            " relative to the scene, not absolute; float32 vertex streams must stay precise after light-centring; "
            "error_pct should match room_omni's.")


def _s(values):
    return tuple(SCALE * v for v in values)


def build(b) -> None:
    b.box("room", _s((0.0, 0.0, 1.5)), _s((8.0, 6.0, 3.0)), inward=True)
    b.box("table_top", _s((-0.8, 0.6, 0.75)), _s((1.6, 0.9, 0.06)))
    for i, (x, y) in enumerate([(-1.5, 0.2), (-0.1, 0.2), (-1.5, 1.0), (-0.1, 1.0)]):
        b.box(f"table_leg_{i}", _s((x, y, 0.36)), _s((0.06, 0.06, 0.72)))
    b.box("crate", _s((1.6, -1.2, 0.4)), _s((0.8, 0.8, 0.8)), rotate_z_deg=25.0)
    b.box("pillar", _s((-2.4, -1.4, 1.5)), _s((0.35, 0.35, 3.0)))
    b.box("shelf", _s((2.6, 2.2, 0.9)), _s((1.6, 0.4, 1.8)), rotate_z_deg=-10.0)
    b.box("lamp_shade", _s((0.5, 0.3, 2.62)), _s((0.5, 0.5, 0.04)))
    b.point_light(_s((0.5, 0.3, 2.2)), energy=1000.0 * SCALE * SCALE)
    b.camera(_s((3.6, -2.6, 1.9)), _s((-1.0, 1.0, 0.9)), fov_deg=78.0, clip_end=200.0 * SCALE,
             clip_start=0.05 * SCALE)

