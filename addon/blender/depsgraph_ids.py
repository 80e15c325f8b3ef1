"""What the viewport's caches (scene_cache.py, scene_pieces.py) call the depsgraph's
objects and changes: a stable key per ID, the flags of what changed, a matrix as numpy."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Hashable

import numpy as np

Key = Hashable

# Dirty flags per object key.
GEOMETRY = 1
TRANSFORM = 2


def id_key(id_data: Any) -> Key:
    """Stable key of an ID: the original's `session_uid`, else its `name_full`.

    Evaluated copies report session_uid 0, so the original is always asked. The
    session_uid survives renames; `name_full` is the fallback for Blender
    versions without it.
    """
    original = getattr(id_data, "original", None) or id_data
    uid = getattr(original, "session_uid", 0)
    return uid if uid else original.name_full


def matrix_of(matrix: Any) -> np.ndarray:
    """A depsgraph matrix as a (4, 4) float64 array."""
    return np.array(matrix, dtype=np.float64).reshape(4, 4)


@dataclass
class Dirty:
    """What `depsgraph_update_post` reported since the last `update`."""

    objects: dict[Key, int] = field(default_factory=dict)
    data: set[Key] = field(default_factory=set)
    collections: set[Key] = field(default_factory=set)

    def clear(self) -> None:
        self.objects.clear()
        self.data.clear()
        self.collections.clear()
