"""Writes a small animated .blend for the shot sweeps (run in a child process: it resets bpy's data).

    python tests/support/make_shot_blend.py OUT.blend

Two point lights, `key` and `rim`, and two cameras, `Camera` (the scene's) and `side`.
Over frames 1-24 the crate slides and turns and the key light moves, so every frame
casts other shadows.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def main(out: str) -> None:
    import bpy

    from addon.core.scene import SceneBuilder
    from addon.reference.blender_scene import build_blender_scene

    bpy.ops.wm.read_homefile(use_empty=True)
    builder = SceneBuilder("shot_scene", (160, 120))
    builder.plane("ground", (0.0, 0.0, 0.0), 12.0, 12.0)
    builder.box("crate", (0.5, 0.2, 0.6), (1.0, 0.8, 1.2), rotate_z_deg=20.0)
    builder.box("post", (-1.5, 1.0, 1.0), (0.3, 0.3, 2.0))
    builder.point_light((1.5, -1.0, 3.0))
    builder.camera((5.0, -5.0, 3.5), (0.0, 0.0, 0.5), fov_deg=55.0)
    scene = build_blender_scene(builder.finish())
    key = next(o for o in scene.objects if o.type == "LIGHT")
    key.name = "key"
    rim = key.copy()
    rim.data = key.data.copy()
    rim.name = "rim"
    rim.location = (-2.0, 2.5, 2.5)
    scene.collection.objects.link(rim)
    side = scene.camera.copy()
    side.name = "side"
    side.location = (-5.5, -3.0, 3.0)
    side.rotation_euler = (1.2, 0.0, -1.05)
    scene.collection.objects.link(side)
    crate = next(o for o in scene.objects if o.name.startswith("crate"))
    scene.frame_start, scene.frame_end = 1, 24
    for frame, dx, turn, light_x in ((1, 0.0, 0.0, 1.5), (24, 1.2, 0.6, -0.5)):
        crate.location.x = 0.5 + dx
        crate.rotation_euler.z += turn
        crate.keyframe_insert("location", frame=frame)
        crate.keyframe_insert("rotation_euler", frame=frame)
        key.location.x = light_x
        key.keyframe_insert("location", frame=frame)
    scene.frame_set(1)
    for other in [s for s in bpy.data.scenes if s != scene]:
        bpy.data.scenes.remove(other)
    bpy.ops.wm.save_as_mainfile(filepath=out)


if __name__ == "__main__":
    main(sys.argv[1])
