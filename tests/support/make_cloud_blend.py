"""Clouds made as artists make them, beside or around a figure (issue 43, grid media):

    python tests/support/make_cloud_blend.py OUT.blend [--variant NAME] [--reference OUT.npz]

- make_fog_blend.py's `stage`: `Ground` (a 6 m plane) and `Figure` (a 0.4 x 0.4 x 1.2 m
  box standing on it), a hard point light `Lamp` above, a camera looking down at the
  ground, 128 x 96 pixels;
- by `--variant`:
  - `mesh_to_volume` (the default): `Cloud`, a Volume object whose Mesh to Volume
    modifier fills `Puff` (an icosphere of radius 0.6, hidden from renders) with density
    (interior 1, ramping in over its interior band), a `Vapour` Principled Volume of
    density 2, beside the figure;
  - `noise`: `Noise Cloud`, a mesh object whose geometry nodes make a Volume Cube whose
    density is a Noise Texture of the position (a heterogeneous cloud, 0 to about 3),
    `Vapour` set on it by a Set Material node;
  - `vdb`: `VDB Cloud`, a Volume object that loads a saved OpenVDB file (`cloud.vdb`
    beside the .blend, written by a geometry-nodes Bake node from a Volume Cube of noise
    density, as a simulation or another program leaves one), turned and moved by its
    object transform, with `Vapour`;
  - `inside`: `Haze`, a Volume object whose geometry nodes make a Volume Cube around the
    figure reaching below the ground, its density falling with height and varying with a
    noise texture; no material (Cycles' default volume shader). The figure and the ground
    stand inside it.

`build` makes the scene in the running Blender; `--reference` also captures the OmniWarp
reference of the scene (reference/capture.py) into a .npz (ReferenceData), with
`--soft-samples` samples a pixel (two halves); `--check OUT.npz` reads the cloud's grid
(render_geometry.render_triangles) and writes what test_cloud_reference.py checks it
against: Sample Grid's own trilinear values at random world points (a probe object whose
geometry nodes take the cloud in its relative space), the cloud's world bounding box,
the datablock counts before and after, and the grid read again at a small budget.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from tests.support.make_fog_blend import stage, variant_main  # noqa: E402

CLOUD_CENTRE, CLOUD_RADIUS = np.array([0.0, 0.0, 1.2]), 0.6
VARIANTS = ("mesh_to_volume", "noise", "vdb", "inside")
# The `inside` haze's box (min, max) and the `noise` cloud's.
HAZE_BOX = ((0.3, -0.6, -0.3), (1.9, 1.0, 1.5))
NOISE_BOX = ((-0.7, -0.7, 0.6), (0.7, 0.7, 1.8))
# The saved cloud's box in its file, and the Volume object's transform on top of it.
VDB_BOX, VDB_TURN, VDB_AT = ((-0.6, -0.5, -0.35), (0.6, 0.5, 0.35)), 30.0, (0.1, 0.2, 1.3)


def vapour():
    """A white-ish Principled Volume of density 2 (its grid times 2)."""
    import bpy

    from addon.compat import blender as blender_compat

    material = bpy.data.materials.new("Vapour")
    tree = blender_compat.ensure_node_tree(material)
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    node.inputs["Density"].default_value = 2.0
    node.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    tree.links.new(node.outputs[0], output.inputs["Volume"])
    return material


def _mesh_to_volume(scene):
    import bpy

    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=CLOUD_RADIUS, location=tuple(CLOUD_CENTRE))
    puff = bpy.context.active_object
    puff.name = "Puff"
    puff.hide_render = True
    cloud = bpy.data.objects.new("Cloud", bpy.data.volumes.new("Cloud"))
    scene.collection.objects.link(cloud)
    modifier = cloud.modifiers.new("Mesh to Volume", "MESH_TO_VOLUME")
    modifier.object = puff
    modifier.resolution_mode = "VOXEL_SIZE"
    modifier.voxel_size = 0.04
    modifier.interior_band_width = 0.15
    cloud.data.materials.append(vapour())
    return cloud


def _volume_cube_nodes(name: str, box, density) -> object:
    """A node group: a Volume Cube over `box` whose density is `density(tree)` (a socket)."""
    import bpy

    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    out = tree.nodes.new("NodeGroupOutput")
    cube = tree.nodes.new("GeometryNodeVolumeCube")
    cube.inputs["Min"].default_value, cube.inputs["Max"].default_value = box
    for axis, size in zip("XYZ", np.subtract(box[1], box[0])):
        cube.inputs[f"Resolution {axis}"].default_value = int(round(size / 0.05))
    tree.links.new(density(tree), cube.inputs["Density"])
    tree.links.new(cube.outputs[0], out.inputs[0])
    return tree, cube, out


def _math(tree, operation: str, a, b):
    node = tree.nodes.new("ShaderNodeMath")
    node.operation = operation
    for socket, value in zip(node.inputs[:2], (a, b)):
        if isinstance(value, float):
            socket.default_value = value
        else:
            tree.links.new(value, socket)
    return node.outputs[0]


def _noise(tree, scale: float):
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = scale
    return noise.outputs["Fac"]


def _noise_cloud(scene):
    import bpy

    # density = max(noise - 0.35, 0) * 8: patches of cloud and clear air
    tree, cube, out = _volume_cube_nodes(
        "noise cloud", NOISE_BOX,
        lambda t: _math(t, "MULTIPLY", _math(t, "MAXIMUM", _math(t, "SUBTRACT", _noise(t, 2.5), 0.35), 0.0), 8.0))
    material = tree.nodes.new("GeometryNodeSetMaterial")
    material.inputs["Material"].default_value = vapour()
    tree.links.new(cube.outputs[0], material.inputs["Geometry"])
    tree.links.new(material.outputs[0], out.inputs[0])
    obj = bpy.data.objects.new("Noise Cloud", bpy.data.meshes.new("Noise Cloud"))
    scene.collection.objects.link(obj)
    obj.modifiers.new("cloud", "NODES").node_group = tree
    return obj


def _haze(scene):
    import bpy

    def density(t):
        z = t.nodes.new("ShaderNodeSeparateXYZ")
        t.links.new(t.nodes.new("GeometryNodeInputPosition").outputs[0], z.inputs[0])
        # (1.6 - z) * 0.4 * (0.5 + noise): thicker low down, patchy
        fall = _math(t, "MULTIPLY", _math(t, "SUBTRACT", 1.6, z.outputs["Z"]), 0.4)
        return _math(t, "MULTIPLY", fall, _math(t, "ADD", _noise(t, 3.0), 0.5))

    tree, _, _ = _volume_cube_nodes("haze", HAZE_BOX, density)
    obj = bpy.data.objects.new("Haze", bpy.data.volumes.new("Haze"))
    scene.collection.objects.link(obj)
    obj.modifiers.new("haze", "NODES").node_group = tree
    return obj


def _vdb_cloud(scene, folder: Path):
    """Bake a Volume Cube of noise density to `folder`/cloud.vdb (the baking object is
    removed afterwards), then a Volume object that loads the file."""
    import shutil

    import bpy

    tree, cube, out = _volume_cube_nodes(
        "saved cloud", VDB_BOX,
        lambda t: _math(t, "MULTIPLY", _math(t, "MAXIMUM", _math(t, "SUBTRACT", _noise(t, 1.8), 0.4), 0.0), 10.0))
    bake = tree.nodes.new("GeometryNodeBake")
    if not len(bake.bake_items):
        bake.bake_items.new("GEOMETRY", "Geometry")
    tree.links.new(cube.outputs[0], bake.inputs[0])
    tree.links.new(bake.outputs[0], out.inputs[0])
    baker = bpy.data.objects.new("Baker", bpy.data.meshes.new("Baker"))
    scene.collection.objects.link(baker)
    modifier = baker.modifiers.new("bake", "NODES")
    modifier.node_group = tree
    modifier.bake_directory = str(folder / "cloud_bake")
    if hasattr(modifier, "bake_target"):  # 4.3+; 4.2 bakes to disk
        modifier.bake_target = "DISK"
    item = modifier.bakes[0]
    if hasattr(item, "bake_mode"):
        item.bake_mode = "STILL"
    bpy.context.view_layer.objects.active = baker
    if not bpy.data.filepath:  # 4.2 bakes a saved file only
        bpy.ops.wm.save_as_mainfile(filepath=str(folder / "baking.blend"))
        (folder / "baking.blend").unlink()
    bpy.ops.object.geometry_node_bake_single(session_uid=baker.session_uid, modifier_name=modifier.name,
                                             bake_id=item.bake_id)
    found = sorted((folder / "cloud_bake").rglob("*.vdb"))
    if len(found) != 1:
        raise RuntimeError(f"the Bake node wrote {len(found)} .vdb files, not 1")
    saved = folder / "cloud.vdb"
    shutil.copyfile(found[0], saved)
    shutil.rmtree(folder / "cloud_bake")
    mesh = baker.data
    bpy.data.objects.remove(baker)
    bpy.data.meshes.remove(mesh)
    bpy.data.node_groups.remove(tree)
    volume = bpy.data.volumes.new("VDB Cloud")
    volume.filepath = str(saved)
    cloud = bpy.data.objects.new("VDB Cloud", volume)
    cloud.location, cloud.rotation_euler = VDB_AT, (0.0, 0.0, math.radians(VDB_TURN))
    scene.collection.objects.link(cloud)
    volume.materials.append(vapour())
    return cloud


_CLOUDS = {"mesh_to_volume": _mesh_to_volume, "noise": _noise_cloud, "vdb": _vdb_cloud, "inside": _haze}


def build(variant: str = "mesh_to_volume", folder: Path | None = None):
    """The scene in the running Blender (an empty file first); returns (scene, light, cloud).
    `folder`: where the `vdb` variant saves its OpenVDB file (the current directory if None)."""
    scene, light = stage("cloud")
    cloud = _vdb_cloud(scene, Path(folder or ".").resolve()) if variant == "vdb" else _CLOUDS[variant](scene)
    return scene, light, cloud


def _sample_grid(cloud, points: np.ndarray, grid: str = "density") -> np.ndarray:
    """Sample Grid's trilinear value of the cloud's grid at world points, through a probe
    object at the origin (Object Info in relative space: world coordinates)."""
    import bpy

    tree = bpy.data.node_groups.new("probe", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes = tree.nodes
    info, named, sample = (nodes.new(n) for n in ("GeometryNodeObjectInfo", "GeometryNodeGetNamedGrid",
                                                   "GeometryNodeSampleGrid"))
    info.transform_space = "RELATIVE"
    info.inputs["Object"].default_value = cloud
    named.inputs["Name"].default_value = grid
    sample.inputs["Interpolation"].default_value = "Trilinear"
    store = nodes.new("GeometryNodeStoreNamedAttribute")
    store.inputs["Name"].default_value = "probe"
    tree.links.new(info.outputs["Geometry"], named.inputs["Volume"])
    tree.links.new(named.outputs["Grid"], sample.inputs["Grid"])
    tree.links.new(nodes.new("GeometryNodeInputPosition").outputs[0], sample.inputs["Position"])
    tree.links.new(nodes.new("NodeGroupInput").outputs[0], store.inputs["Geometry"])
    tree.links.new(sample.outputs["Value"], store.inputs["Value"])
    tree.links.new(store.outputs[0], nodes.new("NodeGroupOutput").inputs[0])
    mesh = bpy.data.meshes.new("probe")
    mesh.vertices.add(len(points))
    mesh.vertices.foreach_set("co", points.astype(np.float32).ravel())
    probe = bpy.data.objects.new("probe", mesh)
    probe.modifiers.new("probe", "NODES").node_group = tree
    bpy.context.scene.collection.objects.link(probe)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    attribute = probe.evaluated_get(depsgraph).data.attributes["probe"]
    values = np.empty(len(points), dtype=np.float32)
    attribute.data.foreach_get("value", values)
    bpy.data.objects.remove(probe)
    bpy.data.meshes.remove(mesh)
    bpy.data.node_groups.remove(tree)
    return values


def check(variant: str, out: Path) -> None:
    """What test_cloud_reference.py checks the grid read against (module docstring)."""
    import bpy

    from addon.readers import volume_grids
    from addon.readers.render_geometry import render_pass, render_triangles

    scene, _, cloud = build(variant, out.parent)
    layer = scene.view_layers[0]
    counts = lambda: [len(getattr(bpy.data, k)) for k in ("objects", "meshes", "node_groups", "materials")]  # noqa: E731
    before = counts()
    found = render_triangles(scene, layer)
    after = counts()
    (medium,) = [grid for _, grid in found.grids]
    small = volume_grids.read(scene, found.volumes, lambda fn: render_pass(scene, layer, fn), budget=16 ** 3)[0]
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = cloud.evaluated_get(depsgraph)
    # The cloud's bounding box, world (a mesh's geometry-nodes volume: the volume's own).
    volume = next(i.object for i in depsgraph.object_instances
                  if i.object.type == "VOLUME" and i.object.original == cloud)
    corners = np.array(volume.bound_box, dtype=np.float64) @ np.array(evaluated.matrix_world)[:3, :3].T \
        + np.array(evaluated.matrix_world)[:3, 3]
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    rng = np.random.default_rng(7)
    margin = 2.0 * medium.voxel_size()
    points = rng.uniform(lo - margin, hi + margin, size=(3000, 3))
    np.savez(out, density=medium.density, to_index=medium.to_index, sigma=medium.sigma, name=medium.name,
             small_density=small.density, small_to_index=small.to_index, points=points,
             sampled=_sample_grid(cloud, points), box=np.array([lo, hi]), before=before, after=after,
             left_out=np.array(found.left_out.notes(), dtype=str))


def main(argv: list[str] | None = None) -> int:
    return variant_main(argv, __doc__.splitlines()[0], VARIANTS, "mesh_to_volume", build, check)


if __name__ == "__main__":
    sys.exit(main())
