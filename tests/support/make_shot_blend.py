"""Writes a small animated .blend for the shot sweeps (run in a child process: it resets bpy's data).

    python tests/support/make_shot_blend.py OUT.blend [--size WxH] [--dark-key-at FRAME]

Two point lights, `key` and `rim`, and two cameras, `Camera` (the scene's) and `side`.
Over frames 1-24 the crate slides and turns and the key light moves, so every frame
casts other shadows. --size sets the render size (default 160x120); --dark-key-at
keys the key light's energy to 0 from that frame on (a frame that is bad input, found
only when the job renders it).
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def main(out: str, size: tuple[int, int] = (160, 120), dark_key_at: int | None = None) -> None:
    import bpy

    from addon.core.scene import SceneBuilder
    from addon.reference.blender_scene import build_blender_scene

    bpy.ops.wm.read_homefile(use_empty=True)
    builder = SceneBuilder("shot_scene", size)
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
    if dark_key_at is not None:
        key.data.keyframe_insert("energy", frame=dark_key_at - 1)
        key.data.energy = 0.0
        key.data.keyframe_insert("energy", frame=dark_key_at)
        for curve in _fcurves(key.data):
            for point in curve.keyframe_points:
                point.interpolation = "CONSTANT"
    scene.frame_set(1)
    for other in [s for s in bpy.data.scenes if s != scene]:
        bpy.data.scenes.remove(other)
    bpy.ops.wm.save_as_mainfile(filepath=out)


def _fcurves(idblock):
    """The F-curves of an ID's action (Blender 5 keeps them in layered channelbags)."""
    action = idblock.animation_data.action
    if hasattr(action, "fcurves"):
        return list(action.fcurves)
    from bpy_extras import anim_utils

    bag = anim_utils.action_get_channelbag_for_slot(action, idblock.animation_data.action_slot)
    return list(bag.fcurves) if bag is not None else []


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser()
    parser.add_argument("out")
    parser.add_argument("--size", default="160x120")
    parser.add_argument("--dark-key-at", type=int)
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    main(args.out, (width, height), args.dark_key_at)
