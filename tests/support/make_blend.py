"""Writes a small .blend that was never a preset (run in a child process: it resets bpy's data).

    python tests/support/make_blend.py OUT.blend [--no-light]
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def main(out: str, with_light: bool) -> None:
    import bpy

    from addon.core.scene import SceneBuilder
    from addon.reference.blender_scene import build_blender_scene

    bpy.ops.wm.read_homefile(use_empty=True)
    builder = SceneBuilder("user_scene", (160, 120))
    builder.plane("ground", (0.0, 0.0, 0.0), 12.0, 12.0)
    builder.box("crate", (0.5, 0.2, 0.6), (1.0, 0.8, 1.2), rotate_z_deg=20.0)
    builder.box("post", (-1.5, 1.0, 1.0), (0.3, 0.3, 2.0))
    builder.point_light((1.5, -1.0, 3.0))
    builder.camera((5.0, -5.0, 3.5), (0.0, 0.0, 0.5), fov_deg=55.0)
    scene = build_blender_scene(builder.finish())
    if not with_light:
        for obj in [o for o in scene.objects if o.type == "LIGHT"]:
            bpy.data.objects.remove(obj)
    bpy.context.window_manager.windows  # noqa: B018 - background: no window to switch
    for other in [s for s in bpy.data.scenes if s != scene]:
        bpy.data.scenes.remove(other)
    bpy.ops.wm.save_as_mainfile(filepath=out)


if __name__ == "__main__":
    main(sys.argv[1], "--no-light" not in sys.argv)
