"""The materials the reference renders with: white diffuse, keeping the file's alpha.

The reference measures visibility, so every surface renders as a white Lambert that
also writes its geometric normal to an AOV. A scene without see-through materials gets
that as the view layer's material override, as before. A scene with them cannot: the
override would remove the alpha that Cycles' shadow rays see. Then every material slot
of the rendered objects gets a white copy instead, and a see-through material's copy
keeps its own node graph in front of the white:

    surface = Mix(fac, Transparent, white diffuse)
    fac     = alpha for shadow (and every other) rays; alpha >= 1/2 ? 1 : 0 for camera rays

so Cycles lets shadow rays through with weight 1 - alpha, evaluating the file's own
graph (images, math, even procedural textures), while the camera sees each surface as
opaque or absent, as the position pass (pass_alpha_threshold 0.5) and OmniWarp's view
samples take it. The alpha is read from the shader that reaches the Material Output:
a Principled BSDF's Alpha, Transparent BSDFs (alpha 0), and Mix Shaders of them,
(1 - f) alpha_A + f alpha_B; any other shader is opaque.

Volumes keep their shaders: a material with a Volume output gets a copy that
keeps the volume graph (density, absorption and scattering as the file has them) and the
white for its surface if it has one. The reference measures the light that reaches
surfaces, and a camera ray that crosses a medium may end in it (measured in the
notebook, 2026-12-volumes.md), so the copy's volume acts on shadow rays alone:

    volume = Mix(Is Shadow Ray, nothing, the file's volume)

Camera rays still cross the medium's faces, so a receiver inside it (a figure standing
in fog) has the medium in its volume stack and its shadow ray is attenuated from the
receiver on; a homogeneous medium stays exact at one sample (exp(-sigma L) to 1e-6).
Hiding the medium from camera rays instead (`visible_camera` off, the first version)
left such receivers unshadowed (errors up to 0.8). Volume objects (OpenVDB grids) are
guarded the same way and stay seen by camera rays (grid media), so a receiver
inside a cloud is shadowed by it from itself on; one without a material gets a guarded
copy of Cycles' default volume shader (a Principled Volume of default inputs), and a
material that geometry nodes set on a volume (Set Material), in no object's slots, is
swapped for its guarded copy by `ID.user_remap` for the capture. This holds on every
line: where Blender cannot read grids (`blender_compat.grid_nodes_available`, 4.x) the
methods draw no Volume object, but the reference is still Cycles' (hiding them from camera
rays there would leave receivers inside them unshadowed).
"""
from __future__ import annotations

import logging
from typing import Any

from ..compat import blender as blender_compat
from ..readers.material_nodes import is_medium, linked_from, see_through, surface_output, volume_source

log = logging.getLogger(__name__)

AOV_NORMAL = "OmniWarpTrueNormal"  # the geometric normal, written by every reference material
# Alpha at or above which a camera ray stops at the surface (Cycles' pass_alpha_threshold).
CAMERA_ALPHA = 0.5


def white_material(overrides, name: str = "OmniWarp reference white"):
    """White diffuse material that also writes the geometric normal to the AOV."""
    import bpy

    mat = bpy.data.materials.new(name)
    overrides.on_restore(lambda: bpy.data.materials.remove(mat))
    tree = blender_compat.ensure_node_tree(mat)
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.target = "ALL"
    tree.links.new(_white_diffuse(tree), out.inputs["Surface"])
    _normal_aov(tree)
    return mat


def _white_diffuse(tree) -> Any:
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0  # Lambert
    return diffuse.outputs["BSDF"]


def _normal_aov(tree) -> None:
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    aov = tree.nodes.new("ShaderNodeOutputAOV")
    aov.aov_name = AOV_NORMAL
    tree.links.new(geometry.outputs["True Normal"], aov.inputs["Color"])


class _Expression:
    """Builds the alpha as math nodes in a tree, folding constants (a float or a socket)."""

    def __init__(self, tree) -> None:
        self.tree = tree

    def math(self, operation: str, a, b):
        if isinstance(a, float) and isinstance(b, float):
            return {"MULTIPLY": a * b, "ADD": a + b, "SUBTRACT": a - b, "GREATER_THAN": float(a > b)}[operation]
        node = self.tree.nodes.new("ShaderNodeMath")
        node.operation = operation
        for slot, value in zip(node.inputs[:2], (a, b)):
            if isinstance(value, float):
                slot.default_value = value
            else:
                self.tree.links.new(value, slot)
        return node.outputs[0]

    def value_of(self, socket):
        """A float input's value: its link or its default."""
        source = linked_from(socket)
        return source if source is not None else float(socket.default_value)

    def alpha(self, shader_output, depth: int = 0):
        """The alpha of the shader behind an output socket; None when it is opaque."""
        node = shader_output.node
        if depth > 16:
            return None
        if node.type == "BSDF_PRINCIPLED":
            value = self.value_of(node.inputs["Alpha"])
            return None if value == 1.0 else value
        if node.type == "BSDF_TRANSPARENT":
            return 0.0
        if node.type == "MIX_SHADER":
            fac = self.value_of(node.inputs[0])
            parts = []
            for socket in node.inputs[1:3]:
                source = linked_from(socket)
                parts.append(1.0 if source is None else self.alpha(source, depth + 1))
            if parts[0] is None and parts[1] is None:
                return None
            a, b = (1.0 if p is None else p for p in parts)
            # (1 - f) a + f b
            return self.math("ADD", self.math("MULTIPLY", self.math("SUBTRACT", 1.0, fac), a),
                             self.math("MULTIPLY", fac, b))
        return None


def media(scene, view_layer) -> list[str]:
    """The rendered objects that are media: Volume objects, and objects whose every
    material is a volume without a surface (read-only)."""
    named = {obj.name for obj in _rendered_objects(scene, view_layer) if _is_medium_object(obj)}
    return sorted(named | set(media_instances(view_layer)))


def _is_medium_object(obj) -> bool:
    materials = [slot.material for slot in obj.material_slots if slot.material is not None]
    return obj.type == "VOLUME" or (bool(materials) and all(is_medium(m) for m in materials))


def _volume_copy(material, overrides, guard: bool = True):
    """A copy of a material with a volume: its volume graph for shadow rays alone
    (`shadow_only`), the white for its surface when it has one, no surface when it has none."""
    import bpy

    copy = material.copy()
    overrides.on_restore(lambda: bpy.data.materials.remove(copy))
    tree = copy.node_tree
    output = surface_output(tree)
    surface = output.inputs["Surface"]
    if linked_from(surface) is not None:
        tree.links.new(_white_diffuse(tree), surface)
    volume = output.inputs["Volume"]
    if guard:
        tree.links.new(shadow_only(tree, linked_from(volume)), volume)
    _normal_aov(tree)
    return copy


def shadow_only(tree, volume) -> Any:
    """A volume shader that shadow rays see in full and every other ray not at all:
    Mix Shader(Is Shadow Ray, nothing, volume). Cycles still takes a homogeneous volume
    so guarded as homogeneous (exact at one sample, measured on 5.2.3)."""
    light_path = tree.nodes.new("ShaderNodeLightPath")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(light_path.outputs["Is Shadow Ray"], mix.inputs[0])
    tree.links.new(volume, mix.inputs[2])
    return mix.outputs["Shader"]


def _see_through_copy(material, overrides, guard: bool = True):
    """A copy of a see-through material: its graph, with the white in front (module docstring)."""
    import bpy

    copy = material.copy()
    overrides.on_restore(lambda: bpy.data.materials.remove(copy))
    tree = copy.node_tree
    output = surface_output(tree)
    expr = _Expression(tree)
    alpha = expr.alpha(linked_from(output.inputs["Surface"]))
    alpha = 1.0 if alpha is None else alpha
    volume = linked_from(output.inputs["Volume"]) if "Volume" in output.inputs else None
    for node in [n for n in tree.nodes if n.type in ("OUTPUT_MATERIAL", "OUTPUT_AOV")]:
        tree.nodes.remove(node)
    light_path = tree.nodes.new("ShaderNodeLightPath")
    opaque_for_camera = expr.math("GREATER_THAN", alpha, CAMERA_ALPHA - 1e-6)  # alpha >= 1/2
    fac = expr.math("ADD", alpha, expr.math("MULTIPLY", light_path.outputs["Is Camera Ray"],
                                            expr.math("SUBTRACT", opaque_for_camera, alpha)))
    mix = tree.nodes.new("ShaderNodeMixShader")
    if isinstance(fac, float):
        mix.inputs[0].default_value = fac
    else:
        tree.links.new(fac, mix.inputs[0])
    transparent = tree.nodes.new("ShaderNodeBsdfTransparent")
    transparent.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    tree.links.new(transparent.outputs["BSDF"], mix.inputs[1])
    tree.links.new(_white_diffuse(tree), mix.inputs[2])
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.target = "ALL"
    tree.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    if volume is not None:
        tree.links.new(shadow_only(tree, volume) if guard else volume, out.inputs["Volume"])
    _normal_aov(tree)
    blender_compat.set_see_through(copy)
    return copy


def apply(scene, view_layer, overrides, shadow_rays_only: bool = True) -> list[str]:
    """Give the scene its reference materials (module docstring); returns notes for the
    objects whose materials could not be replaced (linked, read-only data). With
    `shadow_rays_only` off (the EEVEE row, which renders the file's volumes as EEVEE does)
    volumes keep their graph unguarded."""
    objects = _rendered_objects(scene, view_layer)
    materials = {slot.material for obj in objects for slot in obj.material_slots if slot.material is not None}
    # Materials geometry nodes set on volumes (Set Material): in no rendered object's slots.
    node_set = _volume_instance_materials(view_layer) - materials
    materials |= node_set
    volumes = any(obj.type == "VOLUME" for obj in objects) or any(volume_source(m) is not None for m in materials)
    if not volumes and not any(see_through(m) for m in materials):
        overrides.set(view_layer, "material_override", white_material(overrides))
        return []
    white = white_material(overrides)
    copies = {m: (_see_through_copy(m, overrides, shadow_rays_only) if see_through(m)
                  else _volume_copy(m, overrides, shadow_rays_only) if volume_source(m) is not None else white)
              for m in materials}
    for material in node_set:
        _remap(material, copies[material], overrides)

    default_volume = None
    refused = []
    for obj in objects:
        try:
            if obj.type == "VOLUME" and not any(slot.material for slot in obj.material_slots):
                if default_volume is None:
                    default_volume = _default_volume(overrides, shadow_rays_only)
                for slot in obj.material_slots:  # empty slots: Cycles' default shader too
                    overrides.set(slot, "material", default_volume)
                if not obj.material_slots:
                    _append_material(obj, default_volume, overrides)
                continue
            if not obj.material_slots and obj.data is not None and hasattr(obj.data, "materials"):
                _append_material(obj, white, overrides)
            for slot in obj.material_slots:
                overrides.set(slot, "material", copies.get(slot.material, white))
        except (AttributeError, TypeError, RuntimeError) as exc:
            log.warning("object %r keeps its own materials in the reference: %s", obj.name, exc)
            refused.append(obj.name)
    log.info("reference materials: %d see-through or volume of %d", sum(c is not white for c in copies.values()),
             len(copies))
    if refused:
        return [f"objects whose materials the reference could not replace (read-only data): {', '.join(refused)}"]
    return []


def _append_material(obj, material, overrides) -> None:
    """Give an object without materials one, for the capture."""
    obj.data.materials.append(material)
    overrides.on_restore(lambda data=obj.data: data.materials.pop())


def _remap(material, copy, overrides) -> None:
    """Every user of `material` (a geometry-nodes Set Material) uses `copy` until restore."""
    material.user_remap(copy)
    overrides.on_restore(lambda: copy.user_remap(material))


def default_volume_material(name: str = "OmniWarp default volume"):
    """Cycles' default volume shader as a material: a Principled Volume of default inputs
    (what Cycles renders a Volume object without a material with, scene/shader.cpp)."""
    import bpy

    mat = bpy.data.materials.new(name)
    tree = blender_compat.ensure_node_tree(mat)
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.target = "ALL"
    tree.links.new(tree.nodes.new("ShaderNodeVolumePrincipled").outputs[0], out.inputs["Volume"])
    return mat


def _default_volume(overrides, guard: bool):
    """The default volume shader's reference copy (guarded), removed on restore."""
    import bpy

    plain = default_volume_material()
    try:
        return _volume_copy(plain, overrides, guard)
    finally:
        bpy.data.materials.remove(plain)


def _volume_instance_materials(view_layer) -> set:
    """The original materials of the volume instances of the layer's evaluated depsgraph."""
    depsgraph = getattr(view_layer, "depsgraph", None)
    found = set()
    for instance in () if depsgraph is None else depsgraph.object_instances:
        if instance.object.type == "VOLUME":
            found |= {slot.material.original for slot in instance.object.material_slots if slot.material is not None}
    return found


def media_instances(view_layer) -> list[str]:
    """The owners of the layer's volume geometry (a mesh's geometry-nodes volume too)."""
    depsgraph = getattr(view_layer, "depsgraph", None)
    return sorted({i.object.original.name for i in (() if depsgraph is None else depsgraph.object_instances)
                   if i.object.type == "VOLUME"})


_SURFACE_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"}


def _rendered_objects(scene, view_layer) -> list:
    """The original objects whose surfaces render: the scene's, and those only instanced
    (collection instances, geometry-node instances), found through the evaluated instances."""
    found: dict[str, Any] = {}
    for obj in scene.objects:
        found[obj.name_full] = obj
    depsgraph = getattr(view_layer, "depsgraph", None)
    if depsgraph is not None:
        for instance in depsgraph.object_instances:
            original = instance.object.original
            found.setdefault(original.name_full, original)
    return [obj for obj in found.values() if obj.type in _SURFACE_TYPES and hasattr(obj, "material_slots")]
