"""Builds the feature scene: an artist-style .blend with every case the shadow rule follows.

    python tests/support/feature_scene.py OUT.blend [--size WxH]

Run it in a child process (it resets bpy's data). Each case shadows its own patch of
the ground, so a test can tell which case a reading of the scene ignored:

- `no_shadow_box`: ray visibility `visible_shadow` off (seen, receives, casts nothing);
- `array_post`: an Array modifier shown only in the render (three posts in Cycles);
- `render_hidden`: `hide_render` on, shown in the viewport;
- `viewport_hidden`: hidden in the viewport, rendered;
- `excluded_box` in a view-layer-excluded collection, `render_off_box` in a collection
  with `hide_render`;
- `holdout_box` in a holdout collection, `indirect_box` in an indirect-only one;
- `props` collection instanced twice: `props_a` (a scaled empty) and `props_b`, whose
  `visible_shadow` is off; `prop_hidden` inside it has `hide_render`; `nest` instances
  a collection that holds an instancer of `props` with `visible_shadow` off, which
  Cycles ignores (only the object and the top-level instancer count);
- `tube` (a bevelled curve), `label` (extruded text), `blob` (a metaball);
- `scatter`: geometry-nodes instances; `emitter`: particle instances whose emitter is
  not rendered (`show_instancer_for_render` off);
- lights: `LampA` (point, under the scaled empty `rig`) whose blocker collection
  excludes `a_excluded`; `LampB` (hemispherical spot) whose blocker collection
  includes only a nested collection holding `pillar`, and whose receiver collection
  excludes `slab` (also a shadow catcher, which the rows name in a note); `LampC`
  (point) with `use_shadow` off;
- cameras: `Camera` (the scene camera, with a strong depth of field), `ShiftCam` (lens shift, vertical sensor fit)
  and `OrthoCam` (orthographic, shifted); the scene renders at 50 % of twice the
  asked size, with a pixel aspect of 1.2.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

# Cases whose objects block LampA, and those that must not (names of original objects).
BLOCK_A = ("array_post", "viewport_hidden", "holdout_box", "indirect_box", "tube", "label", "blob",
           "scatter", "pillar", "prop_box")
NO_BLOCK_A = ("no_shadow_box", "render_hidden", "excluded_box", "render_off_box", "a_excluded")
LIGHTS = ("LampA", "LampB", "LampC")


def _box(bpy, name: str, centre, size, collection) -> "bpy.types.Object":
    sx, sy, sz = (s / 2.0 for s in size)
    verts = [(x * sx, y * sy, z * sz) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = centre
    collection.objects.link(obj)
    return obj


def _ring(index: int, count: int = 12, radius: float = 1.7, height: float = 2.0) -> tuple[float, float, float]:
    """Spots around LampA's axis: each case's shadow lands on its own patch of ground."""
    angle = 2.0 * math.pi * index / count
    return (radius * math.cos(angle), radius * math.sin(angle), height)


def _collection(bpy, name: str, parent) -> "bpy.types.Collection":
    coll = bpy.data.collections.new(name)
    if parent is not None:
        parent.children.link(coll)
    return coll


def _scatter_nodes(bpy, obj) -> None:
    """Geometry nodes: a small cube instanced on each vertex of the object's mesh."""
    tree = bpy.data.node_groups.new("scatter_cubes", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    group_in = nodes.new("NodeGroupInput")
    group_out = nodes.new("NodeGroupOutput")
    to_points = nodes.new("GeometryNodeMeshToPoints")
    cube = nodes.new("GeometryNodeMeshCube")
    cube.inputs["Size"].default_value = (0.25, 0.25, 0.25)
    instance = nodes.new("GeometryNodeInstanceOnPoints")
    links.new(group_in.outputs[0], to_points.inputs["Mesh"])
    links.new(to_points.outputs["Points"], instance.inputs["Points"])
    links.new(cube.outputs["Mesh"], instance.inputs["Instance"])
    links.new(instance.outputs["Instances"], group_out.inputs[0])
    modifier = obj.modifiers.new("scatter", "NODES")
    modifier.node_group = tree


def build(out: Path, size: tuple[int, int]) -> None:
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.name = "features"
    root = scene.collection
    # Stored at twice the size and rendered at 50 %, with pixels 1.2 times wider than tall:
    # the camera must be read as the file has it.
    scene.render.resolution_x, scene.render.resolution_y = 2 * size[0], 2 * size[1]
    scene.render.resolution_percentage = 50
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = 1.2, 1.0

    ground = bpy.data.meshes.new("ground")
    ground.from_pydata([(-9, -9, 0), (9, -9, 0), (9, 9, 0), (-9, 9, 0)], [], [(0, 1, 2, 3)])
    root.objects.link(bpy.data.objects.new("ground", ground))

    # --- ray visibility and render flags, each on its own spot of the ring
    no_shadow = _box(bpy, "no_shadow_box", _ring(0), (1.0, 1.0, 0.6), root)
    no_shadow.visible_shadow = False
    post = _box(bpy, "array_post", _ring(1), (0.25, 0.25, 0.8), root)
    array = post.modifiers.new("array", "ARRAY")
    array.count, array.relative_offset_displace = 3, (2.0, 0.0, 0.0)
    array.show_viewport = False  # three posts in the render, one in the viewport
    subsurf = post.modifiers.new("smooth", "SUBSURF")
    subsurf.levels, subsurf.render_levels = 0, 1
    _box(bpy, "render_hidden", _ring(2), (0.7, 0.7, 0.4), root).hide_render = True
    _box(bpy, "viewport_hidden", _ring(3), (0.7, 0.7, 0.4), root).hide_viewport = True
    excluded = _collection(bpy, "excluded", root)
    _box(bpy, "excluded_box", _ring(4), (0.7, 0.7, 0.4), excluded)
    render_off = _collection(bpy, "render_off", root)
    render_off.hide_render = True
    _box(bpy, "render_off_box", _ring(5), (0.7, 0.7, 0.4), render_off)
    holdout = _collection(bpy, "holdout", root)
    _box(bpy, "holdout_box", _ring(6), (0.6, 0.6, 0.3), holdout)
    indirect = _collection(bpy, "indirect", root)
    _box(bpy, "indirect_box", _ring(7), (0.6, 0.6, 0.3), indirect)

    # --- curve, text, metaball
    curve = bpy.data.curves.new("tube", "CURVE")
    curve.dimensions, curve.bevel_depth, curve.bevel_resolution = "3D", 0.12, 2
    spline = curve.splines.new("BEZIER")
    spline.bezier_points.add(1)
    for point, co in zip(spline.bezier_points, ((-0.5, 0.0, 0.0), (0.5, 0.2, 0.0))):
        point.co = co
        point.handle_left_type = point.handle_right_type = "AUTO"
    tube = bpy.data.objects.new("tube", curve)
    tube.location = _ring(8)
    root.objects.link(tube)
    text = bpy.data.curves.new("label", "FONT")
    text.body, text.size, text.extrude = "OW", 0.6, 0.05
    label = bpy.data.objects.new("label", text)
    label.location = _ring(9)
    root.objects.link(label)
    meta = bpy.data.metaballs.new("blob")
    meta.resolution = meta.render_resolution = 0.1
    element = meta.elements.new()
    element.radius = 0.4
    blob = bpy.data.objects.new("blob", meta)
    blob.location = _ring(10)
    root.objects.link(blob)

    # --- instances: a collection instanced twice, geometry nodes, particles
    props = _collection(bpy, "props", None)  # only reached through its instancers
    _box(bpy, "prop_box", (0.0, 0.0, 0.0), (0.4, 0.4, 0.3), props)
    _box(bpy, "prop_hidden", (0.6, 0.0, 0.0), (0.4, 0.4, 0.3), props).hide_render = True
    for name, spot, scale, casts in (("props_a", _ring(11), 1.5, True), ("props_b", (-3.6, -1.0, 1.6), 1.0, False)):
        empty = bpy.data.objects.new(name, None)
        empty.instance_type, empty.instance_collection = "COLLECTION", props
        empty.location, empty.scale = spot, (scale, scale, scale)
        empty.visible_shadow = casts
        root.objects.link(empty)
    # A nested instance: `nest` instances `outer`, which holds an instancer of `props` whose
    # visible_shadow is off. Cycles reads only the object and the top-level instancer.
    outer = _collection(bpy, "outer", None)
    middle = bpy.data.objects.new("middle", None)
    middle.instance_type, middle.instance_collection = "COLLECTION", props
    middle.visible_shadow = False
    outer.objects.link(middle)
    nest = bpy.data.objects.new("nest", None)
    nest.instance_type, nest.instance_collection = "COLLECTION", outer
    nest.location = (-0.6, -2.4, 2.3)
    root.objects.link(nest)
    line = bpy.data.meshes.new("scatter")
    line.from_pydata([(0.0, 0.0, 0.0), (0.5, 0.3, 0.0), (1.0, 0.0, 0.0)], [], [])
    scatter = bpy.data.objects.new("scatter", line)
    scatter.location = (2.6, -2.6, 1.8)
    root.objects.link(scatter)
    _scatter_nodes(bpy, scatter)
    sprite = _box(bpy, "sprite", (0.0, 0.0, -30.0), (0.15, 0.15, 0.15), root)  # far below, never in view
    sprite.hide_render = True  # only its particle copies are rendered
    emitter_mesh = bpy.data.meshes.new("emitter")
    emitter_mesh.from_pydata([(-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0)], [], [(0, 1, 2, 3)])
    emitter = bpy.data.objects.new("emitter", emitter_mesh)
    emitter.location = (-2.4, 2.8, 2.2)
    emitter.show_instancer_for_render = False
    root.objects.link(emitter)
    emitter.modifiers.new("particles", "PARTICLE_SYSTEM")
    particles = emitter.particle_systems[0].settings
    particles.type, particles.count, particles.hair_length = "HAIR", 12, 0.3
    particles.render_type, particles.instance_object = "OBJECT", sprite
    particles.particle_size = 1.0
    particles.use_rotation_instance = False

    # --- lights: LampA under a scaled empty, LampB linked, LampC without shadows
    rig = bpy.data.objects.new("rig", None)
    rig.location, rig.scale = (0.0, 0.0, 2.0), (2.0, 2.0, 2.0)
    root.objects.link(rig)
    lamp_a = bpy.data.objects.new("LampA", bpy.data.lights.new("LampA", "POINT"))
    lamp_a.parent, lamp_a.location = rig, (0.0, 0.0, 1.0)  # world (0, 0, 4)
    lamp_b = bpy.data.objects.new("LampB", bpy.data.lights.new("LampB", "SPOT"))
    lamp_b.data.spot_size, lamp_b.data.spot_blend = math.pi, 0.0
    lamp_b.location = (3.0, 2.5, 4.5)
    lamp_c = bpy.data.objects.new("LampC", bpy.data.lights.new("LampC", "POINT"))
    lamp_c.location = (-2.0, -1.0, 3.5)
    lamp_c.data.use_shadow = False
    for lamp in (lamp_a, lamp_b, lamp_c):
        lamp.data.energy, lamp.data.shadow_soft_size = 800.0, 0.0
        root.objects.link(lamp)
    a_excluded = _box(bpy, "a_excluded", (1.2, 2.4, 2.2), (0.8, 0.5, 0.3), root)
    pillar = _box(bpy, "pillar", (3.3, 0.6, 1.4), (0.4, 0.4, 2.8), root)
    slab = _box(bpy, "slab", (1.0, -3.2, 0.05), (1.6, 1.2, 0.1), root)
    slab.is_shadow_catcher = True  # the rule cannot follow it: the capture renders it plain, with a note

    a_blockers = _collection(bpy, "LampA blockers", None)
    a_blockers.objects.link(a_excluded)
    a_blockers.collection_objects[0].light_linking.link_state = "EXCLUDE"
    lamp_a.light_linking.blocker_collection = a_blockers
    b_blockers = _collection(bpy, "LampB blockers", None)
    b_inner = _collection(bpy, "LampB pillars", b_blockers)  # nested: the entry's state reaches inside
    b_inner.objects.link(pillar)
    b_blockers.collection_children[0].light_linking.link_state = "INCLUDE"
    lamp_b.light_linking.blocker_collection = b_blockers
    b_receivers = _collection(bpy, "LampB receivers", None)
    b_receivers.objects.link(slab)
    b_receivers.collection_objects[0].light_linking.link_state = "EXCLUDE"
    lamp_b.light_linking.receiver_collection = b_receivers

    # --- cameras
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, -7.5, 7.5)
    camera.rotation_euler = (math.radians(42.0), 0.0, 0.0)
    camera.data.lens = 24.0
    camera.data.dof.use_dof, camera.data.dof.focus_distance, camera.data.dof.aperture_fstop = True, 3.0, 0.2
    root.objects.link(camera)
    scene.camera = camera
    shift = bpy.data.objects.new("ShiftCam", bpy.data.cameras.new("ShiftCam"))
    shift.location = (1.5, -7.0, 7.0)
    shift.rotation_euler = (math.radians(40.0), 0.0, math.radians(8.0))
    shift.data.lens, shift.data.sensor_fit = 24.0, "VERTICAL"
    shift.data.shift_x, shift.data.shift_y = 0.12, -0.08
    root.objects.link(shift)
    ortho = bpy.data.objects.new("OrthoCam", bpy.data.cameras.new("OrthoCam"))
    ortho.location = (0.0, -8.0, 9.0)
    ortho.rotation_euler = (math.radians(40.0), 0.0, 0.0)
    ortho.data.type, ortho.data.ortho_scale = "ORTHO", 11.0
    ortho.data.shift_y = 0.05
    root.objects.link(ortho)

    # View-layer flags last: the layer collections exist once the collections are linked.
    layer = scene.view_layers[0]
    children = layer.layer_collection.children
    children["excluded"].exclude = True
    children["holdout"].holdout = True
    children["indirect"].indirect_only = True
    bpy.ops.wm.save_as_mainfile(filepath=str(out))


def main(argv: list[str]) -> int:
    out = Path(argv[0])
    size = (160, 120)
    if "--size" in argv:
        width, height = argv[argv.index("--size") + 1].lower().split("x")
        size = (int(width), int(height))
    build(out, size)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
