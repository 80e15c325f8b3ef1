"""Density grids for the viewport's scene cache (scene_cache.py).

The viewport draws the grid media the reference reads (readers/render_geometry.py):

- smoke domains (readers/smoke_domains.py), read at once from the simulation;
- Volume geometry (Volume objects, geometry nodes' volumes; volume_grids.py) and meshes
  whose medium's density is a shader texture (shader_density.py). Both are read through
  geometry nodes, which add reader objects to bpy.data and evaluate them: a draw
  callback may not do that. So `sync`, called from the cache's update inside the draw,
  only notes what needs reading (`pending`), and `read_pending`, run from a timer the
  viewport registers (or by a test), reads it and asks for a redraw. Until then those
  grids are missing from the shadows, never another object's.

A grid is read again when its object (or its instancer, or its data) is flagged with a
geometry change, or its material's extinction or grid changed; a moved object keeps its
grid and only its world-to-index matrix moves (`moved`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Callable, Iterable

import numpy as np

from ..core.media import GridMedium
from ..readers import shader_density, smoke_domains, volume_grids
from ..readers.material_media import GridSigma
from ..readers.volume_grids import VolumeSource, volume_source
from .depsgraph_ids import GEOMETRY, Dirty, id_key, matrix_of

log = logging.getLogger(__name__)

Owner = tuple[str, "str | None"]  # the original object, its instancer


@dataclass
class _Held:
    """One grid as read: what it was read from (`signature`), the matrix it was read at,
    the medium (None: an empty grid) and its owner."""

    signature: Any
    matrix: np.ndarray
    medium: GridMedium | None
    owner: Owner


def moved(medium: GridMedium, before: np.ndarray, after: np.ndarray) -> GridMedium:
    """The medium of a grid whose object moved from matrix `before` to `after`."""
    if np.array_equal(before, after):
        return medium
    return medium.moved(medium.to_index @ before @ np.linalg.inv(after))


class SceneGrids:
    """The grid media of one depsgraph: `held` maps a resident key to (medium, owner)."""

    def __init__(self) -> None:
        self._known: dict[str, _Held] = {}
        self.pending: dict[str, VolumeSource | shader_density.DensitySource] = {}
        self.notes: dict[str, str] = {}  # key -> why its grid is not drawn
        self._materials: dict[str, GridSigma] = {}
        self._seen = False
        self.reads = 0  # grids read (a count for tests)

    @property
    def held(self) -> dict[str, tuple[GridMedium, Owner]]:
        return {key: (held.medium, held.owner) for key, held in self._known.items() if held.medium is not None}

    def sync(self, depsgraph: Any, dirty: Dirty, densities: Iterable[tuple[str, Any, shader_density.DensitySource]]
             ) -> bool:
        """Bring the grids up to date with an evaluated depsgraph (only when it reported a
        change, or on first sight); `densities` are (key, signature, source) of the meshes
        whose density is a shader texture. Returns whether a drawn grid changed."""
        if self._seen and not (dirty.objects or dirty.data or dirty.collections):
            return False
        self._seen = True
        self._materials.clear()  # an edited material's extinction is read again
        frame = depsgraph.scene.frame_current
        known, changed = {}, False
        for inst in depsgraph.object_instances:
            obj = inst.object
            if obj.type != "VOLUME" and not smoke_domains.is_gas_domain(obj):
                continue
            parent = inst.parent if inst.is_instance else None
            owner = (obj.original.name_full, None if parent is None else parent.original.name_full)
            key = f"grid:{owner}:{tuple(inst.persistent_id) if parent is not None else ()}"
            matrix = matrix_of(inst.matrix_world)
            stale = _flagged(obj, dirty) or (parent is not None and _flagged(parent, dirty))
            if obj.type == "VOLUME":
                source = volume_source(inst, self._materials)
                if source.why is not None:
                    self.notes[key] = source.why
                    changed |= key in self._known
                    continue
                signature = ("volume", source.grid, source.sigma.tobytes(), source.index_to_object.tobytes(),
                             source.box)
                changed |= self._keep(key, signature, matrix, owner, stale, known, source)
            else:  # a smoke domain: its grid is read at once, no geometry nodes needed
                changed |= self._keep(key, ("smoke", frame), matrix, owner, stale, known,
                                      read=lambda inst=inst: smoke_domains.smoke_medium(inst, frame, self._materials))
        for key, signature, source in densities:
            changed |= self._keep(key, signature, source.matrix, (source.name, source.parent), False, known, source)
        changed |= bool(self._known.keys() - known.keys())
        self._known = known
        self.pending = {key: source for key, source in self.pending.items() if key in known}
        return changed

    def _keep(self, key: str, signature: Any, matrix: np.ndarray, owner: Owner, stale: bool,
              known: dict[str, _Held], source: Any = None,
              read: Callable[[], GridMedium | str | None] | None = None) -> bool:
        """Keep a grid read before (moved if need be); else read it now with `read`, or note
        `source` for `read_pending`. Returns whether the drawn grids changed."""
        held = self._known.get(key)
        if held is not None and held.signature == signature and not stale:
            known[key] = self._move(held, matrix)
            return known[key] is not held
        if read is None:
            self.pending[key] = source
            known[key] = _Held(signature, matrix, None, owner)
            return held is not None and held.medium is not None
        known[key] = _Held(signature, matrix, self._settle(key, read()), owner)
        return True

    def _settle(self, key: str, found: GridMedium | str | None) -> GridMedium | None:
        """A read's medium (None: empty, or not read, its why noted), counted."""
        self.reads += 1
        if isinstance(found, str):
            self.notes[key] = found
            return None
        return found

    @staticmethod
    def _move(held: _Held, matrix: np.ndarray) -> _Held:
        if np.array_equal(held.matrix, matrix):
            return held
        medium = None if held.medium is None else moved(held.medium, held.matrix, matrix)
        return _Held(held.signature, matrix, medium, held.owner)

    def read_pending(self, scene: Any, view_layer: Any) -> bool:
        """Read the grids `sync` noted, through geometry nodes evaluated in the view layer's
        depsgraph (outside any draw: a timer); returns whether any was read."""
        if not self.pending:
            return False
        pending, self.pending = self.pending, {}
        volumes = [(k, s) for k, s in pending.items() if isinstance(s, VolumeSource)]
        densities = [(k, s) for k, s in pending.items() if not isinstance(s, VolumeSource)]

        def evaluated(fn: Callable[[Any], Any]) -> Any:
            view_layer.update()
            return fn(view_layer.depsgraph)

        found: list[tuple[str, GridMedium | str | None]] = []
        try:
            if volumes:
                found += zip([k for k, _ in volumes], volume_grids.read(scene, [s for _, s in volumes], evaluated))
            if densities:
                found += zip([k for k, _ in densities],
                             shader_density.read(scene, [s for _, s in densities], evaluated))
        finally:
            view_layer.update()  # without the readers
        for key, medium in found:
            held = self._known.get(key)
            if held is not None:  # else gone since
                self._known[key] = _Held(held.signature, held.matrix, self._settle(key, medium), held.owner)
        return bool(found)

    def clear(self) -> bool:
        """Forget every grid; returns whether any was held."""
        had = bool(self._known)
        self._known.clear()
        self.pending.clear()
        self.notes.clear()
        self._materials.clear()
        self._seen = False
        return had


def _flagged(obj: Any, dirty: Dirty) -> bool:
    """Whether the depsgraph reported a geometry change of an object or its data."""
    data = getattr(obj.original, "data", None)
    return bool(dirty.objects.get(id_key(obj), 0) & GEOMETRY) or (data is not None and id_key(data) in dirty.data)
