"""The scene's triangles as the renderer evaluates them, sorted by the shadow rule.

Cycles renders from a *render* depsgraph: modifiers at their render levels,
`hide_render` applied to objects, collections and instanced collections,
instancers shown or not as `show_instancer_for_render` says, particles at their
render amount, objects hidden in the viewport included. The viewport depsgraph
that `bpy.context.evaluated_depsgraph_get()` returns differs on each of those.
Python cannot build a render depsgraph directly, but a render engine is handed
one: `render_triangles` registers a tiny engine, "renders" one frame with it and
reads `depsgraph.object_instances` inside its `render` call.

Every instance is kept with the names of its original object and instancer
(`Owner`), so one read serves any light's `ShadowRule`, and with its see-through
materials (`material_alpha.mesh_surface`: per-triangle UVs and alpha maps) and its
homogeneous media (`material_media.mesh_media`: a medium's index per triangle). Volume
geometry's density grids are read in a second render-depsgraph pass
(`volume_grids.read`), into grid media by owner, and so are the media of meshes whose
density is a shader texture (`shader_density.read`: their triangles are no surface, their
density a grid). Hair and points come from `hair.py`. What the walk meets that the methods
do not draw (volumes whose grid was not read, media not followed, true displacement) is
kept apart, by owner (`left_out.py`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ..core import interrupt
from ..core.alpha import Surface
from ..core.blockers import Spheres, Strands
from ..core.errors import ReferenceCaptureError
from ..core.media import GridMedium
from .hair import CurveShape, particle_strands, points_or_strands, uniform_scale
from .left_out import LeftOut, scan_instance
from .material_alpha import MaterialAlpha, mesh_surface, triangle_slots
from .material_media import GridSigma, MediumFound, mesh_media
from .volume_grids import VolumeSource, volume_source
from . import shader_density, smoke_domains, volume_grids

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

log = logging.getLogger(__name__)

# Object types whose evaluated geometry becomes triangles (to_mesh understands them);
# the render depsgraph hands the non-mesh ones over as meshes (see `collect`).
GEOMETRY_TYPES = frozenset({"MESH", "CURVE", "SURFACE", "META", "FONT"})
_ENGINE_ID = "OMNIWARP_GEOMETRY"


@dataclass(frozen=True)
class Owner:
    """Who a batch of triangles belongs to: the original object, and its instancer if instanced."""

    name: str
    parent: str | None = None


@dataclass
class SceneTriangles:
    """World-space triangles (T, 3, 3) float32 grouped by owner, with their surfaces."""

    owners: list[Owner]
    triangles: list[np.ndarray]
    surfaces: list[Surface] | None = None  # one a batch; None: all opaque
    notes: dict[str, str] | None = None  # material -> why its alpha was not followed
    left_out: LeftOut = field(default_factory=LeftOut)  # what Cycles renders that no method draws
    # Point clouds and hair curves, world space, by owner (core/blockers.py).
    spheres: list[tuple[Owner, Spheres]] = field(default_factory=list)
    strands: list[tuple[Owner, Strands]] = field(default_factory=list)
    # Volume geometry: where to read each grid (collect), then the grids read (render_triangles).
    volumes: list[VolumeSource] = field(default_factory=list)
    grids: list[tuple[Owner, GridMedium]] = field(default_factory=list)
    # Meshes whose medium's density is a shader texture: where to read it (collect, `densities`).
    densities: list[shader_density.DensitySource] = field(default_factory=list)
    # World matrices of the lights and cameras as the render evaluates them, by name_full: an
    # object disabled in the viewport is not evaluated there (its matrix stays as saved).
    matrices: dict[str, np.ndarray] = field(default_factory=dict)

    def select_grids(self, keep: Callable[[str, str | None], bool]) -> tuple[GridMedium, ...]:
        """The grid media of the owners `keep(name, parent)` accepts."""
        return tuple(grid for owner, grid in self.grids if keep(owner.name, owner.parent))

    def select_spheres(self, keep: Callable[[str, str | None], bool]) -> Spheres:
        """The point clouds of the owners `keep(name, parent)` accepts, as one set."""
        return Spheres.concatenate([s for owner, s in self.spheres if keep(owner.name, owner.parent)])

    def select_strands(self, keep: Callable[[str, str | None], bool]) -> Strands:
        """The hair curves of the owners `keep(name, parent)` accepts, as one set."""
        return Strands.concatenate([s for owner, s in self.strands if keep(owner.name, owner.parent)])

    def select_surface(self, keep: Callable[[str, str | None], bool]) -> Surface:
        """The surfaces of the triangles `select(keep)` returns, in the same order."""
        surfaces = self.surfaces or [Surface.opaque(len(t)) for t in self.triangles]
        return Surface.concatenate([surface for owner, surface in zip(self.owners, surfaces)
                                    if keep(owner.name, owner.parent)])

    def alpha_notes(self) -> list[str]:
        """One note naming the see-through materials whose alpha the rule could not
        follow: the reference renders them as the file has them, OmniWarp as opaque."""
        if not self.notes:
            return []
        listed = ", ".join(f"{name} ({why})" for name, why in sorted(self.notes.items()))
        return [f"materials whose alpha OmniWarp draws as opaque: {listed}"]

    def select(self, keep: Callable[[str, str | None], bool], key: object = None) -> np.ndarray:
        """The triangles of the owners `keep(name, parent)` accepts, concatenated.

        `key` is accepted for the scene cache's signature and not used.
        """
        parts = [tris for owner, tris in zip(self.owners, self.triangles) if keep(owner.name, owner.parent)]
        if not parts:
            return np.zeros((0, 3, 3), dtype=np.float32)
        return np.concatenate(parts, axis=0)

    @property
    def names(self) -> set[str]:
        """Original objects that gave triangles (instancers for their instances)."""
        return {owner.parent or owner.name for owner in self.owners}


def local_triangles(obj: Any, depsgraph: Any) -> np.ndarray:
    """Object-space triangles (n, 3, 3) float32 of an evaluated object."""
    return local_geometry(obj, depsgraph)[0]


# A mesh medium whose density is a shader texture: (original material name_full, its
# object-space triangles, the mesh's texture space location and size).
DensityPart = tuple[str, np.ndarray, tuple[np.ndarray, np.ndarray]]


def local_geometry(obj: Any, depsgraph: Any, materials: dict[str, MaterialAlpha] | None = None,
                   media: dict[str, MediumFound] | None = None,
                   densities: tuple[dict[str, bool], list[DensityPart]] | None = None
                   ) -> tuple[np.ndarray, Surface, dict[str, str]]:
    """Object-space triangles (n, 3, 3) float32 of an evaluated object, their surface (see-
    through materials and homogeneous media) and the notes of the materials whose alpha
    was not followed; the surface is read only with `materials` (a cache shared by the
    scene's objects; `media` the same for the media), else it is opaque. With `densities`
    (a cache of material name_full -> whether its density is a shader graph read, and a
    list), the triangles of such media are left out and appended to the list instead."""
    if smoke_domains.is_gas_domain(obj):  # Cycles renders it as Volume geometry (its grids)
        return np.zeros((0, 3, 3), dtype=np.float32), Surface.opaque(0), {}
    temporary = obj.type != "MESH"
    mesh = obj.to_mesh(preserve_all_data_layers=False, depsgraph=depsgraph) if temporary else obj.data
    try:
        if mesh is None:
            return np.zeros((0, 3, 3), dtype=np.float32), Surface.opaque(0), {}
        if len(mesh.polygons) and not len(mesh.loop_triangles):
            mesh.calc_loop_triangles()
        n_tris = len(mesh.loop_triangles)
        coords = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", coords)
        indices = np.empty(n_tris * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", indices)
        tris = coords.reshape(-1, 3)[indices].reshape(n_tris, 3, 3)
        if materials is None:
            return tris, Surface.opaque(n_tris), {}
        surface, notes = mesh_surface(obj, mesh, materials)
        medium, found = mesh_media(obj, mesh, media)
        # A medium's triangles bound it: the methods draw the medium between them.
        surface = surface.with_media(medium, found) if found else surface
        if densities is not None:
            tris, surface = _density_parts(obj, mesh, tris, surface, *densities)
        return tris, surface, notes
    finally:
        if temporary:
            obj.to_mesh_clear()


def _density_parts(obj: Any, mesh: Any, tris: np.ndarray, surface: Surface, cache: dict[str, bool],
                   parts: list[DensityPart]) -> tuple[np.ndarray, Surface]:
    """The triangles and surface less those of media whose density is a shader graph that
    `shader_density` reads, which go to `parts`."""
    slots, index = triangle_slots(obj, mesh)
    keep = np.ones(len(tris), dtype=bool)
    for slot in np.unique(index) if slots and len(tris) else ():
        material = slots[slot]
        if material is None:
            continue
        name = material.original.name_full
        if name not in cache:
            cache[name] = shader_density.density_graph(material)[0] is not None
        if cache[name]:
            chosen = index == slot
            texspace = (np.array(mesh.texspace_location, dtype=np.float64),
                        np.array(mesh.texspace_size, dtype=np.float64))
            parts.append((name, tris[chosen].copy(), texspace))
            keep &= ~chosen
    if keep.all():
        return tris, surface
    return tris[keep], surface.take(np.nonzero(keep)[0])


def collect(depsgraph: Any, densities: bool = False) -> SceneTriangles:
    """Every instance of an evaluated depsgraph that has surface triangles, in world space.

    The object-space triangles of a source object are read once, however many
    instances it has. With `densities`, the media whose density is a shader texture
    are kept apart (`SceneTriangles.densities`) for `shader_density.read`.
    """
    owners: list[Owner] = []
    triangles: list[np.ndarray] = []
    surfaces: list[Surface] = []
    notes: dict[str, str] = {}
    materials: dict[str, MaterialAlpha] = {}
    media: dict[str, MediumFound] = {}
    local_cache: dict[Any, tuple[np.ndarray, Surface, list[DensityPart]]] = {}
    density_cache: dict[str, bool] = {}
    density_sources: list[shader_density.DensitySource] = []
    left = LeftOut()
    left_materials: dict[str, tuple[tuple[str, str | None], ...]] = {}
    spheres: list[tuple[Owner, Spheres]] = []
    strands: list[tuple[Owner, Strands]] = []
    volumes: list[VolumeSource] = []
    grids: list[tuple[Owner, GridMedium]] = []
    grid_materials: dict[str, GridSigma] = {}
    shape = CurveShape.of(depsgraph.scene)
    # A view layer with "Strands" off renders no hair (Cycles' view_layer.use_hair).
    hair = bool(getattr(depsgraph.view_layer, "use_strand", True))
    for inst in depsgraph.object_instances:
        obj = inst.object
        if not hair and obj.type == "CURVES":
            continue
        scan_instance(left, inst, left_materials)
        if obj.type == "VOLUME":
            volumes.append(volume_source(inst, grid_materials))
            continue
        if obj.type in ("POINTCLOUD", "CURVES"):
            parent = inst.parent if inst.is_instance else None
            owner = Owner(obj.original.name_full, None if parent is None else parent.original.name_full)
            matrix = np.array(inst.matrix_world, dtype=np.float64)
            found = points_or_strands(obj, matrix, shape)
            if found is not None and len(found):
                (spheres if obj.type == "POINTCLOUD" else strands).append((owner, found))
                if obj.type == "CURVES" and not uniform_scale(matrix):
                    left.add("elliptic_hair", *owner)
            continue
        # Cycles renders evaluated meshes only. A curve, text, surface or metaball
        # object comes twice: as itself (skipped) and as the mesh instance of its
        # evaluated geometry, whose instancer is the object itself.
        if obj.type != "MESH":
            continue
        parent = inst.parent if inst.is_instance else None
        if smoke_domains.is_gas_domain(obj):
            _smoke(inst, depsgraph, grid_materials, grids, left, densities)
            continue
        if parent is None and hair:
            matrix = np.array(inst.matrix_world, dtype=np.float64)
            for found in particle_strands(obj, shape, matrix):
                strands.append((Owner(obj.original.name_full), found))
                if not uniform_scale(matrix):
                    left.add("elliptic_hair", obj.original.name_full)
        if parent is None and obj.is_instancer and not obj.original.show_instancer_for_render:
            continue  # an emitter that Cycles does not draw itself
        # Geometry-nodes instance geometry has no object of its own: key on its data.
        key = obj.original.name_full if parent is None or obj.original != parent.original else \
            ("data", obj.data.as_pointer() if obj.data is not None else obj.as_pointer())
        held = local_cache.get(key)
        if held is None:
            parts: list[DensityPart] = []
            local, surface, found = local_geometry(obj, depsgraph, materials, media,
                                                   (density_cache, parts) if densities else None)
            held = local_cache[key] = (local, surface, parts)
            notes.update(found)
        local, surface, parts = held
        matrix = np.array(inst.matrix_world, dtype=np.float64)
        for material, part, texspace in parts:
            density_sources.append(shader_density.DensitySource(
                obj.original.name_full, None if parent is None else parent.original.name_full, matrix,
                material, part, texspace, key=(key, material)))
        if not len(local):
            continue
        corners = local.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
        owners.append(Owner(obj.original.name_full, None if parent is None else parent.original.name_full))
        triangles.append(corners.reshape(-1, 3, 3).astype(np.float32))
        surfaces.append(surface)
    for source in density_sources:  # read: no longer left out (re-added with why if the read fails)
        left.forget("volume_material", source.name, source.parent, shader_density.left_out_why(source.material))
    matrices = {obj.original.name_full: np.array(obj.matrix_world, dtype=np.float64)
                for obj in depsgraph.objects if obj.type in ("LIGHT", "CAMERA")}
    return SceneTriangles(owners, triangles, surfaces, notes, left, spheres, strands, volumes, grids,
                          densities=density_sources, matrices=matrices)


def _smoke(inst: Any, depsgraph: Any, materials: dict[str, GridSigma], grids: list[tuple[Owner, GridMedium]],
           left: LeftOut, read: bool) -> None:
    """A smoke domain instance: its grid medium (`smoke_domains`) into `grids`, or named
    as left out with why (`read` False: grids are not read in this pass)."""
    parent = inst.parent if inst.is_instance else None
    owner = Owner(inst.object.original.name_full, None if parent is None else parent.original.name_full)
    found = smoke_domains.smoke_medium(inst, depsgraph.scene.frame_current, materials) if read else \
        "grids are not read in this pass"
    if isinstance(found, str):
        left.add("volume", owner.name, owner.parent, found)
    elif found is not None:
        grids.append((owner, found))


def render_triangles(scene: "bpy.types.Scene", view_layer: "bpy.types.ViewLayer", grids: bool = True) -> SceneTriangles:
    """`collect` over the render depsgraph of one view layer (see the module docstring),
    and, with `grids`, the density grids of its Volume geometry (a second pass, only
    where there is some): a grid read is no longer left out, one not read is, with why.

    The scene's engine is switched for each pass only and put back afterwards.
    """
    found: SceneTriangles = render_pass(scene, view_layer, lambda depsgraph: collect(depsgraph, densities=grids))
    if found.densities:
        _read_densities(scene, view_layer, found)
    if grids and found.volumes:
        try:
            read = volume_grids.read(scene, found.volumes, lambda fn: render_pass(scene, view_layer, fn))
        finally:
            # The layer's evaluated depsgraph met the readers during the pass: evaluate it
            # again without them, or its instances would point at removed objects.
            view_layer.update()
        for source, grid in zip(found.volumes, read):
            owner = Owner(source.name, source.parent)
            if isinstance(grid, str):
                found.left_out.add("volume", source.name, source.parent, grid)
                continue
            found.left_out.discard("volume", source.name, source.parent)
            if grid is not None:
                found.grids.append((owner, grid))
    elif found.volumes:
        for source in found.volumes:
            found.left_out.add("volume", source.name, source.parent, source.why)
    return found


def _read_densities(scene: "bpy.types.Scene", view_layer: "bpy.types.ViewLayer", found: SceneTriangles) -> None:
    """The grids of the media whose density is a shader texture; one not read is drawn
    opaque and named, with why."""
    try:
        read = shader_density.read(scene, found.densities, lambda fn: render_pass(scene, view_layer, fn))
    finally:
        view_layer.update()  # as after the grid readers
    for source, grid in zip(found.densities, read):
        owner = Owner(source.name, source.parent)
        if isinstance(grid, str):
            found.left_out.add("volume_material", source.name, source.parent, f"{source.material}: {grid}")
            world = source.triangles.reshape(-1, 3) @ source.matrix[:3, :3].T + source.matrix[:3, 3]
            found.owners.append(owner)
            found.triangles.append(world.reshape(-1, 3, 3).astype(np.float32))
            if found.surfaces is not None:
                found.surfaces.append(Surface.opaque(len(source.triangles)))
        elif grid is not None:
            found.grids.append((owner, grid))


def render_pass(scene: "bpy.types.Scene", view_layer: "bpy.types.ViewLayer", fn: Callable[[Any], Any]) -> Any:
    """`fn(depsgraph)` inside the render depsgraph of one view layer: a tiny engine
    "renders" one frame and calls it (the module docstring)."""
    import bpy

    found: dict[str, Any] = {}

    class _Engine(bpy.types.RenderEngine):
        bl_idname = _ENGINE_ID
        bl_label = "OmniWarp geometry"

        def render(self, depsgraph: "bpy.types.Depsgraph") -> None:
            try:
                found["result"] = fn(depsgraph)
                found["mode"] = depsgraph.mode
            # Raised again outside the engine; an interrupt too (a signal's, raised inside
            # this callback, would otherwise end in Blender's C with a traceback).
            except (RuntimeError, ReferenceError, ValueError, KeyError, KeyboardInterrupt) as exc:
                found["error"] = exc

    bpy.utils.register_class(_Engine)
    engine = scene.render.engine
    try:
        scene.render.engine = _ENGINE_ID
        # A signal is only recorded in there (an interrupt raised at the engine callback's
        # first bytecode, before its `try`, ended in Blender's C as "not evaluated for
        # render"); the command's own process still ends at once (core/interrupt.py).
        with interrupt.blocking("render-geometry pass"):
            bpy.ops.render.render(write_still=False, scene=scene.name, layer=view_layer.name)
    finally:
        scene.render.engine = engine
        bpy.utils.unregister_class(_Engine)
    if isinstance(found.get("error"), KeyboardInterrupt):
        raise found["error"]
    if "error" in found:
        raise ReferenceCaptureError(f"reading the render geometry of {scene.name!r} failed: {found['error']}")
    if found.get("mode") != "RENDER":
        raise ReferenceCaptureError(f"the render geometry of {scene.name!r} was not evaluated for render")
    return found["result"]
