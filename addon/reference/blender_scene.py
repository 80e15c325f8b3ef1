"""Turn a `SceneSpec` into a new Blender scene (and remove it again).

Everything created here is tagged with the custom property `TAG` holding the scene
name, so `remove_blender_scene` deletes exactly what was built and nothing else.
"""
from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING

import numpy as np

from ..core.camera import blender_camera_settings
from ..core.light_shape import Area, Sphere, SunDisk
from ..core.errors import InputError
from ..core.scene import MeshSpec, SceneSpec

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

log = logging.getLogger(__name__)

TAG = "omniwarp_generated"


def _matrix(m: np.ndarray):
    """numpy 4x4 -> mathutils.Matrix."""
    from mathutils import Matrix

    return Matrix(np.asarray(m, dtype=np.float64).tolist())


def _unique_scene_name(base: str) -> str:
    import bpy

    name, i = base, 1
    while name in bpy.data.scenes:
        i += 1
        name = f"{base}.{i:03d}"
    return name


def build_mesh(spec: MeshSpec) -> "bpy.types.Mesh":
    """A flat-shaded Blender mesh from a MeshSpec (object space), filled with foreach_set."""
    import bpy

    verts = np.ascontiguousarray(spec.vertices, dtype=np.float32).reshape(-1, 3)
    tris = np.ascontiguousarray(spec.triangles, dtype=np.int32).reshape(-1, 3)
    if not np.all(np.isfinite(verts)):
        raise InputError(f"mesh {spec.name!r} has non-finite vertices")
    mesh = bpy.data.meshes.new(spec.name)
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", verts.ravel())
    mesh.loops.add(tris.size)
    mesh.loops.foreach_set("vertex_index", tris.ravel())
    mesh.polygons.add(len(tris))
    mesh.polygons.foreach_set("loop_start", np.arange(0, tris.size, 3, dtype=np.int32))
    # New faces are smooth by default since Blender 4.1; the box corners are shared,
    # so smooth shading would bend the lighting at every edge. Shade flat.
    mesh.polygons.foreach_set("use_smooth", np.zeros(len(tris), dtype=bool))
    if spec.alpha is not None and spec.uvs is not None:
        layer = mesh.uv_layers.new(name="UVMap")
        corners = np.asarray(spec.uvs, dtype=np.float32)[tris.ravel()]
        layer.data.foreach_set("uv", corners.ravel())
    mesh.update(calc_edges=True)
    if mesh.validate(verbose=False):
        # validate() returns True when it had to fix something (e.g. degenerate faces).
        log.warning("mesh %r had invalid geometry that Blender corrected", spec.name)
    return mesh


_INTERPOLATION = {"closest": "Closest", "linear": "Linear"}


def build_material(spec: MeshSpec, tag: str) -> "bpy.types.Material":
    """The see-through material of a MeshSpec, as an artist builds one: a white Principled
    BSDF whose Alpha comes from an image texture's alpha (a float image, so the values are
    the map's own), or a constant Alpha for a 1 x 1 map. A map's transfer is baked into the
    image: the Blender side needs no math nodes to reproduce it."""
    import bpy

    from ..compat import blender as blender_compat

    amap = spec.alpha
    mat = bpy.data.materials.new(amap.name)
    mat[TAG] = tag
    blender_compat.set_see_through(mat)
    tree = blender_compat.ensure_node_tree(mat)
    principled = next(node for node in tree.nodes if node.type == "BSDF_PRINCIPLED")
    principled.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    values = amap.values().reshape(amap.image.shape).astype(np.float32)  # the transfer applied
    if values.size == 1:
        principled.inputs["Alpha"].default_value = float(values[0, 0])
        return mat
    height, width = values.shape
    image = bpy.data.images.new(amap.name, width, height, alpha=True, float_buffer=True)
    image[TAG] = tag
    image.colorspace_settings.name = "Non-Color"
    image.alpha_mode = "STRAIGHT"
    rgba = np.ones((height, width, 4), dtype=np.float32)
    rgba[..., 3] = values
    image.pixels.foreach_set(rgba.ravel())
    image.pack()  # saved with the file, as an artist's packed texture
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    texture.interpolation = _INTERPOLATION[amap.interpolation]
    texture.extension = amap.extension.upper()
    tree.links.new(texture.outputs["Alpha"], principled.inputs["Alpha"])
    return mat


def _check_light(spec: SceneSpec) -> None:
    """Refuse a light Blender cannot hold as specified, before anything is created."""
    import bpy

    light_spec = spec.light
    if light_spec.emission not in ("omni", "hemi", "spot", "sun"):
        raise InputError(f"scene {spec.name!r}: unknown light emission {light_spec.emission!r}")
    if light_spec.emission == "spot":
        # RNA clamps spot_size silently (at least 1 degree); a clamped cone would light
        # another domain than the spec (and the pipeline) describes.
        rna = bpy.types.SpotLight.bl_rna.properties["spot_size"]
        if not rna.hard_min - 1e-7 <= float(light_spec.spot_size) <= rna.hard_max + 1e-7:  # float32 RNA
            raise InputError(
                f"scene {spec.name!r}: spot cone {math.degrees(light_spec.spot_size):.4g} degrees is outside "
                f"Blender's range [{math.degrees(rna.hard_min):.4g}, {math.degrees(rna.hard_max):.4g}]"
            )


def build_blender_scene(spec: SceneSpec) -> "bpy.types.Scene":
    """Create a NEW scene holding the spec's meshes, light and camera; other scenes are untouched."""
    import bpy

    _check_light(spec)
    scene = bpy.data.scenes.new(_unique_scene_name(f"OmniWarp {spec.name}"))
    scene[TAG] = scene.name
    collection = scene.collection

    def link(obj: "bpy.types.Object") -> None:
        obj[TAG] = scene.name
        if obj.data is not None:
            obj.data[TAG] = scene.name
        collection.objects.link(obj)

    materials: dict[str, "bpy.types.Material"] = {}  # alpha digest -> its material, shared as artists do
    for mesh_spec in spec.meshes:
        obj = bpy.data.objects.new(mesh_spec.name, build_mesh(mesh_spec))
        obj.matrix_world = _matrix(mesh_spec.matrix_world)
        if mesh_spec.alpha is not None:
            digest = mesh_spec.alpha.digest
            if digest not in materials:
                materials[digest] = build_material(mesh_spec, scene.name)
            obj.data.materials.append(materials[digest])
        link(obj)

    light_spec = spec.light
    shape = light_spec.shape
    if isinstance(shape, Area):  # one-sided: the hemispherical emission with a size
        light = bpy.data.lights.new(f"{spec.name}_light", "AREA")
        light.shape = "RECTANGLE" if shape.outline == "rectangle" else "ELLIPSE"
        light.size, light.size_y = float(shape.size_x), float(shape.size_y)
        if hasattr(light, "spread"):
            light.spread = float(shape.spread)
    elif light_spec.emission == "omni":
        light = bpy.data.lights.new(f"{spec.name}_light", "POINT")
    elif light_spec.emission == "hemi":
        light = bpy.data.lights.new(f"{spec.name}_light", "SPOT")
        light.spot_size = math.pi  # 180 degree cone: the half space in front of local -Z
        light.spot_blend = float(light_spec.spot_blend)
    elif light_spec.emission == "spot":
        light = bpy.data.lights.new(f"{spec.name}_light", "SPOT")
        light.spot_size = float(light_spec.spot_size)  # full cone angle, radians
        light.spot_blend = float(light_spec.spot_blend)  # 0 (a hard edge) unless the spec fades it
    elif light_spec.emission == "sun":
        light = bpy.data.lights.new(f"{spec.name}_light", "SUN")
        # The spec's disk, or a hard sun (Blender's default 0.526 degrees gives penumbrae).
        light.angle = float(shape.angle) if isinstance(shape, SunDisk) else 0.0
    else:
        raise InputError(f"scene {spec.name!r}: unknown light emission {light_spec.emission!r}")
    light.energy = float(light_spec.energy)  # W, or W/m^2 (strength) for a sun
    if light.type != "AREA":
        # The spec's sphere, or a hard point light, as the shadow maps assume.
        light.shadow_soft_size = float(shape.radius) if isinstance(shape, Sphere) else 0.0
    light_obj = bpy.data.objects.new(f"{spec.name}_light", light)
    light_obj.matrix_world = _matrix(light_spec.matrix_world)
    link(light_obj)

    cam_spec = spec.camera
    camera = bpy.data.cameras.new(f"{spec.name}_camera")
    aspect = (1.0, 1.0)
    if cam_spec.window is None:
        camera.type = "PERSP"
        camera.sensor_fit = "AUTO"  # the angle spans the larger image side, like CameraSpec
        camera.angle = math.radians(cam_spec.fov_deg)
    else:
        # A windowed camera (shift, pixel aspect, orthographic): the settings that give it.
        settings = blender_camera_settings(cam_spec)
        for key in ("type", "sensor_fit", "sensor_width", "shift_x", "shift_y", "lens", "ortho_scale"):
            if key in settings:
                setattr(camera, key, settings[key])
        aspect = (float(settings["pixel_aspect_x"]), float(settings["pixel_aspect_y"]))
    camera.clip_start = float(cam_spec.clip_start)
    camera.clip_end = float(cam_spec.clip_end)
    cam_obj = bpy.data.objects.new(f"{spec.name}_camera", camera)
    cam_obj.matrix_world = _matrix(cam_spec.matrix_world)
    link(cam_obj)
    scene.camera = cam_obj

    width, height = cam_spec.resolution
    scene.render.resolution_x = int(width)
    scene.render.resolution_y = int(height)
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = aspect
    log.debug("built scene %r: %d meshes, %s light", scene.name, len(spec.meshes), light_spec.emission)
    return scene


def remove_blender_scene(scene: "bpy.types.Scene") -> None:
    """Delete a scene made by `build_blender_scene` and the datablocks it created.

    Only IDs carrying our tag for this scene are removed, so user data linked into
    the scene afterwards survives (it just loses the scene).
    """
    import bpy

    name = scene.get(TAG)
    if name is None:
        raise InputError(f"scene {scene.name!r} was not built by OmniWarp; refusing to remove it")
    objects = [o for o in scene.collection.all_objects if o.get(TAG) == name]
    data = [o.data for o in objects if o.data is not None and o.data.get(TAG) == name]
    materials = [m for m in bpy.data.materials if m.get(TAG) == name]
    images = [i for i in bpy.data.images if i.get(TAG) == name]
    bpy.data.scenes.remove(scene)
    for obj in objects:
        bpy.data.objects.remove(obj)
    for datablock in data:
        if datablock.users:
            log.debug("keeping %r: still used elsewhere", datablock.name)
            continue
        if isinstance(datablock, bpy.types.Mesh):
            bpy.data.meshes.remove(datablock)
        elif isinstance(datablock, bpy.types.Light):
            bpy.data.lights.remove(datablock)
        elif isinstance(datablock, bpy.types.Camera):
            bpy.data.cameras.remove(datablock)
    for material in materials:
        if not material.users:
            bpy.data.materials.remove(material)
    for image in images:
        if not image.users:
            bpy.data.images.remove(image)
