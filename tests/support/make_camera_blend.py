"""Writes a small .blend whose camera is not a centred perspective one (run in a child
process: it resets bpy's data).

    python tests/support/make_camera_blend.py OUT.blend ortho|shifted

ortho: an orthographic camera with lens shift, VERTICAL fit, pixel aspect 2:1 and a
50 % resolution, lit by a spot light. shifted: a perspective camera with lens shift
and a point light.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def main(out: str, kind: str) -> None:
    import bpy

    from addon.core.scene import SceneBuilder
    from addon.reference.blender_scene import build_blender_scene

    bpy.ops.wm.read_homefile(use_empty=True)
    builder = SceneBuilder("camera_scene", (128, 96))
    builder.plane("ground", (0.0, 0.0, 0.0), 12.0, 12.0)
    builder.box("crate", (0.5, 0.2, 0.6), (1.0, 0.8, 1.2), rotate_z_deg=20.0)
    builder.box("post", (-1.5, 1.0, 1.0), (0.3, 0.3, 2.0))
    if kind == "ortho":
        builder.spot_light((1.5, -1.0, 5.0), (0.0, 0.0, 0.0), spot_size_deg=90.0)
    else:
        builder.point_light((1.5, -1.0, 3.0))
    builder.camera((5.0, -5.0, 3.5), (0.0, 0.0, 0.5), fov_deg=55.0)
    scene = build_blender_scene(builder.finish())
    cam = scene.camera.data
    if kind == "ortho":
        cam.type, cam.ortho_scale, cam.sensor_fit = "ORTHO", 7.0, "VERTICAL"
        cam.shift_x, cam.shift_y = 0.1, -0.05
        scene.render.pixel_aspect_x = 2.0
        scene.render.resolution_x, scene.render.resolution_y = 160, 192
        scene.render.resolution_percentage = 50
    else:
        cam.shift_x, cam.shift_y = 0.25, 0.15
    for other in [s for s in bpy.data.scenes if s != scene]:
        bpy.data.scenes.remove(other)
    bpy.ops.wm.save_as_mainfile(filepath=out)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
