"""A mesh medium whose density comes from shader textures, read as a density grid.

An artist's cloud is often a cube of Principled Volume whose Density is a Noise Texture
(through Math, Map Range, a Color Ramp, maybe a Mapping and a Texture Coordinate). Cycles
evaluates that shader at each point inside the mesh. Python cannot evaluate shader nodes,
but most of those nodes have the same implementation in geometry nodes, so:

1. `density_medium` (during the render depsgraph walk) reads a medium material whose
   extinction is constant except for one density linked to a graph that varies in
   space: its extinction per unit density (`material_media`'s formulas with the density
   set to 1, checked to be 0 with the density 0: the extinction must be the density
   times constants) and the graph, each node of which must have a geometry-nodes twin
   (`COPIED`), a Mapping (built of Vector Math and Vector Rotate) or a Texture
   Coordinate's Object or Generated output; anything else keeps the material "not
   followed" (drawn opaque, named by left_out.py with why);
2. `read` (a second render-depsgraph pass, as `volume_grids.read`) adds one temporary
   object per mesh: loose vertices at the cell centres of a lattice over the mesh's
   object-space bounds (`BUDGET` points at most, one zero cell beyond them), its geometry
   nodes the density graph copied node by node (the same types, properties and unlinked
   input defaults) and stored on each vertex. The shader's coordinates become fields:
   Object = the vertex position (object space); Generated = (position - texture space
   location + size) / (2 size) from the mesh's texture space, as Cycles' volume shading
   gets it (ATTR_STD_GENERATED_TRANSFORM); an unlinked Vector of a texture node, which is
   Generated in a Cycles shader but Position in geometry nodes, is linked to Generated;
3. the values, clamped at 0 as Cycles clamps a density, are zeroed outside the mesh (the
   parity of a ray's crossings along +z, vectorised over the lattice's columns: the
   columns are moved by a tiny offset so none passes through an edge) and become a
   `GridMedium` in world space, one per instance (the object's matrix).

The lattice's cells have the mesh's faces on their sides for a box: the trilinear field
ramps from the last inside centre to the first outside one, which integrates to the
same length inside as the step Cycles sees. Everything added to bpy.data is removed
afterwards, whatever happens. bpy is imported inside functions.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..core.media import GridMedium
from . import material_nodes
from .material_media import Reader, Unfollowed, material_medium

log = logging.getLogger(__name__)

# The most lattice points one mesh's density is read at.
BUDGET = 64 ** 3
READ_ATTRIBUTE = "omniwarp_shader_density"
_PREFIX = "OmniWarp density reader"
# Shader nodes a geometry-nodes tree takes as they are (Blender 5.2; the same code runs both).
COPIED = frozenset({
    "ShaderNodeTexNoise", "ShaderNodeTexVoronoi", "ShaderNodeTexWave", "ShaderNodeTexGradient",
    "ShaderNodeTexMagic", "ShaderNodeTexChecker", "ShaderNodeTexBrick", "ShaderNodeTexWhiteNoise",
    "ShaderNodeTexGabor", "ShaderNodeMath", "ShaderNodeVectorMath", "ShaderNodeMapRange",
    "ShaderNodeValToRGB", "ShaderNodeCombineXYZ", "ShaderNodeSeparateXYZ", "ShaderNodeClamp",
    "ShaderNodeFloatCurve", "ShaderNodeMix", "ShaderNodeMixRGB", "ShaderNodeValue",
    "ShaderNodeVectorRotate", "ShaderNodeGamma",
})
# Properties every node has (name, location, ...): not copied.
_BASE = None
# Render pass: evaluates fn(depsgraph) inside a render depsgraph of the scene (render_geometry).
RenderPass = Callable[[Callable[[Any], Any]], Any]


class _FieldReader(Reader):
    """`material_media`'s reader with one density that varies in space, taken as `value`."""

    def __init__(self, value: float) -> None:
        self.value = value
        self.field: tuple[Any, tuple[Any, ...]] | None = None  # (the output socket feeding it, groups)

    def density(self, node: Any, groups: tuple[Any, ...]) -> float:
        try:
            return super().density(node, groups)
        except Unfollowed:
            out, _, inner = self.linked(node.inputs["Density"], groups)
            if out is None or not self.varies(out.node, inner, 0):
                raise
            if self.field is not None and self.field[0] != out:
                raise Unfollowed("two densities that vary in space: not followed") from None
            self.field = (out, inner)
            return self.value


@dataclass(frozen=True)
class DensityGraph:
    """A medium material's varying density: its extinction per unit density, and where the
    density's graph starts (an output socket, the node groups it lies inside)."""

    sigma: np.ndarray
    socket: Any
    groups: tuple[Any, ...]


def density_graph(material: Any) -> tuple[DensityGraph | None, str | None]:
    """(the graph, None) of a medium material whose extinction is a density that varies in
    space times constants, every node of which can be copied; else (None, why not), or
    (None, None) for a material that is no medium or a homogeneous one."""
    if material is None or not material_nodes.is_medium(material):
        return None, None
    medium, why = material_medium(material)
    if medium is not None or why is None:
        return None, None
    volume = material_nodes.surface_output(material.node_tree).inputs["Volume"]
    sigmas = []
    try:
        for value in (1.0, 0.0):
            reader = _FieldReader(value)
            source, _, groups = reader.linked(volume, ())
            sigmas.append(np.zeros(3) if source is None else reader.extinction(source, groups))
        if reader.field is None:
            return None, why
        if np.any(np.abs(sigmas[1]) > 1e-9):
            raise Unfollowed("a varying density beside a constant extinction: not followed")
        sigma = sigmas[0]
        if np.any(sigma < 0.0) or not np.all(np.isfinite(sigma)):
            raise Unfollowed("a negative or infinite extinction per unit density: not followed")
        graph = DensityGraph(sigma, *reader.field)
        _Copier(None, graph.groups).check(graph.socket, graph.groups)
    except Unfollowed as exc:
        return None, f"a density that varies in space, {exc}"
    return graph, None


def left_out_why(name: str) -> str:
    """The reason left_out.py names a material's medium for (`material_kinds`), by name_full."""
    import bpy

    material = bpy.data.materials[name]
    return f"{material.name}: {material_medium(material)[1]}"


def _label(node: Any) -> str:
    return node.bl_label.lower() if hasattr(node, "bl_label") else node.type.lower()


class _Copier:
    """Copies a density graph into a geometry-nodes tree (`tree` None: only checks it)."""

    def __init__(self, tree: Any, groups: tuple[Any, ...], texspace: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> None:
        self.tree = tree
        self.reader = Reader()
        self.made: dict[tuple[int, tuple[int, ...]], Any] = {}
        self.texspace = texspace
        self.coordinates: dict[str, Any] = {}

    # -- checking ---------------------------------------------------------------------
    def check(self, socket: Any, groups: tuple[Any, ...], depth: int = 0) -> None:
        """Raises `Unfollowed` for a node that cannot be copied upstream of `socket`."""
        if depth > 64:
            raise Unfollowed("a density graph too deep")
        node = socket.node
        if node.type == "TEX_COORD":
            if socket.identifier not in ("Object", "Generated") or (
                    socket.identifier == "Object" and node.object is not None):
                raise Unfollowed(f"texture coordinates {socket.name} have no geometry-nodes twin")
            return
        if node.bl_idname == "ShaderNodeMapping":
            if node.vector_type == "NORMAL":
                raise Unfollowed("a Mapping of normals is not copied")
        elif node.bl_idname not in COPIED:
            raise Unfollowed(f"a {_label(node)} has no geometry-nodes twin")
        for inp in node.inputs:
            if not inp.enabled:
                continue
            source, _, inner = self.reader.linked(inp, groups)
            if source is not None:
                self.check(source, inner, depth + 1)

    # -- copying ----------------------------------------------------------------------
    def output(self, socket: Any, groups: tuple[Any, ...]) -> Any:
        """The geometry-nodes output socket that computes the shader's `socket`."""
        node = socket.node
        if node.type == "TEX_COORD":
            return self.coordinate(socket.identifier)
        key = (node.as_pointer(), tuple(g.as_pointer() for g in groups))
        made = self.made.get(key)
        if made is None:
            made = self.made[key] = (self.mapping(node, groups) if node.bl_idname == "ShaderNodeMapping"
                                     else self.copy(node, groups))
        if isinstance(made, dict):  # a Mapping: its one output
            return made["Vector"]
        found = next((s for s in made.outputs if s.identifier == socket.identifier), None)
        if found is None:
            raise Unfollowed(f"a {_label(node)}'s {socket.name} output has no geometry-nodes twin")
        return found

    def coordinate(self, which: str) -> Any:
        if which in self.coordinates:
            return self.coordinates[which]
        position = self.tree.nodes.new("GeometryNodeInputPosition").outputs[0]
        if which == "Object":
            self.coordinates[which] = position
            return position
        # Cycles' generated transform (blender/mesh.cpp): P * 0.5 / size - (location * 0.5 / size - 0.5).
        location, size = self.texspace
        inverse = np.divide(0.5, size, out=np.zeros(3), where=size != 0.0)
        node = self.tree.nodes.new("ShaderNodeVectorMath")
        node.operation = "MULTIPLY_ADD"
        node.inputs[1].default_value = tuple(inverse)
        node.inputs[2].default_value = tuple(0.5 - location * inverse)
        self.tree.links.new(position, node.inputs[0])
        self.coordinates[which] = node.outputs[0]
        return node.outputs[0]

    def feed(self, shader_input: Any, target: Any, groups: tuple[Any, ...]) -> None:
        """Sets `target` (an input of a copied node) as `shader_input` has it: linked to the
        copy of what feeds it, or its constant (an unlinked texture Vector: Generated)."""
        source, end, inner = self.reader.linked(shader_input, groups)
        if source is not None:
            self.tree.links.new(self.output(source, inner), target)
        elif end is shader_input and shader_input.name == "Vector" \
                and shader_input.node.bl_idname.startswith("ShaderNodeTex"):
            self.tree.links.new(self.coordinate("Generated"), target)
        elif hasattr(target, "default_value") and hasattr(end, "default_value"):
            value = end.default_value
            try:
                target.default_value = value
            except (TypeError, ValueError):  # a colour into a vector socket, or the like
                target.default_value = tuple(value)[:len(target.default_value)]

    def copy(self, node: Any, groups: tuple[Any, ...]) -> Any:
        """The same node type in the geometry-nodes tree, its properties and inputs copied."""
        copy = self.tree.nodes.new(node.bl_idname)
        for prop in node.bl_rna.properties:
            name = prop.identifier
            if prop.is_readonly or name in _base_properties() or name in ("texture_mapping", "color_mapping"):
                continue
            try:
                setattr(copy, name, getattr(node, name))
            except (AttributeError, TypeError, ValueError) as exc:
                log.debug("density copy: %s.%s not set: %s", node.name, name, exc)
        if node.bl_idname == "ShaderNodeValToRGB":
            _copy_ramp(node.color_ramp, copy.color_ramp)
        elif node.bl_idname == "ShaderNodeFloatCurve":
            _copy_curve(node.mapping, copy.mapping)
        elif node.bl_idname == "ShaderNodeValue":
            copy.outputs[0].default_value = node.outputs[0].default_value
        by_id = {s.identifier: s for s in copy.inputs}
        for inp in node.inputs:
            target = by_id.get(inp.identifier)
            if target is None:
                if inp.enabled and inp.is_linked:
                    raise Unfollowed(f"a {_label(node)}'s {inp.name} input has no geometry-nodes twin")
                continue
            self.feed(inp, target, groups)
        return copy

    def mapping(self, node: Any, groups: tuple[Any, ...]) -> dict[str, Any]:
        """A Mapping node (shader-only) as Cycles computes it (svm_mapping), of Vector Math
        and Vector Rotate: Point R (v S) + L, Texture R^-1 (v - L) / S, Vector R (v S)."""
        nodes, links = self.tree.nodes, self.tree.links
        kind = node.vector_type

        def vector_math(operation: str, a: Any, b_input: Any) -> Any:
            math = nodes.new("ShaderNodeVectorMath")
            math.operation = operation
            links.new(a, math.inputs[0])
            self.feed(b_input, math.inputs[1], groups)
            return math.outputs[0]

        vector = nodes.new("ShaderNodeVectorMath")  # a pass-through holding the input vector
        vector.operation = "ADD"
        vector.inputs[1].default_value = (0.0, 0.0, 0.0)
        self.feed(node.inputs["Vector"], vector.inputs[0], groups)
        value = vector.outputs[0]
        if kind == "TEXTURE":
            value = vector_math("SUBTRACT", value, node.inputs["Location"])
        elif kind in ("POINT", "VECTOR"):
            value = vector_math("MULTIPLY", value, node.inputs["Scale"])
        rotate = nodes.new("ShaderNodeVectorRotate")
        rotate.rotation_type = "EULER_XYZ"
        rotate.invert = kind == "TEXTURE"
        rotate.inputs["Center"].default_value = (0.0, 0.0, 0.0)
        links.new(value, rotate.inputs["Vector"])
        self.feed(node.inputs["Rotation"], rotate.inputs["Rotation"], groups)
        value = rotate.outputs[0]
        if kind == "TEXTURE":
            value = vector_math("DIVIDE", value, node.inputs["Scale"])  # Blender's safe divide: 0 by 0
        elif kind == "POINT":
            value = vector_math("ADD", value, node.inputs["Location"])
        return {"Vector": value}


def _base_properties() -> set[str]:
    global _BASE
    if _BASE is None:
        import bpy

        _BASE = {p.identifier for p in bpy.types.Node.bl_rna.properties}
    return _BASE


def _copy_ramp(source: Any, target: Any) -> None:
    target.color_mode = source.color_mode
    target.interpolation = source.interpolation
    target.hue_interpolation = source.hue_interpolation
    elements = list(source.elements)
    while len(target.elements) > 1:
        target.elements.remove(target.elements[-1])
    target.elements[0].position = elements[0].position
    target.elements[0].color = tuple(elements[0].color)
    for element in elements[1:]:
        target.elements.new(element.position).color = tuple(element.color)


def _copy_curve(source: Any, target: Any) -> None:
    for name in ("use_clip", "clip_min_x", "clip_min_y", "clip_max_x", "clip_max_y", "extend"):
        if hasattr(source, name):
            setattr(target, name, getattr(source, name))
    for curve_from, curve_to in zip(source.curves, target.curves):
        points = list(curve_from.points)
        while len(curve_to.points) > len(points):
            curve_to.points.remove(curve_to.points[-1])
        while len(curve_to.points) < len(points):
            curve_to.points.new(0.0, 0.0)
        for p_from, p_to in zip(points, curve_to.points):
            p_to.location = tuple(p_from.location)
            p_to.handle_type = p_from.handle_type
    target.update()


@dataclass(frozen=True, eq=False)
class DensitySource:
    """One mesh instance whose medium's density is read from its shader."""

    name: str  # the original object
    parent: str | None  # its instancer, if instanced
    matrix: np.ndarray  # (4, 4) object space to world
    material: str  # the original material's name_full
    triangles: np.ndarray  # (T, 3, 3) object space, the medium's triangles
    texspace: tuple[np.ndarray, np.ndarray]  # the mesh's texture space location and size
    key: Any = None  # instances of one mesh and material share it: read once

    @property
    def medium_name(self) -> str:
        return self.name if self.parent is None else f"{self.parent}/{self.name}"


def lattice(triangles: np.ndarray, budget: int = BUDGET) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """(origin, cell size, the cell centres along x, y, z) of the lattice over the
    triangles' bounds: cells with the bounds on their sides, one more cell each side."""
    points = np.asarray(triangles, dtype=np.float64).reshape(-1, 3)
    lo, hi = points.min(axis=0), points.max(axis=0)
    extent = np.maximum(hi - lo, 1e-6)
    h = (float(np.prod(extent)) / budget) ** (1.0 / 3.0)
    counts = np.maximum(np.ceil(extent / h).astype(int), 1)
    while np.prod(counts + 2) > budget:
        h *= 1.05
        counts = np.maximum(np.ceil(extent / h).astype(int), 1)
    cell = extent / counts
    origin = lo - 0.5 * cell  # the centre of the first (outside) cell
    axes = [origin[a] + cell[a] * np.arange(counts[a] + 2) for a in range(3)]
    return origin, cell, axes


def inside(triangles: np.ndarray, axes: list[np.ndarray]) -> np.ndarray:
    """(nz, ny, nx) whether each lattice point lies inside the closed triangles: the parity
    of the crossings of a ray along +z from it, column by column."""
    tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    ax, ay, az = axes
    nx, ny, nz = len(ax), len(ay), len(az)
    span = max(ax[-1] - ax[0], ay[-1] - ay[0], 1e-6)
    # A tiny offset that puts no column through a vertex or an edge of a regular mesh.
    jx, jy = 1.234567e-6 * span, 2.345678e-6 * span
    counts = np.zeros((ny, nx, nz + 1), dtype=np.int32)
    for a, b, c in tris:
        lo, hi = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
        i0, i1 = np.searchsorted(ax + jx, [lo[0], hi[0]])
        j0, j1 = np.searchsorted(ay + jy, [lo[1], hi[1]])
        if i0 >= i1 or j0 >= j1:
            continue
        area = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        if abs(area) < 1e-20:
            continue  # a face along z: no column crosses it
        x, y = np.meshgrid(ax[i0:i1] + jx, ay[j0:j1] + jy)  # (rows y, columns x)
        u = ((b[0] - x) * (c[1] - y) - (c[0] - x) * (b[1] - y)) / area
        v = ((c[0] - x) * (a[1] - y) - (a[0] - x) * (c[1] - y)) / area
        w = 1.0 - u - v
        hit = (u >= 0.0) & (v >= 0.0) & (w >= 0.0)
        if not hit.any():
            continue
        z = u * a[2] + v * b[2] + w * c[2]
        # A crossing at height z counts for the points below it: k < searchsorted(az, z).
        k = np.searchsorted(az, z[hit])
        rows, cols = np.nonzero(hit)
        np.add.at(counts, (rows + j0, cols + i0, 0), 1)
        np.add.at(counts, (rows + j0, cols + i0, k), -1)
    parity = np.cumsum(counts[..., :nz], axis=2) % 2 == 1  # (ny, nx, nz)
    return np.transpose(parity, (2, 0, 1))


def _reader_tree(material: Any, texspace: tuple[np.ndarray, np.ndarray]) -> tuple[Any, Any]:
    """(a node group storing the material's density on each point, the copier's graph)."""
    import bpy

    graph, why = density_graph(material)
    if graph is None:
        raise Unfollowed(why or "no varying density")
    tree = bpy.data.node_groups.new(_PREFIX, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    try:
        group_in, group_out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
        store = tree.nodes.new("GeometryNodeStoreNamedAttribute")
        store.data_type, store.domain = "FLOAT", "POINT"
        store.inputs["Name"].default_value = READ_ATTRIBUTE
        copier = _Copier(tree, graph.groups, texspace)
        tree.links.new(copier.output(graph.socket, graph.groups), store.inputs["Value"])
        tree.links.new(group_in.outputs[0], store.inputs["Geometry"])
        tree.links.new(store.outputs[0], group_out.inputs[0])
    except BaseException:
        bpy.data.node_groups.remove(tree)
        raise
    return tree, graph


def read(scene: Any, sources: list[DensitySource], render_pass: RenderPass, budget: int = BUDGET
         ) -> list[GridMedium | str | None]:
    """Each source's GridMedium (None: a density 0 everywhere), or why it was not read.
    `render_pass(fn)` evaluates `fn(depsgraph)` inside a render depsgraph of `scene`;
    nothing this adds to bpy.data stays."""
    import bpy

    out: list[GridMedium | str | None] = [None] * len(sources)
    plans: dict[Any, tuple] = {}  # key -> (reader object name, origin, cell, axes, sigma) or why
    made: list[tuple[Any, Any]] = []
    try:
        for source in sources:
            key = source.key if source.key is not None else id(source)
            if key in plans:
                continue
            try:
                material = bpy.data.materials[source.material]
                tree, graph = _reader_tree(material, source.texspace)
            except (Unfollowed, KeyError) as why:
                plans[key] = f"a density that varies in space not read: {why}"
                continue
            made.append((bpy.data.node_groups, tree))
            origin, cell, axes = lattice(source.triangles, budget)
            z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
            points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
            mesh = bpy.data.meshes.new(_PREFIX)
            made.append((bpy.data.meshes, mesh))
            mesh.vertices.add(len(points))
            mesh.vertices.foreach_set("co", points.astype(np.float32).reshape(-1))
            obj = bpy.data.objects.new(_PREFIX, mesh)
            made.append((bpy.data.objects, obj))
            obj.modifiers.new(_PREFIX, "NODES").node_group = tree
            scene.collection.objects.link(obj)
            plans[key] = (obj.name_full, origin, cell, axes, graph.sigma)
        names = [p[0] for p in plans.values() if not isinstance(p, str)]
        found = render_pass(lambda depsgraph: _values(depsgraph, names)) if names else {}
    finally:
        for collection, block in reversed(made):
            try:
                collection.remove(block)
            except (ReferenceError, RuntimeError) as exc:
                log.debug("density reader cleanup: %s", exc)
    densities: dict[Any, Any] = {}
    for i, source in enumerate(sources):
        key = source.key if source.key is not None else id(source)
        plan = plans[key]
        if isinstance(plan, str):
            out[i] = plan
            continue
        name, origin, cell, axes, sigma = plan
        if key not in densities:
            values = found.get(name) if isinstance(found, dict) else None
            shape = tuple(len(a) for a in axes[::-1])
            if values is None or len(values) != int(np.prod(shape)):
                densities[key] = "the density reader's geometry nodes gave no values"
            else:
                density = np.maximum(np.nan_to_num(values.reshape(shape), nan=0.0, posinf=0.0, neginf=0.0), 0.0)
                density[~inside(source.triangles, axes)] = 0.0
                densities[key] = density.astype(np.float32)
        density = densities[key]
        if isinstance(density, str):
            out[i] = density
            continue
        if not np.any(density > 0.0) or not np.any(sigma > 0.0):
            out[i] = None
            continue
        to_lattice = np.diag([*(1.0 / cell), 1.0])
        to_lattice[:3, 3] = -origin / cell
        to_index = to_lattice @ np.linalg.inv(source.matrix)
        out[i] = GridMedium(source.medium_name, sigma, density, to_index)
        log.info("shader density %s: %s cells, density up to %.4g, sigma %s", source.medium_name,
                 "x".join(map(str, density.shape[::-1])), float(density.max()), np.round(sigma, 4).tolist())
    return out


def _values(depsgraph: Any, names: list[str]) -> dict[str, np.ndarray]:
    """Each reader's stored values (inside the render pass)."""
    import bpy

    out: dict[str, np.ndarray] = {}
    for name in names:
        mesh = bpy.data.objects[name].evaluated_get(depsgraph).data
        attribute = None if mesh is None else mesh.attributes.get(READ_ATTRIBUTE)
        if attribute is None or attribute.domain != "POINT":
            continue
        values = np.empty(len(attribute.data), dtype=np.float32)
        attribute.data.foreach_get("value", values)
        out[name] = values
    return out
