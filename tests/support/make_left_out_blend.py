"""A small file with what Cycles renders that OmniWarp's methods draw other than as
triangles, or do not draw (issue 42):

    python tests/support/make_left_out_blend.py OUT.blend [--notes OUT.json]

Built the way an artist builds it, on a ground plane under a point light and a camera:
- `Pebbles`: a mesh whose geometry nodes turn its vertices into points (Mesh to Points);
- `Strands`: a hair curves object whose geometry nodes make its strand (a Curve Line of
  radius 0.05); `Wire`: a mesh whose geometry nodes output the same curve, which Cycles
  does not render (no note: the walk must not report what Cycles leaves out too);
- `Groom`: a mesh with a hair particle system drawn as strands; `Ivy`: one whose hair
  particles are drawn as instanced objects (meshes: drawn, so no note);
- `Cloud`: a mesh whose geometry nodes instance a volume (Volume Cube) on its points (its
  grids are not read: named); `Wisp`: a mesh whose geometry nodes output one (read, a
  grid medium: no note);
- `Fog`: a box with a Principled Volume whose density is a noise texture of an attribute's
  coordinates, and no surface shader (a heterogeneous medium, not followed: an attribute
  has no geometry-nodes twin for `shader_density`); `Mist`: a box of a constant Volume
  Absorption (a homogeneous medium, drawn: no note);
- `Bumps`: a plane with true displacement;
- `Hidden`: points like the pebbles, but hidden from renders (no note);
- `Unseen`: a strand like the strands, but with `visible_shadow` off (no note for the light);
- `Cutout`: a holdout object (the shadow rule's note: the reference renders it plain).
With --notes, also reads the render depsgraph (render_geometry.render_triangles) and
writes every left-out note, and those of the light's shadow rule, and the owners of the
points and strands it keeps (drawn as pieces), as JSON.

    python tests/support/make_left_out_blend.py OUT.blend --blockers

builds instead a file of points and hair alone over the ground, for the oracle of
core/blockers.py against Cycles: pebbles of three radii (geometry nodes' Mesh to Points
on a grid), hair curves objects with spiral strands of a few control points each (so
that Cycles' interpolation between them shows: one poly, one Catmull-Rom) and one
straight strand, particle hair on a box (40 strands, tapering, leaning at random, with
3 interpolated children each in renders); a mesh box among them.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))


def _geometry_nodes(name: str, build) -> "bpy.types.NodeTree":
    """A geometry node group: Group Input's geometry -> build(tree, geometry socket) -> Group Output."""
    import bpy

    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    group_in = tree.nodes.new("NodeGroupInput")
    group_out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(build(tree, group_in.outputs[0]), group_out.inputs[0])
    return tree


def _node(tree, idname: str, **values):
    """A new node of `tree`, its inputs set by name (spaces as underscores) or by index
    (`_0`, `_1`, ...), its other properties by name."""
    node = tree.nodes.new(idname)
    for key, value in values.items():
        if key.startswith("_") and key[1:].isdigit():
            node.inputs[int(key[1:])].default_value = value
        elif key.replace("_", " ") in node.inputs:
            node.inputs[key.replace("_", " ")].default_value = value
        else:
            setattr(node, key, value)
    return node


def _with_radius(tree, curve, radius: float):
    """`curve` (a socket) with every point's radius set."""
    node = _node(tree, "GeometryNodeSetCurveRadius", Radius=radius)
    tree.links.new(curve, node.inputs["Curve"])
    return node.outputs["Curve"]


def _points(tree, geometry):
    node = _node(tree, "GeometryNodeMeshToPoints", Radius=0.04)
    tree.links.new(geometry, node.inputs["Mesh"])
    return node.outputs["Points"]


def _curve(tree, geometry):
    return _with_radius(tree, _node(tree, "GeometryNodeCurvePrimitiveLine", End=(0.0, 0.0, 1.0)).outputs["Curve"],
                        0.05)


def _hair(name: str, location) -> "bpy.types.Object":
    """A hair curves object (Blender's Curves type) whose one strand geometry nodes make."""
    import bpy

    obj = bpy.data.objects.new(name, bpy.data.hair_curves.new(name))
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    _with_nodes(obj, _geometry_nodes(f"{name} strand", _curve))
    return obj


def _volume(tree, geometry):
    return _node(tree, "GeometryNodeVolumeCube", Min=(-0.3, -0.3, 0.0), Max=(0.3, 0.3, 0.6)).outputs["Volume"]


def _instanced_volume(tree, geometry):
    """A small volume cube instanced on the mesh's points: OmniWarp cannot read its grid."""
    node = _node(tree, "GeometryNodeInstanceOnPoints")
    tree.links.new(geometry, node.inputs["Points"])
    tree.links.new(_volume(tree, geometry), node.inputs["Instance"])
    return node.outputs["Instances"]


def _object(name: str, fill, location=(0.0, 0.0, 0.0)) -> "bpy.types.Object":
    """A mesh object linked to the scene at `location`, its mesh made by `fill(bmesh)`."""
    import bmesh
    import bpy

    mesh = bpy.data.meshes.new(name)
    made = bmesh.new()
    fill(made)
    made.to_mesh(mesh)
    made.free()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _mesh(name: str, size: float, location) -> "bpy.types.Object":
    """A cube of side `size` centred at `location`."""
    import bmesh

    return _object(name, lambda made: bmesh.ops.create_cube(made, size=size), location)


def _camera(scene, location, rotation, lens: float | None = None) -> "bpy.types.Object":
    """The scene's camera, at `location` turned by the Euler angles `rotation` (radians)."""
    import bpy

    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = location
    camera.rotation_euler = rotation
    if lens is not None:
        camera.data.lens = lens
    scene.collection.objects.link(camera)
    scene.camera = camera
    return camera


def _with_nodes(obj, tree) -> None:
    modifier = obj.modifiers.new("nodes", "NODES")
    modifier.node_group = tree


def _material(name: str):
    import bpy

    from addon.compat import blender as blender_compat

    material = bpy.data.materials.new(name)
    tree = blender_compat.ensure_node_tree(material)
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    return material, tree, output


def _stage(size: tuple[int, int]) -> "bpy.types.Scene":
    """An empty file with a ground, a hard point light and a camera."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100

    ground = bpy.data.objects.new("Ground", bpy.data.meshes.new("Ground"))
    ground.data.from_pydata([(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(ground)

    light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    light.data.energy = 1000.0
    light.data.shadow_soft_size = 0.0
    light.location = (0.5, -0.5, 4.0)
    scene.collection.objects.link(light)
    _camera(scene, (0.0, -7.0, 5.0), (0.9, 0.0, 0.0))
    return scene


def _spiral(tree, geometry):
    """Spiral strands: a few control points a turn, so that the curve between them shows."""
    node = _node(tree, "GeometryNodeCurveSpiral", Resolution=5, Rotations=1.5, Start_Radius=0.5, End_Radius=0.2,
                 Height=1.2)
    return _with_radius(tree, node.outputs["Curve"], 0.03)


def _catmull_rom_spiral(tree, geometry):
    """The spiral, its curve type set to Catmull-Rom (hair's own type)."""
    kind = _node(tree, "GeometryNodeCurveSplineType", spline_type="CATMULL_ROM")
    tree.links.new(_spiral(tree, geometry), kind.inputs["Curve"])
    return kind.outputs["Curve"]


def _grid_points(tree, geometry):
    """A grid of points, their radius cycling through three sizes: 0.04 + 0.03 (index % 3)."""
    grid = _node(tree, "GeometryNodeMeshGrid", Size_X=2.0, Size_Y=1.5, Vertices_X=7, Vertices_Y=5)
    index = _node(tree, "GeometryNodeInputIndex")
    modulo = _node(tree, "ShaderNodeMath", operation="MODULO", _1=3.0)
    tree.links.new(index.outputs[0], modulo.inputs[0])
    scale = _node(tree, "ShaderNodeMath", operation="MULTIPLY_ADD", _1=0.03, _2=0.04)
    tree.links.new(modulo.outputs[0], scale.inputs[0])
    points = _node(tree, "GeometryNodeMeshToPoints")
    tree.links.new(grid.outputs["Mesh"], points.inputs["Mesh"])
    tree.links.new(scale.outputs[0], points.inputs["Radius"])
    return points.outputs["Points"]


def build_blockers(out: Path) -> None:
    """Points and hair over the ground (the module docstring's --blockers)."""
    import bpy

    _stage((160, 120))
    pebbles = _mesh("Pebbles", 0.1, (-1.0, 0.0, 0.6))
    _with_nodes(pebbles, _geometry_nodes("pebble grid", _grid_points))
    hair = bpy.data.objects.new("Spirals", bpy.data.hair_curves.new("Spirals"))
    hair.location = (1.2, 0.5, 0.1)
    bpy.context.scene.collection.objects.link(hair)
    _with_nodes(hair, _geometry_nodes("spirals", _spiral))
    _hair("Straight", (0.3, -1.2, 0.1))
    fur = _mesh("Fur", 0.6, (-0.4, 1.2, 0.3))
    fur_hair = fur.modifiers.new("fur", "PARTICLE_SYSTEM").particle_system.settings
    fur_hair.type, fur_hair.count, fur_hair.render_type, fur_hair.hair_length = "HAIR", 40, "PATH", 0.8
    fur_hair.radius_scale, fur_hair.root_radius, fur_hair.tip_radius = 0.06, 1.0, 0.3
    fur_hair.use_advanced_hair = True
    fur_hair.factor_random = 0.4  # strands that lean and cross, so their keys' curve shows
    # Three interpolated children a strand in renders: Cycles then draws the children alone.
    fur_hair.child_type, fur_hair.rendered_child_count, fur_hair.child_radius = "INTERPOLATED", 3, 0.3
    rounded = bpy.data.objects.new("Rounded", bpy.data.hair_curves.new("Rounded"))
    rounded.location = (-1.6, -1.4, 0.1)
    bpy.context.scene.collection.objects.link(rounded)
    _with_nodes(rounded, _geometry_nodes("rounded spirals", _catmull_rom_spiral))
    _mesh("Box", 0.4, (0.8, -0.5, 0.2))
    bpy.ops.wm.save_as_mainfile(filepath=str(out))


def build(out: Path) -> None:
    import bpy

    scene = _stage((96, 72))
    pebbles = _mesh("Pebbles", 0.8, (-1.5, 0.0, 0.5))
    _with_nodes(pebbles, _geometry_nodes("to points", _points))
    _hair("Strands", (1.5, 0.0, 0.2))
    wire = _mesh("Wire", 0.2, (1.0, -2.5, 0.2))
    _with_nodes(wire, _geometry_nodes("to curve", _curve))
    groom = _mesh("Groom", 0.5, (0.0, 1.5, 0.3))
    hair = groom.modifiers.new("hair", "PARTICLE_SYSTEM").particle_system.settings
    hair.type, hair.count, hair.render_type, hair.hair_length = "HAIR", 50, "PATH", 0.6
    ivy = _mesh("Ivy", 0.5, (-1.5, 1.5, 0.3))
    leaf = _mesh("Leaf", 0.05, (0.0, 0.0, -10.0))
    leaf.hide_render = True  # the particles' instance object, drawn only as instances
    ivy_settings = ivy.modifiers.new("leaves", "PARTICLE_SYSTEM").particle_system.settings
    ivy_settings.type, ivy_settings.count, ivy_settings.render_type = "HAIR", 20, "OBJECT"
    ivy_settings.instance_object = leaf
    cloud = _mesh("Cloud", 0.5, (1.5, 1.5, 0.5))
    _with_nodes(cloud, _geometry_nodes("instanced volume", _instanced_volume))
    wisp = _mesh("Wisp", 0.5, (-1.5, 1.5, 0.5))
    _with_nodes(wisp, _geometry_nodes("to volume", _volume))

    fog = _mesh("Fog", 1.0, (0.0, -1.5, 0.6))
    material, tree, output = _material("Smoke")
    volume = _node(tree, "ShaderNodeVolumePrincipled")
    noise = _node(tree, "ShaderNodeTexNoise")  # a density that varies: not followed
    tree.links.new(noise.outputs["Fac"], volume.inputs["Density"])
    # At an attribute's coordinates: not read as a grid either (shader_density.py).
    tree.links.new(_node(tree, "ShaderNodeAttribute").outputs["Vector"], noise.inputs["Vector"])
    tree.links.new(volume.outputs[0], output.inputs["Volume"])
    fog.data.materials.append(material)
    mist = _mesh("Mist", 0.6, (0.0, 0.0, 1.6))  # a homogeneous medium: drawn, so not named
    material, tree, output = _material("Haze")
    volume = _node(tree, "ShaderNodeVolumeAbsorption", Density=0.5)
    tree.links.new(volume.outputs[0], output.inputs["Volume"])
    mist.data.materials.append(material)

    bumps = _mesh("Bumps", 0.6, (-1.5, -1.5, 0.3))
    material, tree, output = _material("Bumpy")
    diffuse = _node(tree, "ShaderNodeBsdfDiffuse")
    tree.links.new(diffuse.outputs[0], output.inputs["Surface"])
    displace = _node(tree, "ShaderNodeDisplacement")
    noise = _node(tree, "ShaderNodeTexNoise")
    tree.links.new(noise.outputs[0], displace.inputs["Height"])
    tree.links.new(displace.outputs[0], output.inputs["Displacement"])
    material.displacement_method = "DISPLACEMENT"
    bumps.data.materials.append(material)

    hidden = _mesh("Hidden", 0.4, (2.5, -1.5, 0.3))
    _with_nodes(hidden, _geometry_nodes("hidden points", _points))
    hidden.hide_render = True
    _hair("Unseen", (2.5, 1.5, 0.2)).visible_shadow = False
    _mesh("Cutout", 0.3, (2.5, 0.0, 0.2)).is_holdout = True

    bpy.ops.wm.save_as_mainfile(filepath=str(out))


def notes(out: Path) -> None:
    """Every left-out note of the saved file's render geometry, and the light's."""
    import bpy

    from addon.readers.render_geometry import render_triangles
    from addon.readers.shadow_rule import ShadowRule

    scene = bpy.context.scene
    layer = scene.view_layers[0]
    found = render_triangles(scene, layer)
    rule = ShadowRule.for_light(scene, bpy.data.objects["Lamp"], notes=False, view_layer=layer)
    layer.use_strand = False  # the view layer's Strands off: Cycles renders no hair
    no_strands = render_triangles(scene, layer)
    def owners(kept, keep=None):
        return sorted({o.parent or o.name for o, _ in kept if keep is None or keep(o.name, o.parent)})

    out.write_text(json.dumps({"all": found.left_out.notes(), "light": found.left_out.notes(rule.blocks),
                               "names": sorted(found.names), "no_strands": no_strands.left_out.notes(),
                               "strands": [len(found.strands), len(no_strands.strands)],
                               "grids": owners(found.grids),
                               "kept": {"points": owners(found.spheres), "strands": owners(found.strands),
                                        "light_strands": owners(found.strands, rule.blocks)}}, indent=1))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--notes", type=Path, default=None)
    parser.add_argument("--blockers", action="store_true")
    args = parser.parse_args()
    if args.blockers:
        build_blockers(args.out)
        return 0
    build(args.out)
    if args.notes is not None:
        notes(args.notes)
    return 0


if __name__ == "__main__":
    sys.exit(main())
