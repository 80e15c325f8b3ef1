"""A furnished isometric interior built as artists build one (issue 53's 4.0 file, rebuilt):

    python tests/support/make_interior_blend.py OUT.blend [--size W H] [--detail N]

A room of two walls on a floor slab that stands on a wider ground, about 75,000 render
triangles at the default detail (2) from modifiers:
- `WallBack`, `WallLeft`: grids thickened by Solidify; the left wall's window cut by a
  Boolean whose cutter is hidden from renders and drawn as a wire;
- `Shelf`: a board arrayed upwards (Array), `Books` arrayed along it;
- `Table`: a bevelled top and one leg mirrored in x and y (Mirror about the top);
- `Sofa`: a bevelled body and three subdivided cushions (Subdivision, render levels above
  the viewport's); `Rug`: a fine grid with Solidify;
- `Pot` and `PlantCrown`: a pot, and a subdivided grid over it whose geometry nodes put a leaf on each of its points (instances);
- `LampBase`, `LampStem`, `LampShade` (Solidify) and a `Bulb` that emits light (an Emission shader);
- `Chair` and `Chair.001`: two objects sharing one mesh.
Lights: `Spot` (40 W, radius 0, 51.6 degree cone, blend 0.15) over the table, `Spot2`
(radius 0) at the shelf; `Overhead` (a square area light of 3.1 m, 30 W), `Window` (a
rectangle at the window), `Strip` (an ellipse) and `Fill` (a disk with shadows off). The
camera looks down at the room from the open corner (--size, default 320 x 240).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from tests.support.make_left_out_blend import _camera, _geometry_nodes, _node, _object  # noqa: E402


def _box(name: str, size, location) -> "bpy.types.Object":
    """A box of `size` (x, y, z) with its centre at `location`."""
    import bmesh

    obj = _object(name, lambda made: bmesh.ops.create_cube(made, size=1.0), location)
    obj.scale = size
    return obj


def _grid(name: str, segments: int, size: float, location, rotation=(0.0, 0.0, 0.0)):
    import bmesh

    obj = _object(name, lambda made: bmesh.ops.create_grid(made, x_segments=segments, y_segments=segments,
                                                           size=size), location)
    obj.rotation_euler = rotation
    return obj


def _cylinder(name: str, radius: float, depth: float, location, radius2: float | None = None):
    import bmesh

    return _object(name, lambda made: bmesh.ops.create_cone(made, cap_ends=True, segments=24, radius1=radius,
                                                            radius2=radius if radius2 is None else radius2,
                                                            depth=depth), location)


def _leaves(leaf):
    """Geometry nodes: a leaf instanced on every point of the input mesh, rotated at random."""
    def build(tree, geometry):
        points = _node(tree, "GeometryNodeMeshToPoints")
        tree.links.new(geometry, points.inputs["Mesh"])
        info = _node(tree, "GeometryNodeObjectInfo")
        info.inputs["Object"].default_value = leaf
        rotation = _node(tree, "FunctionNodeRandomValue", data_type="FLOAT_VECTOR")
        rotation.inputs[1].default_value = (math.tau, math.tau, math.tau)
        place = _node(tree, "GeometryNodeInstanceOnPoints")
        tree.links.new(points.outputs["Points"], place.inputs["Points"])
        tree.links.new(info.outputs["Geometry"], place.inputs["Instance"])
        tree.links.new(rotation.outputs[0], place.inputs["Rotation"])
        join = _node(tree, "GeometryNodeJoinGeometry")
        tree.links.new(place.outputs[0], join.inputs[0])
        tree.links.new(geometry, join.inputs[0])
        return join.outputs[0]
    return build


def _emission(name: str, strength: float) -> "bpy.types.Material":
    import bpy

    material = bpy.data.materials.new(name)
    if material.node_tree is None:  # Blender 4.x; 5.x gives a new material its tree
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    emit = tree.nodes.new("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = strength
    tree.links.new(emit.outputs[0], output.inputs["Surface"])
    return material


def _light(name: str, kind: str, location, rotation, energy: float, **values):
    import bpy

    light = bpy.data.lights.new(name, kind)
    light.energy = energy
    for key, value in values.items():
        setattr(light, key, value)
    obj = bpy.data.objects.new(name, light)
    obj.location, obj.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


def build(out: Path, size: tuple[int, int], detail: int) -> None:
    import bpy
    from mathutils import Matrix

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100

    _box("Ground", (9.0, 9.0, 0.1), (0.0, 0.0, -0.2))
    floor = _box("Floor", (4.2, 4.2, 0.15), (0.0, 0.0, -0.075))
    floor.modifiers.new("Bevel", "BEVEL").width = 0.02

    back = _grid("WallBack", 20, 2.0, (0.0, 2.0, 1.3), (math.pi / 2, 0.0, 0.0))
    back.scale = (1.0, 0.65, 1.0)
    back.modifiers.new("Solidify", "SOLIDIFY").thickness = 0.15
    left = _grid("WallLeft", 20, 2.0, (-2.0, 0.0, 1.3), (math.pi / 2, 0.0, math.pi / 2))
    left.scale = (1.0, 0.65, 1.0)
    left.modifiers.new("Solidify", "SOLIDIFY").thickness = 0.15
    cutter = _box("WindowCutter", (0.6, 1.2, 1.0), (-2.0, 0.3, 1.4))
    cutter.hide_render = True
    cutter.display_type = "WIRE"
    window = left.modifiers.new("Window", "BOOLEAN")
    window.operation, window.object = "DIFFERENCE", cutter

    board = _box("Shelf", (0.9, 0.3, 0.03), (1.1, 1.75, 0.3))
    shelves = board.modifiers.new("Array", "ARRAY")
    shelves.count, shelves.relative_offset_displace = 5, (0.0, 0.0, 14.0)
    books = _box("Books", (0.04, 0.22, 0.28), (0.72, 1.75, 0.47))
    row = books.modifiers.new("Array", "ARRAY")
    row.count, row.relative_offset_displace = 16, (1.3, 0.0, 0.0)
    books.modifiers.new("Bevel", "BEVEL").width = 0.005

    top = _box("Table", (1.2, 0.8, 0.05), (0.2, -0.3, 0.75))
    top.modifiers.new("Bevel", "BEVEL").segments = 3
    leg = _cylinder("TableLeg", 0.03, 0.72, (0.72, 0.0, 0.36))
    leg.parent = top
    leg.matrix_parent_inverse = top.matrix_world.inverted()
    mirror = leg.modifiers.new("Mirror", "MIRROR")
    mirror.use_axis = (True, True, False)
    mirror.mirror_object = top
    chair_mesh = _box("Chair", (0.45, 0.45, 0.05), (0.9, -0.9, 0.45)).data
    chair = bpy.data.objects["Chair"]
    chair.modifiers.new("Solidify", "SOLIDIFY").thickness = 0.02
    twin = bpy.data.objects.new("Chair.001", chair_mesh)
    twin.location, twin.rotation_euler = (-0.5, -0.9, 0.45), (0.0, 0.0, 0.3)
    scene.collection.objects.link(twin)

    body = _box("Sofa", (0.8, 2.0, 0.4), (-1.45, -0.2, 0.2))
    body.modifiers.new("Bevel", "BEVEL").segments = 4
    for i in range(3):
        cushion = _box(f"Cushion.{i}", (0.6, 0.6, 0.18), (-1.4, -0.85 + 0.65 * i, 0.5))
        sub = cushion.modifiers.new("Subdivision", "SUBSURF")
        sub.levels, sub.render_levels = 1, 2 + detail
    rug = _grid("Rug", 60 * detail, 0.9, (0.2, -0.3, 0.005))
    rug.scale = (1.2, 0.8, 1.0)
    rug.modifiers.new("Solidify", "SOLIDIFY").thickness = 0.01

    leaf = _box("Leaf", (1.0, 1.0, 1.0), (0.0, 0.0, -20.0))
    leaf.data.transform(Matrix.Diagonal((0.12, 0.04, 0.005, 1.0)))  # instances take the mesh alone
    leaf.hide_render = True
    _cylinder("Pot", 0.18, 0.35, (1.6, -1.5, 0.175), radius2=0.14)
    crown = _grid("PlantCrown", 6 * detail, 0.15, (1.6, -1.5, 0.6))
    crown.modifiers.new("Subdivision", "SUBSURF").render_levels = 1
    gn = crown.modifiers.new("Leaves", "NODES")
    gn.node_group = _geometry_nodes("leaves", _leaves(leaf))

    _cylinder("LampBase", 0.08, 0.04, (0.5, -0.2, 0.8))
    _cylinder("LampStem", 0.01, 0.35, (0.5, -0.2, 0.99))
    shade = _cylinder("LampShade", 0.16, 0.18, (0.5, -0.2, 1.2), radius2=0.09)
    shade.modifiers.new("Solidify", "SOLIDIFY").thickness = 0.005
    bulb = _cylinder("Bulb", 0.03, 0.06, (0.5, -0.2, 1.15))
    bulb.data.materials.append(_emission("BulbLight", 30.0))

    _light("Spot", "SPOT", (0.3, -0.4, 2.5), (math.radians(8.0), 0.0, 0.0), 40.0,
           spot_size=math.radians(51.6), spot_blend=0.15, shadow_soft_size=0.0)
    _light("Spot2", "SPOT", (0.2, 0.4, 2.4), (math.radians(-35.0), 0.0, math.radians(-20.0)), 60.0,
           spot_size=math.radians(40.0), spot_blend=0.3, shadow_soft_size=0.0)
    _light("Overhead", "AREA", (0.0, 0.0, 2.45), (0.0, 0.0, 0.0), 30.0, shape="SQUARE", size=3.1)
    _light("Window", "AREA", (-1.8, 0.3, 1.4), (0.0, math.radians(-90.0), 0.0), 20.0,
           shape="RECTANGLE", size=0.6, size_y=1.0)
    _light("Strip", "AREA", (1.2, 1.5, 2.3), (math.radians(20.0), 0.0, 0.0), 15.0,
           shape="ELLIPSE", size=1.2, size_y=0.2)
    _light("Fill", "AREA", (1.5, -1.8, 2.2), (math.radians(-30.0), 0.0, math.radians(30.0)), 10.0,
           shape="DISK", size=0.8, use_shadow=False)

    _camera(scene, (6.0, -6.0, 5.2), (math.radians(60.0), 0.0, math.radians(45.0)), lens=35.0)
    bpy.ops.wm.save_as_mainfile(filepath=str(out))


def main() -> None:
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    parser = argparse.ArgumentParser()
    parser.add_argument("out", type=Path)
    parser.add_argument("--size", type=int, nargs=2, default=(320, 240))
    parser.add_argument("--detail", type=int, default=2)
    args = parser.parse_args(argv)
    build(args.out, tuple(args.size), args.detail)


if __name__ == "__main__":
    main()
