"""A head and shoulders with groomed hair and a bed of pebbles, as an artist builds them
(issue 42's example file):

    python tests/support/make_groom_blend.py OUT.blend [--shape RIBBONS|THICK] [--light-radius R]

- `Head` (a sphere of 12 cm) on `Shoulders` (a box), over a ground plane;
- `Hair`: a hair curves object whose geometry nodes grow about 6,000 strands of 8 points
  from the head's upper half (Distribute Points on Faces, a Curve Line of 15 cm instanced
  along each normal, realized, drooping with the square of its length, radius 4 mm,
  Catmull-Rom, hair's own type);
- `Pebbles`: a mesh whose geometry nodes turn a jittered 20 x 20 grid into 400 points of
  2-4 cm (Mesh to Points);
- `Seeds`: 300 points that geometry nodes scatter over the ground as a point cloud
  (Distribute Points on Faces, its points kept as points);
- a point light (hard unless --light-radius), or with --sun-angle a sun that many degrees
  across; a camera at the head, 200 x 150 pixels (--size W H).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from tests.support.make_left_out_blend import _geometry_nodes, _mesh, _node, _with_nodes  # noqa: E402


def _link(tree, socket, node, name):
    tree.links.new(socket, node.inputs[name])


def _socket(sockets, name: str, kind: str):
    """The socket of `name` and type `kind` (Random Value has one Min and Max per type)."""
    return next(s for s in sockets if s.name == name and s.type == kind)


def _hair(head):
    """The groom: strands along the head's upper normals, drooping."""
    def build(tree, geometry):
        info = _node(tree, "GeometryNodeObjectInfo", transform_space="RELATIVE")
        info.inputs["Object"].default_value = head
        normal = _node(tree, "GeometryNodeInputNormal")
        split = _node(tree, "ShaderNodeSeparateXYZ")
        _link(tree, normal.outputs[0], split, "Vector")
        upper = _node(tree, "FunctionNodeCompare", data_type="FLOAT", operation="GREATER_THAN", B=0.05)
        tree.links.new(split.outputs["Z"], upper.inputs[0])
        scatter = _node(tree, "GeometryNodeDistributePointsOnFaces", Density=65000.0, Seed=3)
        _link(tree, info.outputs["Geometry"], scatter, "Mesh")
        _link(tree, upper.outputs[0], scatter, "Selection")
        line = _node(tree, "GeometryNodeCurvePrimitiveLine", End=(0.0, 0.0, 0.15))
        resample = _node(tree, "GeometryNodeResampleCurve", Count=8)
        _link(tree, line.outputs["Curve"], resample, "Curve")
        align = _node(tree, "FunctionNodeAlignEulerToVector", axis="Z")
        _link(tree, scatter.outputs["Normal"], align, "Vector")
        place = _node(tree, "GeometryNodeInstanceOnPoints")
        _link(tree, scatter.outputs["Points"], place, "Points")
        _link(tree, resample.outputs["Curve"], place, "Instance")
        _link(tree, align.outputs["Rotation"], place, "Rotation")
        real = _node(tree, "GeometryNodeRealizeInstances")
        _link(tree, place.outputs["Instances"], real, "Geometry")
        factor = _node(tree, "GeometryNodeSplineParameter")
        square = _node(tree, "ShaderNodeMath", operation="POWER", _1=2.0)
        tree.links.new(factor.outputs["Factor"], square.inputs[0])
        droop = _node(tree, "ShaderNodeCombineXYZ")
        scale = _node(tree, "ShaderNodeMath", operation="MULTIPLY", _1=-0.12)
        tree.links.new(square.outputs[0], scale.inputs[0])
        tree.links.new(scale.outputs[0], droop.inputs["Z"])
        move = _node(tree, "GeometryNodeSetPosition")
        _link(tree, real.outputs["Geometry"], move, "Geometry")
        _link(tree, droop.outputs[0], move, "Offset")
        radius = _node(tree, "GeometryNodeSetCurveRadius", Radius=0.004)
        _link(tree, move.outputs["Geometry"], radius, "Curve")
        kind = _node(tree, "GeometryNodeCurveSplineType", spline_type="CATMULL_ROM")
        _link(tree, radius.outputs["Curve"], kind, "Curve")
        return kind.outputs["Curve"]
    return build


def _pebbles(tree, geometry):
    """A jittered 20 x 20 grid turned into points of 2-4 cm."""
    grid = _node(tree, "GeometryNodeMeshGrid", Size_X=2.4, Size_Y=1.6, Vertices_X=20, Vertices_Y=20)
    jitter = _node(tree, "FunctionNodeRandomValue", data_type="FLOAT_VECTOR", Seed=5)
    _socket(jitter.inputs, "Min", "VECTOR").default_value = (-0.05, -0.05, 0.0)
    _socket(jitter.inputs, "Max", "VECTOR").default_value = (0.05, 0.05, 0.0)
    move = _node(tree, "GeometryNodeSetPosition")
    _link(tree, grid.outputs["Mesh"], move, "Geometry")
    tree.links.new(_socket(jitter.outputs, "Value", "VECTOR"), move.inputs["Offset"])
    size = _node(tree, "FunctionNodeRandomValue", data_type="FLOAT", Seed=9)
    _socket(size.inputs, "Min", "VALUE").default_value = 0.02
    _socket(size.inputs, "Max", "VALUE").default_value = 0.04
    points = _node(tree, "GeometryNodeMeshToPoints")
    _link(tree, move.outputs["Geometry"], points, "Mesh")
    tree.links.new(_socket(size.outputs, "Value", "VALUE"), points.inputs["Radius"])
    return points.outputs["Points"]


def _seeds(tree, geometry):
    """300 points of 1.5 cm scattered over a patch of the ground, kept as a point cloud."""
    patch = _node(tree, "GeometryNodeMeshGrid", Size_X=1.6, Size_Y=1.2, Vertices_X=2, Vertices_Y=2)
    scatter = _node(tree, "GeometryNodeDistributePointsOnFaces", Density=156.0, Seed=7)
    _link(tree, patch.outputs["Mesh"], scatter, "Mesh")
    radius = _node(tree, "GeometryNodeSetPointRadius", Radius=0.015)
    _link(tree, scatter.outputs["Points"], radius, "Points")
    return radius.outputs["Points"]


def build(out: Path, shape: str, light_radius: float, sun_angle: float | None = None,
          size: tuple[int, int] = (200, 150)) -> None:
    import bpy
    import bmesh  # after bpy, which makes it importable

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.cycles_curves.shape = shape
    ground = bpy.data.objects.new("Ground", bpy.data.meshes.new("Ground"))
    ground.data.from_pydata([(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(ground)
    head = bpy.data.objects.new("Head", bpy.data.meshes.new("Head"))
    made = bmesh.new()
    bmesh.ops.create_uvsphere(made, u_segments=32, v_segments=16, radius=0.12)
    made.to_mesh(head.data)
    made.free()
    head.location = (0.0, 0.0, 1.62)
    scene.collection.objects.link(head)
    shoulders = _mesh("Shoulders", 1.0, (0.0, 0.0, 1.3))
    shoulders.scale = (0.46, 0.22, 0.24)
    hair = bpy.data.objects.new("Hair", bpy.data.hair_curves.new("Hair"))
    scene.collection.objects.link(hair)
    _with_nodes(hair, _geometry_nodes("groom", _hair(head)))
    pebbles = _mesh("Pebbles", 0.1, (0.2, 0.3, 0.05))
    _with_nodes(pebbles, _geometry_nodes("pebble bed", _pebbles))
    seeds = _mesh("Seeds", 0.1, (-0.6, -0.9, 0.02))
    _with_nodes(seeds, _geometry_nodes("seed scatter", _seeds))

    if sun_angle is None:
        light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
        light.data.energy = 1000.0
        light.data.shadow_soft_size = light_radius
    else:
        import math

        light = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
        light.data.energy = 4.0
        light.data.angle = math.radians(sun_angle)
        light.rotation_euler = (0.5, 0.2, 0.3)
    light.location = (0.35, -0.55, 2.6)
    scene.collection.objects.link(light)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, -2.6, 1.9)
    camera.rotation_euler = (1.35, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    bpy.ops.wm.save_as_mainfile(filepath=str(out))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--shape", choices=("RIBBONS", "THICK"), default="RIBBONS")
    parser.add_argument("--light-radius", type=float, default=0.0)
    parser.add_argument("--sun-angle", type=float, default=None, help="a sun this many degrees across")
    parser.add_argument("--size", type=int, nargs=2, default=(200, 150), metavar=("W", "H"))
    args = parser.parse_args()
    build(args.out, args.shape, args.light_radius, args.sun_angle, tuple(args.size))
    return 0


if __name__ == "__main__":
    sys.exit(main())
