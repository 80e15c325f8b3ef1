"""Depsgraph-backed triangle cache for the viewport preview.

The preview redraws often, but the scene's geometry rarely changes between two
redraws. Reading every evaluated mesh each time would dominate the frame, so
`SceneGeometryCache` keeps the object-space triangles of each object (read once
through `loop_triangles` + `foreach_get`) and its world matrix, and re-reads an
object only when the depsgraph says its geometry changed. A moved object costs
one 4x4 compare and one matmul over its triangles.

What is handled:
- plain objects of the types that have surface geometry (MESH, CURVE, SURFACE,
  META, FONT; modifiers and geometry nodes included, as evaluated), visible in
  the depsgraph's view layer; an instancer whose own geometry is hidden
  (`show_instancer_for_viewport` off) contributes only its instances;
- instances (collection instances, particles, vertex/face instancing, geometry
  nodes instances) from `depsgraph.object_instances`, grouped per instancer
  (`is_instancer`, or any object with a viewport geometry-nodes modifier, since
  `is_instancer` stays False for geometry-nodes instances). A
  group is re-collected as a whole (one pass over the instances) when it is new,
  when its instancer is flagged or moved, when one of its source objects is
  flagged, or when one of its instanced collections is flagged;
- hair curves and point clouds as pieces, one resident object each
  (`scene_pieces.py`);
- density grids (`scene_grids.py`): smoke domains, Volume geometry and meshes whose
  medium's density is a shader texture, as resident grids. Those read through geometry
  nodes wait for `read_grids`, which the viewport runs from a timer (not in the draw).

What is not handled:
- object types without surface triangles, pieces or grids (GREASEPENCIL) contribute
  nothing;
- geometry changes are only seen through the `depsgraph_update_post` flags fed
  to `mark_dirty` (and on first sight of an object): comparing vertex data would
  cost as much as re-reading it. Without a handler, only additions, removals,
  visibility and matrix changes of plain objects and instancers are noticed;
- a moved instancer re-collects its instances instead of only updating matrices
  (particles need not follow their emitter, so there is no safe shortcut), and
  geometry-nodes instance geometry is read again with it.

Non-finite vertices are passed through (the pipeline's sanitiser drops and counts
them); negative scale keeps the triangles as they are (winding does not matter
to shadows); objects without faces contribute 0 triangles.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, Callable, Hashable, Iterable

import bpy
import numpy as np

from ..core.alpha import Surface
from ..core.blockers import Pieces
from ..core.errors import InputError
from ..readers import material_nodes, shader_density
from ..readers.material_alpha import MaterialAlpha, material_alpha
from ..readers.material_media import MediumFound, material_medium
from ..readers.render_geometry import GEOMETRY_TYPES, DensityPart, local_geometry
from ..readers.shadow_rule import rules_for
from ..readers.shadow_rule import shadow_inputs as _shadow_inputs
from ..render.resident import ResidentScene
from . import events
from .depsgraph_ids import GEOMETRY, TRANSFORM, Dirty, Key, id_key, matrix_of
from .scene_grids import SceneGrids
from .scene_pieces import ScenePieces

log = logging.getLogger(__name__)

# Data-block types whose geometry flag means "objects using it need a re-read".
# (Text and surface curves are "CURVE" ids too.)
_GEOMETRY_DATA_TYPES = {"MESH", "CURVE", "META", "CURVES", "POINTCLOUD", "VOLUME"}
_EMPTY_LOCAL = np.zeros((0, 3, 3), dtype=np.float32)
_EMPTY_LOCAL.flags.writeable = False


def _has_nodes_modifier(obj: Any) -> bool:
    """Whether geometry nodes may make instances (`is_instancer` stays False for them)."""
    return any(mod.type == "NODES" and mod.show_viewport for mod in getattr(obj, "modifiers", ()))


def _ray_flags(obj: Any) -> tuple[bool, bool]:
    """The ray-visibility flags the shadow rule reads."""
    original = getattr(obj, "original", None) or obj
    return bool(getattr(original, "visible_shadow", True)), bool(getattr(original, "visible_camera", True))


@dataclass
class _Part:
    """One contribution to `world_triangles`: a plain object or one instancer's instances.

    `sources` pairs object-space triangles (T, 3, 3) float32 with the world
    matrices (N, 4, 4) float64 they are drawn with (N = 1 for a plain object).
    """

    name: str
    matrix: np.ndarray  # world matrix of the object / instancer, for change detection
    sources: list[tuple[np.ndarray, np.ndarray]]
    # Per source: (original object, instancer or None) names, for the shadow rule.
    owners: list[tuple[str, str | None]] = field(default_factory=list)
    data_key: Key | None = None  # original object data (plain objects)
    source_keys: frozenset = frozenset()  # instanced source objects (instance groups)
    collection_keys: frozenset = frozenset()  # instanced collections (instance groups)

    @property
    def count(self) -> int:
        return sum(len(local) * len(matrices) for local, matrices in self.sources)

    def write(self, out: np.ndarray) -> None:
        """Transform into `out` (count, 3, 3) float64: one matmul per source."""
        start = 0
        with np.errstate(invalid="ignore", over="ignore"):  # NaN/inf pass through to the sanitiser
            for local, matrices in self.sources:
                n = len(local) * len(matrices)
                if n == 0:
                    continue
                view = out[start:start + n].reshape(len(matrices), -1, 3)
                corners = local.reshape(1, -1, 3)
                np.matmul(corners, matrices[:, :3, :3].transpose(0, 2, 1), out=view)
                view += matrices[:, None, :3, 3]
                start += n


class SceneGeometryCache:
    """World-space triangles of one depsgraph, kept in step with it incrementally.

    Feed `mark_dirty` with each `DepsgraphUpdate` (the handler in this module
    does), call `update(depsgraph)` before drawing, then `world_triangles()`.
    `stats` counts `geometry_reads` (mesh reads), `matrix_updates` (objects whose
    matrix alone was refreshed), `instance_collections` (instance groups
    re-collected) and `version` (bumped whenever `world_triangles` changes; it
    never goes back, so consumers may cache on it).
    """

    def __init__(self) -> None:
        self._parts: dict[tuple[str, Key], _Part] = {}
        # Instance sources without a plain part: key -> (local triangles, data key).
        self._sources: dict[Key, tuple[np.ndarray, Key | None]] = {}
        self._dirty = Dirty()
        self._identity: tuple[Key, str] | None = None
        self._world: np.ndarray | None = None
        self._layout: dict[tuple[str, Key], tuple[int, int]] = {}
        self._stale: set[tuple[str, Key]] = set()  # parts whose world triangles changed
        self._world_valid = False
        self._selections: dict[Hashable, tuple[int, np.ndarray]] = {}
        self._ray_flags: dict[Key, tuple[bool, bool]] = {}  # last seen (visible_shadow, visible_camera)
        # The same geometry as resident objects (`resident`): one per source and instance.
        self._resident = ResidentScene()
        self._resident_held: dict[str, tuple[np.ndarray, np.ndarray, tuple[str, str | None]]] = {}
        self._resident_version = -1
        self._resident_selections: dict[Hashable, tuple[int, ResidentScene]] = {}
        # See-through materials: each material's alpha as read, and the surface
        # of each read source (by the id of its triangle array, which it keeps alive).
        self._materials: dict[str, MaterialAlpha] = {}
        self._media: dict[str, MediumFound] = {}  # homogeneous media by material (material_media.py)
        self._surfaces: dict[int, tuple[np.ndarray, Surface]] = {}
        self._dirty_materials: set[str] = set()
        self.pieces = ScenePieces()  # hair and points (scene_pieces.py)
        self.grids = SceneGrids()  # density grids (scene_grids.py)
        # Media whose density is a shader texture, by the id of their source's triangle
        # array: (the array, its parts, the read's serial); and which materials are such.
        self._density_parts: dict[int, tuple[np.ndarray, list[DensityPart], int]] = {}
        self._density_materials: dict[str, bool] = {}
        self.stats: dict[str, int] = {
            "geometry_reads": 0, "matrix_updates": 0, "instance_collections": 0, "version": 0,
        }

    # ------------------------------------------------------------------ input
    def mark_dirty(self, update: Any) -> str | None:
        """Record one `DepsgraphUpdate`; return "geometry", "transform", "visibility" or None.

        "visibility": an object's ray visibility (`visible_shadow`, `visible_camera`)
        changed. Blender reports that as a shading update only; the triangles stay,
        but what blocks each light (the shadow rule) changes. The update is only valid
        inside the handler, so its flags are copied now.
        """
        geometry = bool(update.is_updated_geometry)
        transform = bool(update.is_updated_transform)
        id_data = update.id
        id_type = getattr(id_data, "id_type", "")
        key = id_key(id_data)
        if not (geometry or transform):
            if id_type in ("MATERIAL", "IMAGE") and self._alpha_changed(id_data):
                return "geometry"  # the objects using it are read again (update)
            if id_type == "OBJECT" and update.is_updated_shading:
                flags = _ray_flags(id_data)
                if self._ray_flags.get(key) != flags:
                    self._ray_flags[key] = flags
                    return "visibility"
            return None
        if id_type == "OBJECT":
            flags = (GEOMETRY if geometry else 0) | (TRANSFORM if transform else 0)
            self._dirty.objects[key] = self._dirty.objects.get(key, 0) | flags
        elif geometry and id_type in _GEOMETRY_DATA_TYPES:
            self._dirty.data.add(key)
        elif geometry and id_type == "COLLECTION":
            self._dirty.collections.add(key)
        return "geometry" if geometry else "transform"

    def _alpha_changed(self, id_data: Any) -> bool:
        """Whether an edited material (or image) changes a see-through alpha; its users are
        then flagged for a re-read. Materials that never had alpha cost one graph check."""
        original = getattr(id_data, "original", None) or id_data
        if getattr(original, "id_type", "") == "IMAGE":
            names = [n for n, found in self._materials.items() if found.alpha is not None]
        else:
            names = [original.name_full]
        changed = False
        for name in names:
            material = bpy.data.materials.get(name)
            held = self._materials.get(name)
            if material is None or (held is None and not material_nodes.see_through(material)):
                continue
            found = material_alpha(material)
            before = None if held is None or held.alpha is None else (held.alpha.digest, held.uv_map,
                                                                       held.uv_matrix.tobytes())
            after = None if found.alpha is None else (found.alpha.digest, found.uv_map, found.uv_matrix.tobytes())
            if before != after:
                self._materials[name] = found
                self._dirty_materials.add(name)
                changed = True
        return changed | self._medium_changed(original)

    def _medium_changed(self, original: Any) -> bool:
        """Whether an edited material changes a homogeneous medium: its users
        are then flagged for a re-read, as for an alpha."""
        name = getattr(original, "name_full", None)
        material = bpy.data.materials.get(name) if name else None
        if material is None or (name not in self._media and not material_nodes.is_medium(material)):
            return False
        held = self._media.get(name)
        found = material_medium(material)
        key = (lambda f: None if f is None or f[0] is None else f[0].digest)
        if held is not None and key(held) == key(found) and held[1] == found[1]:
            return False
        self._media[name] = found
        self._dirty_materials.add(name)
        return True

    def mark_updates(self, updates: Iterable[Any]) -> tuple[bool, bool]:
        """`mark_dirty` for every update; return (any geometry, any other change to redraw)."""
        geometry = redraw = False
        for update in updates:
            kind = self.mark_dirty(update)
            geometry |= kind == "geometry"
            redraw |= kind in ("transform", "visibility")
        return geometry, redraw

    # ------------------------------------------------------------------ sync
    def update(self, depsgraph: "bpy.types.Depsgraph") -> None:
        """Synchronise with an evaluated depsgraph.

        New objects are read; hidden or deleted ones dropped; flagged ones re-read
        only for geometry flags, otherwise only their matrix is compared and kept.
        """
        identity = (id_key(depsgraph.scene), depsgraph.view_layer.name)
        if identity != self._identity:
            if self._parts:
                log.debug("depsgraph changed from %s to %s; cache cleared", self._identity, identity)
            self.clear()
            self._identity = identity
        changed = False
        seen: set[tuple[str, Key]] = set()
        instancers: dict[Key, Any] = {}
        if self._dirty_materials:
            self._flag_material_users(depsgraph)
        for obj in depsgraph.objects:
            key = id_key(obj)
            if obj.is_instancer or _has_nodes_modifier(obj):
                instancers[key] = obj
                if obj.is_instancer and not obj.show_instancer_for_viewport:
                    continue
            if obj.type not in GEOMETRY_TYPES:
                continue
            part_key = ("object", key)
            seen.add(part_key)
            changed |= self._sync_object(part_key, obj, depsgraph)
        # Drop hidden/deleted objects before the instances look plain objects up.
        changed |= self._drop(lambda k: k[0] == "object" and k not in seen)
        changed |= self._sync_instances(instancers, depsgraph)
        changed |= self._drop(lambda k: k[0] == "instances" and k[1] not in instancers)
        changed |= self.pieces.sync(depsgraph, self._dirty)
        changed |= self.grids.sync(depsgraph, self._dirty, self._density_sources())
        self._dirty.clear()  # flags of objects not seen are moot: they are read afresh on sight
        if changed and self._surfaces:
            live = {id(held[0]) for part in self._parts.values() for held in part.sources}
            live |= {id(held[0]) for held in self._sources.values()}
            for stale in [k for k in self._surfaces if k not in live]:
                del self._surfaces[stale]  # sources no longer held
        if changed and self._density_parts:
            live = {id(held[0]) for part in self._parts.values() for held in part.sources}
            live |= {id(held[0]) for held in self._sources.values()}
            for stale in [k for k in self._density_parts if k not in live]:
                del self._density_parts[stale]
        if changed:
            self._world_valid = False
            self.stats["version"] += 1

    def _flag_material_users(self, depsgraph: Any) -> None:
        """Flag the objects whose slots hold a material whose alpha changed, for a re-read."""
        for obj in depsgraph.objects:
            names = {slot.material.original.name_full for slot in getattr(obj, "material_slots", ())
                     if slot.material is not None}
            if names & self._dirty_materials:
                key = id_key(obj)
                self._dirty.objects[key] = self._dirty.objects.get(key, 0) | GEOMETRY
        self._dirty_materials.clear()
        self._density_materials.clear()

    def surface_of(self, local: np.ndarray) -> Surface | None:
        """The see-through surface (or media) of a source's triangles, or None when opaque."""
        held = self._surfaces.get(id(local))
        return held[1] if held is not None and held[0] is local else None

    def _drop(self, gone: Callable[[tuple[str, Key]], bool]) -> bool:
        """Remove the parts `gone` selects; return whether there were any."""
        keys = [k for k in self._parts if gone(k)]
        for k in keys:
            del self._parts[k]
        return bool(keys)

    def _sync_object(self, part_key: tuple[str, Key], obj: Any, depsgraph: Any) -> bool:
        """Bring one plain object up to date; return whether its triangles changed."""
        matrix = matrix_of(obj.matrix_world)
        part = self._parts.get(part_key)
        data_key = id_key(obj.original.data) if obj.original.data is not None else None
        flags = self._dirty.objects.get(part_key[1], 0)
        if part is None or flags & GEOMETRY or (data_key is not None and data_key in self._dirty.data):
            local = self._read(obj, depsgraph)
            self._parts[part_key] = _Part(obj.name, matrix, [(local, matrix[None])],
                                          [(obj.original.name_full, None)], data_key=data_key)
            self._stale.add(part_key)
            return True
        if np.array_equal(matrix, part.matrix, equal_nan=True):
            return False
        part.matrix = matrix
        part.sources = [(part.sources[0][0], matrix[None])]
        self.stats["matrix_updates"] += 1
        self._stale.add(part_key)
        return True

    def _sync_instances(self, instancers: dict[Key, Any], depsgraph: Any) -> bool:
        """Re-collect the instance groups that may have changed; return whether any did."""
        dirty = self._dirty
        touched_objects = set(dirty.objects)
        todo: dict[Key, Any] = {}
        for key, obj in instancers.items():
            part = self._parts.get(("instances", key))
            if (part is None or key in touched_objects
                    or not part.source_keys.isdisjoint(touched_objects)
                    or not part.collection_keys.isdisjoint(dirty.collections)
                    or not np.array_equal(matrix_of(obj.matrix_world), part.matrix, equal_nan=True)):
                todo[key] = obj
        if todo:
            for key, part in self._collect_instances(todo, depsgraph).items():
                self._parts[("instances", key)] = part
                self._stale.add(("instances", key))
            self.stats["instance_collections"] += len(todo)
        # Keep only the sources that groups still use (and no plain part provides).
        used = set().union(*(p.source_keys for k, p in self._parts.items() if k[0] == "instances"))
        for key in [k for k in self._sources if k not in used or ("object", k) in self._parts]:
            del self._sources[key]
        return bool(todo)

    def _collect_instances(self, instancers: dict[Key, Any], depsgraph: Any) -> dict[Key, _Part]:
        """One pass over `depsgraph.object_instances` for the given instancers."""
        # Per instancer: source key -> (local triangles, list of world matrices).
        groups: dict[Key, dict[Key, tuple[np.ndarray, list[np.ndarray]]]] = {k: {} for k in instancers}
        owners: dict[Key, dict[Key, tuple[str, str | None]]] = {k: {} for k in instancers}
        source_keys: dict[Key, set[Key]] = {k: set() for k in instancers}
        # Geometry-nodes instance geometry has no original object to key on; its
        # evaluated data pointer identifies it during this pass only.
        pass_local: dict[Key, np.ndarray] = {}
        for inst in depsgraph.object_instances:
            if not inst.is_instance or inst.parent is None:
                continue
            parent_key = id_key(inst.parent)
            group = groups.get(parent_key)
            if group is None:
                continue
            obj = inst.object
            if obj.type not in GEOMETRY_TYPES:
                continue
            source_key = id_key(obj)
            if source_key == parent_key:
                data = obj.data
                local_key: Key = ("data", data.as_pointer() if data is not None else obj.as_pointer())
            else:
                local_key = ("object", source_key)
                source_keys[parent_key].add(source_key)
            entry = group.get(local_key)
            if entry is None:
                local = pass_local.get(local_key)
                if local is None:
                    local = self._source_local(local_key, obj, depsgraph)
                    pass_local[local_key] = local
                entry = group[local_key] = (local, [])
                owners[parent_key][local_key] = (obj.original.name_full, inst.parent.original.name_full)
            entry[1].append(matrix_of(inst.matrix_world))
        parts = {}
        for key, obj in instancers.items():
            kept = [local_key for local_key, (local, _) in groups[key].items() if len(local)]
            sources = [(groups[key][k][0], np.stack(groups[key][k][1])) for k in kept]
            collections = obj.original.instance_collection if obj.original.instance_type == "COLLECTION" else None
            coll_keys = set()
            if collections is not None:
                coll_keys = {id_key(collections)} | {id_key(c) for c in collections.children_recursive}
            parts[key] = _Part(obj.name, matrix_of(obj.matrix_world), sources, [owners[key][k] for k in kept],
                               source_keys=frozenset(source_keys[key]), collection_keys=frozenset(coll_keys))
        return parts

    def _source_local(self, local_key: tuple[str, Key], obj: Any, depsgraph: Any) -> np.ndarray:
        """Object-space triangles of an instance source, read at most once per change.

        A visible source is a plain part, already synced in this update. A hidden
        one (e.g. in an excluded collection) is kept in `_sources` until flagged.
        """
        if local_key[0] != "object":
            return self._read(obj, depsgraph)
        key = local_key[1]
        part = self._parts.get(local_key)
        if part is not None:
            return part.sources[0][0]
        cached = self._sources.get(key)
        if cached is not None:
            local, data_key = cached
            if not self._dirty.objects.get(key, 0) & GEOMETRY and data_key not in self._dirty.data:
                return local
        local = self._read(obj, depsgraph)
        data = obj.original.data
        self._sources[key] = (local, id_key(data) if data is not None else None)
        return local

    def _read(self, obj: Any, depsgraph: Any) -> np.ndarray:
        """Read one evaluated object's triangles (counted); a failed read gives none."""
        self.stats["geometry_reads"] += 1
        parts: list[DensityPart] = []
        try:
            local, surface, _ = local_geometry(obj, depsgraph, self._materials, self._media,
                                               (self._density_materials, parts))
        except (RuntimeError, ReferenceError) as exc:
            log.warning("could not read the geometry of %r: %s; it casts no shadow", obj.name, exc)
            return _EMPTY_LOCAL
        if surface.see_through or surface.has_media:
            self._surfaces[id(local)] = (local, surface)
        if parts:  # their triangles are a grid's bounds, no surface (scene_grids.py)
            self._density_parts[id(local)] = (local, parts, self.stats["geometry_reads"])
        return local

    def _density_sources(self):
        """(resident key, signature, source) of every instance of a medium whose density is
        a shader texture (`scene_grids.SceneGrids.sync`); the signature changes when the
        source's triangles are read again."""
        for (kind, key), part in self._parts.items():
            for index, ((local, matrices), owner) in enumerate(zip(part.sources, part.owners)):
                held = self._density_parts.get(id(local))
                if held is None or held[0] is not local:
                    continue
                _, parts, serial = held
                for instance, matrix in enumerate(matrices):
                    for material, triangles, texspace in parts:
                        source = shader_density.DensitySource(owner[0], owner[1], matrix, material, triangles,
                                                              texspace, key=(serial, material))
                        yield f"density:{kind}:{key}:{index}:{instance}:{material}", (serial, material), source

    def read_grids(self, scene: Any, view_layer: Any) -> bool:
        """Read the grids that wait for geometry nodes (`SceneGrids.read_pending`), outside
        any draw; returns whether any was read (the viewport then redraws)."""
        if self._identity != (id_key(scene), view_layer.name) or not self.grids.pending:
            return False
        if not self.grids.read_pending(scene, view_layer):
            return False
        self.stats["version"] += 1
        return True

    # ------------------------------------------------------------------ output
    def world_triangles(self) -> np.ndarray:
        """All cached triangles in world space, (T, 3, 3) float64, read-only.

        The same array object comes back until something changes. Parts that did
        not change are copied from the previous array instead of transformed.
        """
        if self._world_valid and self._world is not None:
            return self._world
        total = sum(part.count for part in self._parts.values())
        out = np.empty((total, 3, 3), dtype=np.float64)
        layout: dict[tuple[str, Key], tuple[int, int]] = {}
        previous = self._world
        start = 0
        for part_key, part in self._parts.items():
            n = part.count
            old = self._layout.get(part_key)
            target = out[start:start + n]
            if previous is not None and part_key not in self._stale and old is not None and old[1] == n:
                target[...] = previous[old[0]:old[0] + n]
            else:
                part.write(target)
            layout[part_key] = (start, n)
            start += n
        out.flags.writeable = False
        self._world, self._layout, self._world_valid = out, layout, True
        self._stale.clear()
        return out

    def select(self, keep: Callable[[str, str | None], bool], key: Hashable) -> np.ndarray:
        """The triangles of the sources whose owner `keep(name, instancer)` accepts (read-only).

        `key` names the selection (a `ShadowRule.key()`): the same key on an unchanged
        cache returns the same array object.
        """
        world = self.world_triangles()
        cached = self._selections.get(key)
        if cached is not None and cached[0] == self.stats["version"]:
            return cached[1]
        pieces = []
        for part_key, part in self._parts.items():
            start = self._layout[part_key][0]
            for (local, matrices), owner in zip(part.sources, part.owners):
                n = len(local) * len(matrices)
                if n and keep(*owner):
                    pieces.append(world[start:start + n])
                start += n
        out = np.concatenate(pieces, axis=0) if pieces else np.zeros((0, 3, 3), dtype=np.float64)
        out.flags.writeable = False
        if len(self._selections) > 16:  # lights come and go; keep the cache small
            self._selections.clear()
        self._selections[key] = (self.stats["version"], out)
        return out

    def resident(self) -> ResidentScene:
        """The cached geometry as a `ResidentScene` kept in step with the cache: one object
        per plain object and per instance, in its own frame with its world matrix.

        A moved object only changes its matrix; only objects whose triangles were read
        again are set anew, so a backend's next sync uploads those alone. Instances of one
        source each hold its triangles (an instance is one object of the scene).
        """
        if self._resident_version == self.stats["version"]:
            return self._resident
        wanted: dict[str, tuple[np.ndarray | Pieces, np.ndarray, tuple[str, str | None]]] = {}
        for (kind, key), part in self._parts.items():
            for index, ((local, matrices), owner) in enumerate(zip(part.sources, part.owners)):
                for instance, matrix in enumerate(matrices):
                    wanted[f"{kind}:{key}:{index}:{instance}"] = (local, matrix, owner)
        wanted.update(self.pieces.held)
        scene = self._resident
        grids = self.grids.held
        for key in [k for k in scene.grids if k not in grids]:
            scene.remove(key)
        for key, (medium, _) in grids.items():
            if scene.grids.get(key) is not medium:
                scene.set_grid(key, medium)
        for key in [k for k in self._resident_held if k not in wanted]:
            scene.remove(key)
            del self._resident_held[key]
        for key, entry in wanted.items():
            local, matrix, _ = entry
            held = self._resident_held.get(key)
            if held is None or held[0] is not local:
                self._set_resident(key, local, matrix)
            elif not np.array_equal(held[1], matrix, equal_nan=True):
                try:
                    scene.set_matrix(key, matrix)
                except InputError:
                    self._set_resident(key, local, matrix)  # now singular: as world triangles
            self._resident_held[key] = entry
        self._resident_version = self.stats["version"]
        self._resident_selections.clear()
        return scene

    def _set_resident(self, key: str, local: "np.ndarray | Pieces", matrix: np.ndarray) -> None:
        if isinstance(local, Pieces):
            try:
                self._resident.set_pieces(key, local, matrix)
            except InputError:  # a zero scale: the pieces have no width, so no shadow
                self._resident.remove(key)
            return
        surface = self.surface_of(local)
        try:
            self._resident.set_geometry(key, local, matrix, surface=surface)
        except InputError:
            # A zero scale or a non-finite matrix: its world triangles (flat, or dropped as
            # non-finite by the scene) with no matrix.
            with np.errstate(invalid="ignore", over="ignore"):
                world = np.asarray(local, np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
            self._resident.set_geometry(key, world, surface=surface)

    def select_resident(self, keep: Callable[[str, str | None], bool], key: Hashable) -> ResidentScene:
        """`select` as a subset of `resident()`: the same objects, already on the GPU."""
        scene = self.resident()
        cached = self._resident_selections.get(key)
        if cached is not None and cached[0] == self._resident_version:
            return cached[1]
        keys = [k for k, (_, _, owner) in self._resident_held.items() if keep(*owner)]
        keys += [k for k, (_, owner) in self.grids.held.items() if keep(*owner)]
        subset = scene.subset(keys)
        self._resident_selections[key] = (self._resident_version, subset)
        return subset

    @property
    def object_count(self) -> int:
        """Cached plain objects plus instance groups."""
        return len(self._parts)

    def clear(self) -> None:
        """Forget all geometry (counters stay, and `version` moves on if anything was cached)."""
        had = bool(self._parts) or (self._world is not None and len(self._world) > 0)
        self._parts.clear()
        self._sources.clear()
        self._surfaces.clear()
        self._density_parts.clear()
        self._density_materials.clear()
        self._materials.clear()
        self._dirty.clear()
        self._layout.clear()
        self._stale.clear()
        self._world = None
        self._world_valid = False
        self._selections.clear()
        self._ray_flags.clear()
        self._identity = None
        for key in list(self._resident_held):  # the next sync frees their textures
            self._resident.remove(key)
        self._resident_held.clear()
        self._resident_selections.clear()
        self._resident_version = -1
        had |= self.pieces.clear()
        had |= self.grids.clear()
        if had:
            self.stats["version"] += 1


CACHE = SceneGeometryCache()


def shadow_inputs(cache: SceneGeometryCache, scene: "bpy.types.Scene",
                  light_names: Iterable[str]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The camera's triangles and each light's occluders from the cache (`shadow_rule.shadow_inputs`)."""
    return _shadow_inputs(cache.select, rules_for(scene, light_names))


def resident_inputs(cache: SceneGeometryCache, scene: "bpy.types.Scene",
                    light_names: Iterable[str]) -> tuple[ResidentScene, dict[str, ResidentScene]]:
    """`shadow_inputs` as subsets of the cache's resident scene: what the viewport draws."""
    return _shadow_inputs(cache.select_resident, rules_for(scene, light_names))


def _notify_viewport(geometry: bool, transform: bool) -> None:
    """Tell the viewport preview (if it listens) what kind of redraw it needs."""
    if geometry or transform:
        events.notify("request_update", "geometry" if geometry else "transform")


@bpy.app.handlers.persistent
def on_depsgraph_update(_scene: "bpy.types.Scene", depsgraph: "bpy.types.Depsgraph") -> None:
    """`depsgraph_update_post`: copy the update flags into `CACHE`, wake the viewport."""
    try:
        geometry, transform = CACHE.mark_updates(depsgraph.updates)
    except ReferenceError as exc:  # an ID freed while the update was being reported
        log.warning("depsgraph update skipped: %s; the cache will be rebuilt", exc)
        CACHE.clear()
        geometry, transform = True, False
    _notify_viewport(geometry, transform)


@bpy.app.handlers.persistent
def on_load_post(*_args: Any) -> None:
    """`load_post`: a new file means new IDs; nothing cached can be trusted."""
    CACHE.clear()


# (handler list name, function) in registration order; unregister walks it backwards.
_HANDLERS: tuple[tuple[str, Callable[..., None]], ...] = (
    ("depsgraph_update_post", on_depsgraph_update),
    ("load_post", on_load_post),
)


def register() -> None:
    """Install the handlers (once, however often this is called)."""
    for list_name, fn in _HANDLERS:
        handlers = getattr(bpy.app.handlers, list_name)
        if fn not in handlers:
            handlers.append(fn)


def unregister() -> None:
    """Remove exactly the handlers `register` added (idempotent) and free the cache."""
    for list_name, fn in reversed(_HANDLERS):
        handlers = getattr(bpy.app.handlers, list_name)
        while fn in handlers:
            handlers.remove(fn)
    CACHE.clear()
