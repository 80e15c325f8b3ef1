"""A foggy courtyard, as an artist sets one up (issue 43):

    python tests/support/make_fog_scene.py OUT.blend [--radius R]

- `Ground`: a 12 m plane; `Suzanne` (subdivided, turned), three `Column`s and a `Crate`;
- `GroundFog`: a flat box of Principled Volume (density 0.35) reaching below the ground,
  so the ground, the figure and the columns' feet stand inside it;
- `Smoke`: a ball of orange Volume Absorption (density 2) floating beside the figure;
- a point light above (a sphere of radius R, 0 by default: hard), and a camera looking
  down across the yard, 320 x 240 pixels.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

SIZE = (320, 240)


def _volume_material(name: str, kind: str, density: float, color=None):
    import bpy

    from addon.compat import blender as blender_compat

    material = bpy.data.materials.new(name)
    tree = blender_compat.ensure_node_tree(material)
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    node = tree.nodes.new("ShaderNodeVolumePrincipled" if kind == "principled" else "ShaderNodeVolumeAbsorption")
    node.inputs["Density"].default_value = density
    if color is not None:
        node.inputs["Color"].default_value = (*color, 1.0)
    tree.links.new(node.outputs["Volume"], output.inputs["Volume"])
    return material


def build(radius: float = 0.0) -> None:
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=12.0, location=(0.0, 0.0, 0.0))
    bpy.context.object.name = "Ground"
    bpy.ops.mesh.primitive_monkey_add(size=1.0, location=(0.0, 0.2, 0.75), rotation=(0.3, 0.0, math.radians(25)))
    monkey = bpy.context.object
    monkey.name = "Suzanne"
    monkey.modifiers.new("Subdivision", "SUBSURF").levels = 1
    for i, (x, y) in enumerate([(-1.8, 1.4), (1.9, 1.6), (-2.2, -1.5)]):
        bpy.ops.mesh.primitive_cylinder_add(radius=0.25, depth=2.4, location=(x, y, 1.2))
        bpy.context.object.name = f"Column{i}"
    bpy.ops.mesh.primitive_cube_add(size=0.7, location=(1.2, -0.9, 0.35), rotation=(0.0, 0.0, 0.4))
    bpy.context.object.name = "Crate"
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.3))
    fog = bpy.context.object
    fog.name = "GroundFog"
    fog.scale = (4.0, 4.0, 0.5)  # 8 x 8 x 1 m: from 0.2 m below the ground to 0.8 m above
    fog.data.materials.append(_volume_material("GroundFog", "principled", 0.35))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.7, location=(1.4, -1.1, 1.7), segments=24, ring_count=12)
    smoke = bpy.context.object
    smoke.name = "Smoke"
    smoke.data.materials.append(_volume_material("Smoke", "absorption", 2.0, (0.8, 0.5, 0.2)))
    light_data = bpy.data.lights.new("Lamp", "POINT")
    light_data.energy = 1500.0
    light_data.shadow_soft_size = radius
    light = bpy.data.objects.new("Lamp", light_data)
    light.location = (-1.2, 0.8, 4.5)
    scene.collection.objects.link(light)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (6.0, -7.0, 4.5)
    scene.collection.objects.link(camera)
    direction = camera.location.copy()
    direction.negate()
    direction.z += 0.6
    camera.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--radius", type=float, default=0.0, help="the light's radius (m); 0: hard")
    args = parser.parse_args(argv)
    import bpy

    build(args.radius)
    bpy.ops.wm.save_as_mainfile(filepath=str(args.out.resolve()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
