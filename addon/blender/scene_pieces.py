"""Hair and points for the viewport's scene cache (scene_cache.py): hair curves (CURVES
objects, and particle hair drawn as paths) and point clouds (POINTCLOUD objects and
geometry nodes' points, instanced or not), read as the reference reads them
(readers/render_geometry.py) and kept as pieces (core/blockers.Pieces) in their
objects' frames, so a move only changes a matrix. They are looked for again when the
depsgraph reports a change, or when the scene's curve shape or the view layer's strands
setting changes."""
from __future__ import annotations

import logging
from typing import Any, Callable

import numpy as np

from ..core.blockers import Pieces, Spheres, Strands, pieces as blocker_pieces
from ..readers.left_out import path_hair_systems
from ..readers.hair import CurveShape, particle_strands, points_or_strands
from .depsgraph_ids import GEOMETRY, Dirty, Key, id_key, matrix_of

log = logging.getLogger(__name__)

# Object types drawn as pieces (hair curves, point clouds).
PIECE_TYPES = ("CURVES", "POINTCLOUD")

Entry = tuple[Pieces, np.ndarray, tuple[str, "str | None"]]  # object-space pieces, world matrix, owner


class ScenePieces:
    """The hair and points of one depsgraph: `held` maps a resident key to its entry."""

    def __init__(self) -> None:
        self.held: dict[str, Entry] = {}
        self._sources: dict[Key, Pieces] = {}  # each source's pieces as last read
        self._settings: tuple[CurveShape, bool] | None = None  # the settings last read with
        self.reads = 0  # sources read (a count for tests)

    def sync(self, depsgraph: Any, dirty: Dirty) -> bool:
        """Bring the hair and points up to date (one pass over the depsgraph's instances,
        only when it reported a change, the curve shape or the layer's strands changed, or
        on first sight); return whether any changed."""
        shape = CurveShape.of(depsgraph.scene)
        hair = bool(getattr(depsgraph.view_layer, "use_strand", True))  # Cycles' "Strands"
        if self._settings == (shape, hair) and not (dirty.objects or dirty.data or dirty.collections):
            return False
        if self._settings and self._settings[0] != shape:
            self._sources.clear()  # ribbons or tubes, straight or not: read again
        self._settings = (shape, hair)
        wanted: dict[str, Entry] = {}
        read: dict[Key, Pieces] = {}
        for inst in depsgraph.object_instances:
            obj = inst.object
            parent = inst.parent if inst.is_instance else None
            if obj.type in PIECE_TYPES and (hair or obj.type != "CURVES"):
                own = parent is None or obj.original != parent.original
                # Geometry-nodes points and curves have no object of their own: their data,
                # read again whenever the object that makes them changes.
                source = id_key(obj) if own else ("data", obj.data.as_pointer())
                stale = _geometry_flagged(obj, dirty) if own else id_key(parent) in dirty.objects
                local = self._piece_source(source, read, lambda: points_or_strands(obj, np.eye(4), shape), stale)
                owner = (obj.original.name_full, None if parent is None else parent.original.name_full)
                place = () if parent is None else (id_key(parent), tuple(inst.persistent_id))
                matrix = matrix_of(inst.matrix_world)
            elif hair and obj.type == "MESH" and parent is None and path_hair_systems(obj):
                # Particle hair is read in world space; a moved emitter is read again.
                source = ("particles", id_key(obj))
                stale = id_key(obj) in dirty.objects or _geometry_flagged(obj, dirty)
                local = self._piece_source(source, read, lambda: particle_strands(obj, shape), stale)
                owner, place, matrix = (obj.original.name_full, None), (), np.eye(4)
            else:
                continue
            if len(local):
                wanted[f"pieces:{source}:{place}"] = (local, matrix, owner)
        self._sources = read
        changed = wanted.keys() != self.held.keys() or any(
            held[0] is not wanted[key][0] or not np.array_equal(held[1], wanted[key][1], equal_nan=True)
            for key, held in self.held.items())
        self.held = wanted
        return changed

    def _piece_source(self, source: Key, read: dict[Key, Pieces], reader: Callable[[], Any],
                      stale: bool) -> Pieces:
        """A source's pieces in its own frame: read once per pass, and kept between passes
        until it is `stale`."""
        if source in read:
            return read[source]
        held = self._sources.get(source)
        if held is None or stale:
            self.reads += 1
            try:
                found = reader()
            except (RuntimeError, ReferenceError) as exc:
                log.warning("could not read hair or points of %s: %s; they cast no shadow", source, exc)
                found = None
            parts = found if isinstance(found, list) else [] if found is None else [found]
            held = Pieces.concatenate([blocker_pieces(part if isinstance(part, Spheres) else None,
                                                      part if isinstance(part, Strands) else None) for part in parts])
        read[source] = held
        return held

    def clear(self) -> bool:
        """Forget everything; return whether anything was held."""
        had = bool(self.held)
        self.held.clear()
        self._sources.clear()
        self._settings = None
        return had


def _geometry_flagged(obj: Any, dirty: Dirty) -> bool:
    """Whether the depsgraph flagged an object's geometry or its data's."""
    data = obj.original.data
    return bool(dirty.objects.get(id_key(obj), 0) & GEOMETRY) or (data is not None and id_key(data) in dirty.data)
