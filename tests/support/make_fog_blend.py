"""A fog box beside a figure, as an artist builds one (issue 43):

    python tests/support/make_fog_blend.py OUT.blend [--noise]

- `Ground` (a 6 m plane) and `Figure` (a 0.4 x 0.4 x 1.2 m box standing beside the fog);
- `Fog`: a 1.2 m cube of Principled Volume, density 1.5 (with --noise, a noise texture
  times 3), and no surface shader: a medium;
- a hard point light above, a camera looking down at the ground, 128 x 96 pixels.

`build` makes the scene in the running Blender; `scripts/fog_box_probe.py` renders it
with its own settings.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

SIZE = (128, 96)
LIGHT = np.array([0.4, 0.3, 3.0])
BOX_CENTRE, BOX_HALF, DENSITY = np.array([0.0, 0.0, 0.8]), 0.6, 1.5
FIGURE_CENTRE, FIGURE_HALF = np.array([1.1, 0.2, 0.6]), np.array([0.2, 0.2, 0.6])


def _box(name: str, size, location):
    import bpy  # first: bmesh is bpy's
    import bmesh

    mesh = bpy.data.meshes.new(name)
    made = bmesh.new()
    bmesh.ops.create_cube(made, size=1.0)
    bmesh.ops.scale(made, vec=size, verts=made.verts)
    made.to_mesh(mesh)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _fog_material(noise: bool):
    import bpy

    from addon.render import blender_compat

    material = bpy.data.materials.new("Fog")
    tree = blender_compat.ensure_node_tree(material)
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    volume = tree.nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Density"].default_value = DENSITY
    if noise:
        texture = tree.nodes.new("ShaderNodeTexNoise")
        texture.inputs["Scale"].default_value = 3.0
        scale = tree.nodes.new("ShaderNodeMath")
        scale.operation, scale.inputs[1].default_value = "MULTIPLY", 3.0
        tree.links.new(texture.outputs["Fac"], scale.inputs[0])
        tree.links.new(scale.outputs[0], volume.inputs["Density"])
    tree.links.new(volume.outputs[0], output.inputs["Volume"])
    return material


def build(noise: bool = False):
    """The scene in the running Blender (an empty file first); returns (scene, light, fog)."""
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.name = "fog"
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    ground = bpy.data.meshes.new("Ground")
    ground.from_pydata([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(bpy.data.objects.new("Ground", ground))
    _box("Figure", tuple(2.0 * FIGURE_HALF), tuple(FIGURE_CENTRE))
    fog = _box("Fog", (2.0 * BOX_HALF,) * 3, tuple(BOX_CENTRE))
    fog.data.materials.append(_fog_material(noise))
    light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    light.data.energy, light.data.shadow_soft_size, light.location = 1000.0, 0.0, tuple(LIGHT)
    scene.collection.objects.link(light)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location, camera.rotation_euler = (0.0, -4.0, 5.0), (math.radians(38.0), 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    return scene, light, fog


def _inside(position: np.ndarray, centre: np.ndarray, half) -> np.ndarray:
    """The length of each point's segment to the light inside a box (position (..., 3))."""
    p = np.asarray(position, dtype=np.float64).reshape(-1, 3)
    d = LIGHT - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (centre - half - p) / d, (centre + half - p) / d
    enter = np.clip(np.nanmax(np.minimum(t0, t1), axis=1), 0.0, 1.0)
    leave = np.clip(np.nanmin(np.maximum(t0, t1), axis=1), 0.0, 1.0)
    return (np.maximum(leave - enter, 0.0) * np.linalg.norm(d, axis=1)).reshape(np.shape(position)[:-1])


def transmittance(position: np.ndarray) -> np.ndarray:
    """exp(-DENSITY x the length inside the fog of each point's segment to the light)."""
    return np.exp(-DENSITY * _inside(position, BOX_CENTRE, BOX_HALF))


def behind_figure(position: np.ndarray) -> np.ndarray:
    """Whether each point's segment to the light crosses the figure."""
    return _inside(position, FIGURE_CENTRE, FIGURE_HALF) > 0.0


def main(argv: list[str] | None = None) -> int:
    import bpy

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--noise", action="store_true")
    args = parser.parse_args(argv)
    build(args.noise)
    bpy.ops.wm.save_as_mainfile(filepath=str(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
