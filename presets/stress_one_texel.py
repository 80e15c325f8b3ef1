"""A 1 cm cube 100 m from the light fills a 0.12 degree view: every sample in one texel."""

DESCRIPTION = ("An omni light 10 m up; a 1 cm cube floats 100 m away and a camera 3.2 m from it with a 0.12 degree "
               "field of view sees nothing else; a pole halfway puts a shadow edge across the cube's lit face.")
STRESSES = ("all view samples in one texel: the viewed patch (about 7x5 mm, under 1e-4 rad from the light) is a small"
            " fraction of one texel at any map resolution, so count maps hold a single non-zero texel: the DV crop "
            "and the warps must stay finite (no zero-width crop, no division by a zero row sum). Documented "
            "degradation: the shadow edge crosses the patch, so a map without a crop/warp cannot resolve it (error up"
            " to the minority share of the patch); only a crop that zooms in to sub-texel can.")

LIGHT = (0.0, 0.3, 10.0)
CUBE = (100.0, 0.0, 5.0)
TARGET = (99.995, 0.0, 5.0)  # the centre of the cube's lit face (x = 99.995)


def build(b) -> None:
    b.plane("ground", (50.0, 0.0, 0.0), 240.0, 80.0)
    b.box("tiny_cube", CUBE, (0.01, 0.01, 0.01))
    # A pole halfway between the light and the cube. Its +y face at y = 0.15 is
    # seen from the light (y = 0.3) as an edge whose shadow lands at y = 0.0003 on
    # the cube's lit face (x = 99.995), so the edge crosses the viewed patch.
    b.box("pole", (50.0, 0.1, 4.5), (0.1, 0.1, 9.0))
    b.point_light(LIGHT)
    b.camera((97.0, -1.0, 5.0), TARGET, fov_deg=0.12, clip_end=300.0)
