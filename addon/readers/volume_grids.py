"""The density grids of the Volume geometry Cycles renders, read into `core.media.GridMedium`.

Cycles shadows with Volume geometry (OpenVDB grids loaded from files, made by geometry
nodes or by a Mesh to Volume modifier) as a heterogeneous medium: the extinction is its
material's extinction per unit density (`material_media.grid_sigma`) times the density
grid, sampled trilinearly. Python cannot read voxels (there is no openvdb module), so the
grid is read through geometry nodes, in two steps:

1. `volume_source`, during the render depsgraph walk (`render_geometry.collect`), notes
   each Volume instance: the object whose evaluated geometry holds it, its matrix, the
   grid's name, its index-to-object transform (`VolumeGrid.matrix_object`) and the index
   box of its bounds, and the material's extinction per unit density;
2. `read` adds one temporary reader object per source: a mesh of loose vertices at the
   grid's voxel centres (object space) whose geometry nodes take the source through Object
   Info (original transform space, not as an instance), Get Named Grid and Sample Grid
   (trilinear: at a voxel centre, that voxel's value) and store the value on each
   vertex. A second render-depsgraph pass evaluates the readers (so render-level
   modifiers and settings hold) and `foreach_get` reads the values; the readers, their
   meshes and node groups are removed afterwards, whatever happens.

The lattice covers the grid's bounds with a zero voxel beyond them, so the dense grid's
trilinear interpolation is the grid's own (its background is 0). Past `BUDGET` lattice
points the lattice takes every s-th voxel (s the smallest stride that fits) and samples
the grid trilinearly there: features narrower than s voxels are then smoothed or missed,
an error of the order of s^2 h^2 |d^2 density / dx^2| / 8 between lattice points (h the
voxel size), which the GridMedium's `voxel_size()` shows as s h. The dense array is
cropped to where the density is not 0, plus one zero voxel.

What is not read (the source is named by `left_out.py` with why): a Blender without the
grid nodes (`grid_nodes_available`), a volume inside geometry-nodes instances (Object
Info hands over instances, not their grids), a material whose extinction is not a grid
times constants, a missing or non-float density grid. bpy is imported inside functions.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..core.media import GridMedium
from ..compat.blender import grid_nodes_available
from .material_media import GridSigma, grid_sigma

log = logging.getLogger(__name__)

# The most lattice points a grid is read at (128^3): 2M vertices, 8 MB of float32.
BUDGET = 128 ** 3
READ_ATTRIBUTE = "omniwarp_density"
_PREFIX = "OmniWarp grid reader"
# The nodes the readers need. They exist from Blender 5.0 on (4.x has them only as an
# experimental feature, off in a plain install); the one gate of this module.
NO_GRID_NODES = "this Blender has no geometry-nodes grid nodes to read grids with (5.0 or later)"
# Evaluates `fn(depsgraph)` inside a render depsgraph of the scene (render_geometry).
RenderPass = Callable[[Callable[[Any], Any]], Any]


@dataclass(frozen=True, eq=False)
class VolumeSource:
    """One Volume instance of the render depsgraph and how to read its density grid."""

    name: str  # the original object whose evaluated geometry holds the volume
    parent: str | None  # its instancer, if instanced
    matrix: np.ndarray  # (4, 4) the instance's object space to world
    grid: str = ""  # the density grid's name
    sigma: np.ndarray | None = None  # (3,) extinction per unit density
    index_to_object: np.ndarray | None = None  # (4, 4) VolumeGrid.matrix_object
    box: tuple[tuple[int, int, int], tuple[int, int, int]] | None = None  # index (x, y, z) min, max, inclusive
    why: str | None = None  # why it cannot be read; None: readable

    @property
    def medium_name(self) -> str:
        return self.name if self.parent is None else f"{self.parent}/{self.name}"


def volume_source(inst: Any, materials: dict[str, GridSigma] | None = None) -> VolumeSource:
    """What reading one VOLUME instance of a render depsgraph needs (step 1 of the module
    docstring), or why it cannot be read. `materials` caches `grid_sigma` by material."""
    obj = inst.object
    parent = inst.parent if inst.is_instance else None
    name = obj.original.name_full
    parent_name = None if parent is None else parent.original.name_full
    matrix = np.array(inst.matrix_world, dtype=np.float64)

    def unread(why: str) -> VolumeSource:
        return VolumeSource(name, parent_name, matrix, why=why)

    if not grid_nodes_available():
        return unread(NO_GRID_NODES)
    if parent is not None and parent.original == obj.original and not np.allclose(
            matrix, np.array(parent.matrix_world, dtype=np.float64), atol=1e-6):
        return unread("a volume inside geometry-nodes instances: not read")
    sigma, grid_name = object_grid_sigma(obj, materials)
    if sigma is None:
        return unread(grid_name)
    grids = obj.data.grids
    if not grids.is_loaded:
        grids.load()
    grid = grids.get(grid_name) if hasattr(grids, "get") else next((g for g in grids if g.name == grid_name), None)
    if grid is None:
        return unread(f"no grid named {grid_name!r}: not read")
    if grid.data_type not in ("FLOAT", "DOUBLE"):
        return unread(f"the grid {grid_name!r} holds {grid.data_type.lower()} values: not read")
    to_object = np.array(grid.matrix_object, dtype=np.float64)
    if abs(np.linalg.det(to_object[:3, :3])) < 1e-30:
        return unread(f"the grid {grid_name!r} has a singular transform: not read")
    corners = np.concatenate([np.array(obj.bound_box, dtype=np.float64), np.ones((8, 1))], axis=1)
    index = (corners @ np.linalg.inv(to_object).T)[:, :3]
    # The bounds reach half a voxel past the outer centres: floor and ceil add one zero voxel.
    lo, hi = np.floor(index.min(axis=0) - 1e-6).astype(int), np.ceil(index.max(axis=0) + 1e-6).astype(int)
    return VolumeSource(name, parent_name, matrix, grid_name, np.asarray(sigma, dtype=np.float64), to_object,
                        (tuple(int(v) for v in lo), tuple(int(v) for v in hi)))


def object_grid_sigma(obj: Any, materials: dict[str, GridSigma] | None = None) -> GridSigma:
    """`grid_sigma` of an evaluated object's first material (Cycles renders Volume geometry
    with it), cached by the material's name in `materials`."""
    material = next((slot.material for slot in obj.material_slots if slot.material is not None), None)
    key = "" if material is None else material.original.name_full
    cache = {} if materials is None else materials
    if key not in cache:
        cache[key] = grid_sigma(material)
    return cache[key]


def lattice(box: tuple[tuple[int, ...], tuple[int, ...]], budget: int = BUDGET) -> tuple[int, list[np.ndarray]]:
    """(stride, the index coordinates along x, y, z) of the points a grid's box is read
    at: every voxel, or every stride-th where that would pass `budget` points."""
    lo, hi = np.array(box[0]), np.array(box[1])
    count = float(np.prod(hi - lo + 1))
    stride = max(1, int(np.ceil((count / budget) ** (1.0 / 3.0))))
    while np.prod([len(range(a, b + stride, stride)) for a, b in zip(lo, hi)]) > budget:
        stride += 1
    return stride, [np.arange(a, b + stride, stride, dtype=np.float64) for a, b in zip(lo, hi)]


def _reader_nodes(source_object: Any, grid: str) -> Any:
    """The reader's node group: Sample Grid of the source's grid at each vertex, stored on it."""
    import bpy

    tree = bpy.data.node_groups.new(_PREFIX, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    group_in, group_out = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    info = nodes.new("GeometryNodeObjectInfo")
    info.transform_space = "ORIGINAL"  # the source's own object space: the grid's matrix_object
    info.inputs["Object"].default_value = source_object
    info.inputs["As Instance"].default_value = False
    named = nodes.new("GeometryNodeGetNamedGrid")
    named.data_type = "FLOAT"
    named.inputs["Name"].default_value = grid
    sample = nodes.new("GeometryNodeSampleGrid")
    sample.data_type = "FLOAT"
    sample.inputs["Interpolation"].default_value = "Trilinear"
    store = nodes.new("GeometryNodeStoreNamedAttribute")
    store.data_type, store.domain = "FLOAT", "POINT"
    store.inputs["Name"].default_value = READ_ATTRIBUTE
    links.new(info.outputs["Geometry"], named.inputs["Volume"])
    links.new(named.outputs["Grid"], sample.inputs["Grid"])
    links.new(nodes.new("GeometryNodeInputPosition").outputs[0], sample.inputs["Position"])
    links.new(group_in.outputs[0], store.inputs["Geometry"])
    links.new(sample.outputs["Value"], store.inputs["Value"])
    links.new(store.outputs[0], group_out.inputs[0])
    return tree


class _Readers:
    """The temporary reader objects, meshes and node groups; `remove` deletes them all."""

    def __init__(self) -> None:
        self.made: list[tuple[Any, Any]] = []  # (bpy.data collection, block), in creation order

    def add(self, scene: Any, source: VolumeSource, points: np.ndarray) -> str:
        """A reader object of `source` at `points` (object space, (N, 3)); returns its name."""
        import bpy

        obj_source = bpy.data.objects[source.name]
        tree = _reader_nodes(obj_source, source.grid)
        self.made.append((bpy.data.node_groups, tree))
        mesh = bpy.data.meshes.new(_PREFIX)
        self.made.append((bpy.data.meshes, mesh))
        mesh.vertices.add(len(points))
        mesh.vertices.foreach_set("co", points.astype(np.float32).reshape(-1))
        obj = bpy.data.objects.new(_PREFIX, mesh)
        self.made.append((bpy.data.objects, obj))
        obj.modifiers.new(_PREFIX, "NODES").node_group = tree
        scene.collection.objects.link(obj)
        return obj.name_full

    def remove(self) -> None:
        for collection, block in reversed(self.made):
            try:
                collection.remove(block)
            except (ReferenceError, RuntimeError) as exc:  # already gone with its owner
                log.debug("grid reader cleanup: %s", exc)
        self.made.clear()


def _values(depsgraph: Any, names: list[str]) -> dict[str, np.ndarray | str]:
    """Each reader's stored values (inside the render pass), or why there are none."""
    import bpy

    out: dict[str, np.ndarray | str] = {}
    for name in names:
        evaluated = bpy.data.objects[name].evaluated_get(depsgraph)
        mesh = evaluated.data
        attribute = None if mesh is None else mesh.attributes.get(READ_ATTRIBUTE)
        if attribute is None or attribute.domain != "POINT":
            out[name] = "the grid reader's geometry nodes gave no values"
            continue
        values = np.empty(len(attribute.data), dtype=np.float32)
        attribute.data.foreach_get("value", values)
        out[name] = values
    return out


def dense_medium(source: VolumeSource, stride: int, axes: list[np.ndarray], values: np.ndarray) -> GridMedium | None:
    """The GridMedium of a source's values read at the lattice `axes` (x, y, z index
    coordinates, every `stride` voxels), cropped to its non-zero voxels plus one zero
    voxel each side; None when the grid is empty."""
    nx, ny, nz = (len(a) for a in axes)
    density = np.maximum(np.nan_to_num(values.reshape(nz, ny, nx), nan=0.0, posinf=0.0), 0.0)
    filled = np.nonzero(density > 0.0)
    if not len(filled[0]):
        return None
    start = [max(int(f.min()) - 1, 0) for f in filled]  # (z, y, x)
    stop = [min(int(f.max()) + 2, n) for f, n in zip(filled, (nz, ny, nx))]
    density = density[start[0]:stop[0], start[1]:stop[1], start[2]:stop[2]]
    origin = np.array([axes[0][start[2]], axes[1][start[1]], axes[2][start[0]]])  # grid index of lattice (0, 0, 0)
    grid_to_lattice = np.eye(4)
    grid_to_lattice[:3, :3] /= stride
    grid_to_lattice[:3, 3] = -origin / stride
    to_index = grid_to_lattice @ np.linalg.inv(source.index_to_object) @ np.linalg.inv(source.matrix)
    return GridMedium(source.medium_name, source.sigma, density.astype(np.float32), to_index)


def read(scene: Any, sources: list[VolumeSource], render_pass: RenderPass, budget: int = BUDGET
         ) -> list[GridMedium | str | None]:
    """Each source's GridMedium (None: an empty grid, which blocks nothing), or why it was
    not read (step 2 of the module docstring). `render_pass(fn)` evaluates `fn(depsgraph)`
    inside a render depsgraph of `scene`; nothing this adds to bpy.data stays."""
    out: list[GridMedium | str | None] = [s.why for s in sources]
    todo = [i for i, s in enumerate(sources) if s.why is None]
    if not todo:
        return out
    readers = _Readers()
    try:
        plans = {}
        for i in todo:
            source = sources[i]
            stride, axes = lattice(source.box, budget)
            z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")  # (nz, ny, nx): x fastest
            index = np.stack([x.ravel(), y.ravel(), z.ravel(), np.ones(x.size)], axis=1)
            points = (index @ source.index_to_object.T)[:, :3]
            plans[i] = (readers.add(scene, source, points), stride, axes)
            log.debug("reading grid %r of %s at %d points (stride %d)", source.grid, source.medium_name,
                      len(points), stride)
        found = render_pass(lambda depsgraph: _values(depsgraph, [p[0] for p in plans.values()]))
    finally:
        readers.remove()
    for i, (name, stride, axes) in plans.items():
        values = found.get(name) if isinstance(found, dict) else None
        expected = int(np.prod([len(a) for a in axes]))
        if isinstance(values, str) or values is None or len(values) != expected:
            out[i] = values if isinstance(values, str) else "the grid reader's geometry nodes gave no values"
            continue
        out[i] = dense_medium(sources[i], stride, axes, values)
        if out[i] is not None:
            medium = out[i]
            log.info("grid medium %s: %s voxels of %.4g m, density up to %.4g, sigma %s", medium.name,
                     "x".join(map(str, medium.density.shape[::-1])), medium.voxel_size(),
                     float(medium.density.max()), np.round(medium.sigma, 4).tolist())
    return out
