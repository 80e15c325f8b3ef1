"""Writes a foliage .blend built the way an artist builds one (run in a child process).

    python tests/support/make_foliage_blend.py OUT.blend [--sized]

Not the foliage preset: the materials come from bpy's own node setups, the way an artist
wires them, and the images are 8-bit sRGB PNGs packed into the file.
- leaves: one leaf card mesh instanced 60 times through a collection instance per empty,
  its Principled BSDF's Alpha from an Image Texture's Alpha (a packed RGBA PNG);
- a fence: a Mix Shader of a Transparent BSDF and a Principled BSDF whose factor is an
  Image Texture's Color through Math Greater Than 0.5, the texture's UVs scaled by a
  Mapping node to tile the wire;
- a net curtain: a Principled BSDF with Alpha 0.4 and a subdivision modifier;
- an opaque barrel (a cylinder) and a ground plane with the default material;
- a point light, and a camera with a lens shift.

`--sized` gives the file the lights an artist lights foliage with (issue 27): the point
light a 0.2 m radius, a "Sun" 3 degrees across, a "Disc" area light (DISK, 1.5 m,
spread 100 degrees) and an "Oval" (ELLIPSE, 2 x 0.8 m, its object scaled 1.2 in x) over
the tree, and a "Key" spot (0.1 m radius, 80 degree cone, blend 0.3) keyed to move
between frames 1 and 3.
"""
from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from addon.compat import blender as blender_compat  # noqa: E402


def _png(name: str, rgba: np.ndarray):
    """A packed 8-bit image from (H, W, 4) floats in [0, 1] (row 0 at the bottom)."""
    import bpy

    height, width = rgba.shape[:2]
    image = bpy.data.images.new(name, width, height, alpha=True)
    image.pixels.foreach_set(np.ascontiguousarray(rgba, dtype=np.float32).ravel())
    path = Path(tempfile.mkdtemp()) / f"{name}.png"
    image.filepath_raw = str(path)
    image.file_format = "PNG"
    image.save()
    loaded = bpy.data.images.load(str(path))
    loaded.pack()
    bpy.data.images.remove(image)
    return loaded


def _leaf_material():
    import bpy

    v, u = (np.indices((48, 48)) + 0.5) / 48
    blade = ((u - 0.5) / 0.45) ** 2 + ((v - 0.5) / 0.28) ** 2 <= 1.0
    rgba = np.zeros((48, 48, 4))
    rgba[..., 1] = 0.6
    rgba[..., 3] = blade
    mat = bpy.data.materials.new("Leaf")
    blender_compat.ensure_node_tree(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = _png("leaf_alpha", rgba)
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    return mat


def _fence_material():
    import bpy

    v, u = (np.indices((32, 32)) + 0.5) / 32
    wire = (np.abs(((u + v) % 1.0) - 0.5) > 0.4) | (np.abs(((u - v) % 1.0) - 0.5) > 0.4)
    rgba = np.ones((32, 32, 4))
    rgba[..., :3] = wire[..., None] * 0.9
    mat = bpy.data.materials.new("ChainLink")
    blender_compat.ensure_node_tree(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Metallic"].default_value = 1.0
    out = nodes["Material Output"]
    transparent = nodes.new("ShaderNodeBsdfTransparent")
    mix = nodes.new("ShaderNodeMixShader")
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = _png("chain_link", rgba)
    coords = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (30.0, 8.0, 1.0)
    links.new(coords.outputs["UV"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    step = nodes.new("ShaderNodeMath")
    step.operation = "GREATER_THAN"
    step.inputs[1].default_value = 0.5
    links.new(tex.outputs["Color"], step.inputs[0])
    links.new(step.outputs[0], mix.inputs["Fac"])
    links.new(transparent.outputs["BSDF"], mix.inputs[1])
    links.new(bsdf.outputs["BSDF"], mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return mat


def _curtain_material():
    import bpy

    mat = bpy.data.materials.new("NetCurtain")
    blender_compat.ensure_node_tree(mat)
    mat.node_tree.nodes["Principled BSDF"].inputs["Alpha"].default_value = 0.4
    return mat


def _sized_lights() -> None:
    """The foliage's sized lights (see the module's docstring)."""
    import bpy

    scene = bpy.context.scene
    point = next(o for o in scene.objects if o.type == "LIGHT")
    point.data.shadow_soft_size = 0.2
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.angle = math.radians(3.0)
    sun.rotation_euler = (math.radians(40.0), 0.0, math.radians(150.0))
    scene.collection.objects.link(sun)
    for name, shape, size, size_y, location in (("Disc", "DISK", 1.5, 1.5, (-1.0, 0.5, 5.5)),
                                               ("Oval", "ELLIPSE", 2.0, 0.8, (1.0, -1.0, 4.5))):
        area = bpy.data.objects.new(name, bpy.data.lights.new(name, "AREA"))
        area.data.shape, area.data.size, area.data.size_y = shape, size, size_y
        area.location = location
        scene.collection.objects.link(area)
    disc = bpy.data.objects["Disc"]
    disc.data.spread = math.radians(100.0)
    oval = bpy.data.objects["Oval"]
    oval.scale = (1.2, 1.0, 1.0)
    oval.rotation_euler = (math.radians(20.0), 0.0, 0.0)
    key = bpy.data.objects.new("Key", bpy.data.lights.new("Key", "SPOT"))
    key.data.shadow_soft_size = 0.1
    key.data.spot_size = math.radians(80.0)
    key.data.spot_blend = 0.3
    for frame, location in ((1, (4.0, -3.0, 5.0)), (3, (3.0, 4.0, 5.5))):
        key.location = location
        key.rotation_euler = tuple(_look(np.array([-1.0, 1.0, 0.5]) - np.array(location)))
        key.keyframe_insert("location", frame=frame)
        key.keyframe_insert("rotation_euler", frame=frame)
    scene.collection.objects.link(key)
    scene.frame_start, scene.frame_end = 1, 3


def main(out: str, sized: bool = False) -> None:
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 320, 240
    bpy.ops.mesh.primitive_plane_add(size=14.0)
    # The leaf card, kept in a collection that is not rendered itself, instanced by empties.
    leaves = bpy.data.collections.new("LeafCard")
    bpy.ops.mesh.primitive_plane_add(size=1.0)
    card = bpy.context.active_object
    card.name = "leaf_card"
    card.scale = (0.5, 0.32, 1.0)
    card.data.materials.append(_leaf_material())
    for collection in card.users_collection:
        collection.objects.unlink(card)
    leaves.objects.link(card)
    rng = np.random.default_rng(7)
    for i in range(60):
        empty = bpy.data.objects.new(f"leaf_{i:02d}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = leaves
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        empty.location = tuple(np.array([-1.5, 1.0, 2.6]) + d * rng.uniform(0.4, 1.1))
        empty.rotation_euler = tuple(rng.uniform(0.0, math.pi, size=3))
        scene.collection.objects.link(empty)
    bpy.ops.mesh.primitive_cylinder_add(radius=0.12, depth=2.2, location=(-1.5, 1.0, 1.1))  # the trunk
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(2.0, 3.0, 0.9), rotation=(math.pi / 2, 0.0, 0.0))
    fence = bpy.context.active_object
    fence.name = "fence"
    fence.scale = (6.0, 1.8, 1.0)
    fence.data.materials.append(_fence_material())
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(3.2, -0.5, 1.3), rotation=(0.0, math.pi / 2, 0.0))
    curtain = bpy.context.active_object
    curtain.name = "curtain"
    curtain.modifiers.new("subdivide", "SUBSURF").levels = 1
    curtain.data.materials.append(_curtain_material())
    bpy.ops.mesh.primitive_cylinder_add(radius=0.5, depth=1.0, location=(0.5, -2.5, 0.5))
    bpy.ops.object.light_add(type="POINT", location=(0.0, 0.5, 6.5))
    bpy.context.active_object.data.shadow_soft_size = 0.0
    bpy.ops.object.camera_add(location=(6.5, 7.0, 6.5))
    camera = bpy.context.active_object
    direction = np.array([-0.8, -0.5, 0.0]) - np.array(camera.location)
    camera.rotation_euler = tuple(_look(direction))
    camera.data.shift_x = 0.05
    scene.camera = camera
    if sized:
        _sized_lights()
    bpy.ops.wm.save_as_mainfile(filepath=out)


def _look(direction: np.ndarray):
    """Euler angles that point a camera's -Z along `direction` (Y up)."""
    from mathutils import Vector

    return Vector(direction.tolist()).to_track_quat("-Z", "Y").to_euler()


if __name__ == "__main__":
    main(sys.argv[1], "--sized" in sys.argv[2:])
