"""A grass field built as old files build one: particle hair on an emitter and a sun, both
hidden in the viewport but rendered (issue 53's 2013 file, rebuilt):

    python tests/support/make_grass_blend.py OUT.blend [--strands N] [--size W H] [--sun-angle DEG]

- `Field`: a plane of 2 m scaled to 3 m in x and y (its hair is thicker for it in Cycles),
  hidden in the viewport, whose hair particle system grows N strands (default 6,000) of 0.25 m, drawn as paths (radius scale 0.01, root 1, tip 0,
  3 render steps against 2 in the viewport, half of them shown there), leaning at random;
- `Ground`: a larger plane under it, a `Post` and a `Crate` among the grass;
- `Sun`: 11.4 degrees across (--sun-angle), rotated YXZ (37.3, 3.2, 106.9) degrees, hidden
  in the viewport; a camera looking down at the field (--size, default 320 x 240).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from tests.support.make_left_out_blend import _camera, _mesh, _object  # noqa: E402


def _plane(name: str, size: float) -> "bpy.types.Object":
    """A flat square of side 2 * size, its normal +Z."""
    import bmesh

    return _object(name, lambda made: bmesh.ops.create_grid(made, x_segments=8, y_segments=8, size=size))


def build(out: Path, strands: int, size: tuple[int, int], sun_angle: float) -> None:
    import bpy
    from mathutils import Euler

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100

    ground = _mesh("Ground", 4.0, (0.0, 0.0, -0.01))
    ground.scale = (1.0, 1.0, 0.0025)
    field = _plane("Field", 1.0)
    field.scale = (1.5, 1.5, 1.0)  # scaled in the plane, as a grass plane is: thicker hair
    field.hide_viewport = True
    settings = field.modifiers.new("grass", "PARTICLE_SYSTEM").particle_system.settings
    settings.type, settings.count, settings.render_type = "HAIR", strands, "PATH"
    settings.hair_length = 0.25
    settings.radius_scale, settings.root_radius, settings.tip_radius = 0.01, 1.0, 0.0
    settings.display_step, settings.render_step = 2, 3
    settings.display_percentage = 50
    settings.use_advanced_hair = True
    settings.factor_random = 0.3
    settings.emit_from = "FACE"
    _mesh("Post", 0.08, (0.6, -0.4, 0.5)).scale = (1.0, 1.0, 6.0)
    _mesh("Crate", 0.2, (-0.7, 0.5, 0.2))

    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.data.angle = math.radians(sun_angle)
    sun.rotation_mode = "YXZ"
    sun.rotation_euler = Euler([math.radians(a) for a in (37.3, 3.2, 106.9)], "YXZ")
    sun.location = (0.0, 0.0, 4.0)
    sun.hide_viewport = True
    scene.collection.objects.link(sun)

    _camera(scene, (2.4, -2.4, 2.2), (math.radians(58.0), 0.0, math.radians(45.0)))
    bpy.ops.wm.save_as_mainfile(filepath=str(out))


def main() -> None:
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    parser = argparse.ArgumentParser()
    parser.add_argument("out", type=Path)
    parser.add_argument("--strands", type=int, default=6000)
    parser.add_argument("--size", type=int, nargs=2, default=(320, 240))
    parser.add_argument("--sun-angle", type=float, default=11.4)
    args = parser.parse_args(argv)
    build(args.out, args.strands, tuple(args.size), args.sun_angle)


if __name__ == "__main__":
    main()
