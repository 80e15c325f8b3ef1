"""Writes a .blend built the way artists build files, for host-time and error checks on a
scene no preset resembles (issue 17): about 300k render triangles.

    .venv/bin/python scripts/artist_scene.py OUT.blend [--scale N] [--sized]

Modifiers (subdivision, array, bevel, solidify, mirror), collection instances, a text
object and a bevelled curve, a point light and a 180 degree spot ("hemi"), and a camera
with lens shift on a parented rig. `--scale` raises the statue's subdivision and
multiplies the instanced trees (2: about 300k render triangles). `--sized` gives the lights
the sizes artists give them (issue 27): the Lamp a 0.25 m radius, the Hemi 0.1 m, and adds
a 1.2 x 0.8 m area light, "Softbox", over the statue, a "Key" spot of 0.15 m radius (a 70
degree cone, blend 0.1) and a "Sun" 2 degrees across.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _link(obj, collection=None):
    import bpy

    (collection or bpy.context.scene.collection).objects.link(obj)
    return obj


def _mesh_object(name: str, maker, location=(0.0, 0.0, 0.0), collection=None, **kwargs):
    """A mesh object from a bmesh primitive (no operators: they need a context)."""
    import bmesh
    import bpy

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    maker(bm, **kwargs)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    return _link(obj, collection)


def build(scale: int, sized: bool = False) -> None:
    import bmesh
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"

    ground = _mesh_object("Ground", bmesh.ops.create_grid, x_segments=60, y_segments=60, size=14.0)
    ground.modifiers.new("Subdivision", "SUBSURF").render_levels = 1

    # A heavy centrepiece: a subdivided sphere with a displacement-free bevel look.
    statue = _mesh_object("Statue", bmesh.ops.create_uvsphere, location=(0.0, 0.0, 1.6), u_segments=48,
                          v_segments=24, radius=1.2)
    statue.scale = (1.0, 0.7, 1.3)
    statue.modifiers.new("Subdivision", "SUBSURF").render_levels = 1 + scale

    # A colonnade: one column arrayed along x, mirrored in y, bevelled.
    column = _mesh_object("Column", bmesh.ops.create_cone, location=(-6.0, 4.0, 0.0), cap_ends=True,
                          segments=24, radius1=0.35, radius2=0.3, depth=3.0)
    column.location.z = 1.5
    array = column.modifiers.new("Array", "ARRAY")
    array.count = 9
    array.relative_offset_displace = (4.0, 0.0, 0.0)
    mirror = column.modifiers.new("Mirror", "MIRROR")
    mirror.use_axis = (False, True, False)
    mirror.mirror_object = ground
    column.modifiers.new("Bevel", "BEVEL").segments = 3

    # A wall with a window, thickened by solidify.
    wall = _mesh_object("Wall", bmesh.ops.create_grid, location=(0.0, -6.5, 2.0), x_segments=40, y_segments=12,
                        size=5.0)
    wall.rotation_euler = (math.pi / 2, 0.0, 0.0)
    wall.scale = (1.0, 0.4, 1.0)
    wall.modifiers.new("Solidify", "SOLIDIFY").thickness = 0.3

    # Trees as a collection, instanced around the scene (nested: a grove instances trees).
    trees = bpy.data.collections.new("Trees")
    bpy.context.scene.collection.children.link(trees)
    trunk = _mesh_object("Trunk", bmesh.ops.create_cone, collection=trees, cap_ends=True, segments=12,
                         radius1=0.15, radius2=0.1, depth=1.6)
    trunk.location.z = 0.8
    crown = _mesh_object("Crown", bmesh.ops.create_icosphere, collection=trees, subdivisions=3, radius=0.8)
    crown.location.z = 2.1
    crown.modifiers.new("Subdivision", "SUBSURF").render_levels = 1
    trees.hide_render = False
    layer_trees = bpy.context.view_layer.layer_collection.children["Trees"]
    layer_trees.exclude = True  # only the instances render
    count = 14 * scale
    for i in range(count):
        angle = i / count * 2 * math.pi
        empty = bpy.data.objects.new(f"Tree.{i:02d}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = trees
        empty.location = (9.5 * math.cos(angle), 9.5 * math.sin(angle), 0.0)
        empty.rotation_euler.z = angle
        empty.scale = (1.0 + 0.1 * (i % 3),) * 3
        _link(empty)

    # Text and a bevelled curve.
    text = bpy.data.curves.new("Sign", "FONT")
    text.body = "OmniWarp"
    text.extrude = 0.08
    text.bevel_depth = 0.01
    sign = bpy.data.objects.new("Sign", text)
    sign.location = (-2.5, -4.0, 0.3)
    sign.rotation_euler = (math.pi / 2, 0.0, 0.0)
    _link(sign)
    curve = bpy.data.curves.new("Rail", "CURVE")
    curve.dimensions = "3D"
    curve.bevel_depth = 0.06
    curve.bevel_resolution = 4
    spline = curve.splines.new("BEZIER")
    spline.bezier_points.add(5)
    for k, point in enumerate(spline.bezier_points):
        point.co = (4.0 * math.cos(k), 4.0 * math.sin(k), 0.6 + 0.3 * math.sin(2 * k))
        point.handle_left_type = point.handle_right_type = "AUTO"
    _link(bpy.data.objects.new("Rail", curve))

    # Lights: a point light in the colonnade, a 180 degree spot under the wall's lintel.
    point = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    point.location = (1.5, 1.0, 3.6)
    point.data.energy = 1500.0
    point.data.shadow_soft_size = 0.25 if sized else 0.0
    _link(point)
    hemi = bpy.data.objects.new("Hemi", bpy.data.lights.new("Hemi", "SPOT"))
    hemi.location = (0.5, -5.5, 4.2)
    hemi.data.spot_size = math.pi
    hemi.data.spot_blend = 0.0
    hemi.data.energy = 1200.0
    hemi.data.shadow_soft_size = 0.1 if sized else 0.0
    _link(hemi)
    if sized:
        box = bpy.data.lights.new("Softbox", "AREA")
        box.shape, box.size, box.size_y, box.energy = "RECTANGLE", 1.2, 0.8, 800.0
        softbox = bpy.data.objects.new("Softbox", box)
        softbox.location = (-1.0, 2.0, 4.0)
        softbox.rotation_euler = (math.radians(-25.0), math.radians(-15.0), 0.0)
        _link(softbox)
        # A key spot of 0.15 m radius with a blended 70 degree cone, and a sun 2 degrees across.
        key = bpy.data.objects.new("Key", bpy.data.lights.new("Key", "SPOT"))
        key.location = (5.0, 4.0, 6.0)
        key.rotation_euler = (math.radians(40.0), 0.0, math.radians(130.0))
        key.data.spot_size, key.data.spot_blend = math.radians(70.0), 0.1
        key.data.energy, key.data.shadow_soft_size = 3000.0, 0.15
        _link(key)
        sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
        sun.rotation_euler = (math.radians(50.0), 0.0, math.radians(-35.0))
        sun.data.energy, sun.data.angle = 3.0, math.radians(2.0)
        _link(sun)

    # A camera with lens shift on a parented, rotated rig.
    rig = _link(bpy.data.objects.new("Rig", None))
    rig.location = (0.0, 0.0, 0.0)
    rig.rotation_euler.z = math.radians(20.0)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.parent = rig
    camera.location = (0.0, 13.0, 6.5)
    camera.rotation_euler = (math.radians(66.0), 0.0, math.radians(180.0))
    camera.data.lens = 30.0
    camera.data.shift_x = 0.08
    camera.data.shift_y = -0.05
    _link(camera)
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = 640, 480


def render_triangle_count() -> int:
    """Triangles of the evaluated scene (render settings are what Cycles sees; the viewport
    depsgraph is near enough for a size check)."""
    import bpy

    depsgraph = bpy.context.evaluated_depsgraph_get()
    total = 0
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.type in {"MESH", "CURVE", "FONT"}:
            mesh = obj.to_mesh()
            mesh.calc_loop_triangles()
            total += len(mesh.loop_triangles)
            obj.to_mesh_clear()
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--scale", type=int, default=2)
    parser.add_argument("--sized", action="store_true", help="lights with the sizes artists give them")
    args = parser.parse_args()
    import bpy

    build(args.scale, args.sized)
    print(f"{args.out}: about {render_triangle_count()} triangles (viewport levels)")
    bpy.ops.wm.save_as_mainfile(filepath=str(args.out.resolve()))


if __name__ == "__main__":
    main()
