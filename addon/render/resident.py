"""The scene as the GPU keeps it: triangles per object, uploaded once per change.

An object is its vertices in its own frame (relative to its bounding box's centre) and a
float64 affine matrix. A frame uploads nothing for an object whose geometry is unchanged;
a moved object changes only its matrix, a uniform.

Each vertex is stored double-single: hi = float32(p) and lo = float32(p - hi), two
texels. The frame passes the light in the object's frame, split the same way, and the
depth pass forms p - light = (hi - light_hi) + (lo - light_lo) before the matrix: the
light-centred vertex is as precise as float32 allows at its own distance from the light,
however large the object or far the scene is from the origin (a 0.1 mm plate 1 mm from
the light in a 110 m scene keeps its shape), as the host's float64 light-centring did.

What the frame needs from the scene on the host is per object, not per triangle:
the bounding box (the depth range) and the triangle count.

Hair and point clouds are parts of **pieces** (core/blockers.Pieces): a piece
is a sphere swept from a to b, its radius from ra to rb (a sphere: a == b), stored as a
triangle (a, b, a) whose texels' w carry ra, rb and the run of pieces of its curve
(`_piece_uvs`: the exact pass leaves a sample on a curve unshadowed by it). A strand's
pieces are sampled from its curve once, when it is set, not per frame.

See-through materials: an object's triangles of one alpha material are a part
of their own, which carries that `AlphaMap` and each vertex's UV (in the w of its two
texels); the depth pass draws such a part with the alpha variant. The opaque triangles
stay a part as before, drawn by the same programs, so a scene without alpha is
uploaded and drawn exactly as it was.
"""
from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass, field
from itertools import count

import numpy as np

from ..core.alpha import AlphaMap, Surface
from ..core.blockers import Pieces
from ..core.coplanar import overlapping_faces
from ..core.errors import InputError
from ..core.media import GridMedium, Medium
from ..core.projection import MAX_COORDINATE
from .shaders import VERTEX_TEXTURE_WIDTH

log = logging.getLogger(__name__)

_revisions = count(1)  # geometry revisions, unique across scenes: a backend keys uploads on them
_soups = count(1)  # keys of triangle-soup objects, unique across scenes


@dataclass(frozen=True)
class SanitizeCounts:
    """Triangles left out at upload: they can never cast a shadow or be projected."""

    nonfinite: int = 0  # a corner NaN, inf or beyond projection.MAX_COORDINATE
    degenerate: int = 0  # zero area, relative to the object's size

    @property
    def skipped(self) -> int:
        return self.nonfinite + self.degenerate


# Most triangles one vertex texture holds: 2^21 triangles are 6 * 2^21 texels, 6144 rows of
# VERTEX_TEXTURE_WIDTH, within every GL 4.5 GPU's 16384. A larger object is stored as
# several parts (consecutive in Morton order), drawn alike.
MAX_PART_TRIANGLES = 2 ** 21

# Triangles per chunk: the unit of the depth pass's choice between points and quads
# (parameterizations.footprint_ranges). Triangles are stored in Morton order of their
# centroids, so a chunk is a compact cluster with a small bounding sphere.
CHUNK_TRIANGLES = 256


@dataclass(frozen=True)
class Chunks:
    """Bounding spheres (in the object's frame, relative to its origin) and longest edges
    of consecutive runs of CHUNK_TRIANGLES triangles."""

    centres: np.ndarray  # (C, 3)
    radii: np.ndarray  # (C,)
    edges: np.ndarray  # (C,) the longest triangle edge of the chunk

    def __len__(self) -> int:
        return len(self.radii)


def morton_order(tris: np.ndarray) -> np.ndarray:
    """Indices that sort triangles by the Morton code of their centroids (10 bits an axis)."""
    if len(tris) < 2:
        return np.arange(len(tris))
    centroids = tris.mean(axis=1)
    lo, hi = centroids.min(axis=0), centroids.max(axis=0)
    cells = ((centroids - lo) / np.maximum(hi - lo, 1e-300) * 1023.0).astype(np.uint64)
    code = np.zeros(len(tris), dtype=np.uint64)
    for bit in range(10):
        for axis in range(3):
            code |= ((cells[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    return np.argsort(code, kind="stable")


def chunk_bounds(local: np.ndarray) -> Chunks:
    """Per chunk of CHUNK_TRIANGLES consecutive triangles: bounding sphere and longest edge."""
    tris = np.asarray(local, dtype=np.float64)
    count = -(-len(tris) // CHUNK_TRIANGLES)
    if not count:
        return Chunks(np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    # Pad the last chunk with copies of its last triangle: boxes and edges are unchanged.
    padded = np.concatenate([tris, np.repeat(tris[-1:], count * CHUNK_TRIANGLES - len(tris), axis=0)])
    lengths = np.linalg.norm(padded - np.roll(padded, -1, axis=1), axis=2).max(axis=1)
    points = padded.reshape(count, CHUNK_TRIANGLES * 3, 3)
    centres = 0.5 * (points.min(axis=1) + points.max(axis=1))
    radii = np.sqrt(((points - centres[:, None, :]) ** 2).sum(axis=2).max(axis=1))
    return Chunks(centres, radii, lengths.reshape(count, CHUNK_TRIANGLES).max(axis=1))


def piece_chunks(local: np.ndarray, radii: np.ndarray) -> Chunks:
    """`chunk_bounds` of pieces (T, 3, 3) with radii (T, 2): the spheres grown by twice the
    chunk's largest radius (the footprint pass boxes a piece by its oriented bounding box,
    whose corners lie within sqrt(3) r of its axis), the edges by five times it (that
    box's diagonal is below length + (2 + 2 sqrt 2) r)."""
    chunks = chunk_bounds(local)  # of the axes a -> b: a piece's third vertex repeats a
    if not len(chunks):
        return chunks
    count = len(chunks)
    widest = np.asarray(radii, dtype=np.float64).max(axis=1)
    widest = np.concatenate([widest, np.repeat(widest[-1:], count * CHUNK_TRIANGLES - len(widest))])
    widest = widest.reshape(count, CHUNK_TRIANGLES).max(axis=1)
    return Chunks(chunks.centres, chunks.radii + 2.0 * widest, chunks.edges + 5.0 * widest)


def _piece_uvs(extra: np.ndarray) -> np.ndarray:
    """(T, 3, 2): a piece's ra, rb, its curve's run (first, count), whether it is a ribbon
    and whether its curve ends closed, where vertex_texels puts a triangle's UVs: (ra,
    first), (rb, count), (flat, closed), the w of the hi and lo texels of its three
    vertices (lib/vertex_pull.glsl reads them so; indices below 2^21 are exact in float32)."""
    extra = np.asarray(extra, dtype=np.float64)
    uvs = np.zeros((len(extra), 3, 2))
    uvs[:, :2, :] = extra[:, [0, 2, 1, 3]].reshape(-1, 2, 2)
    uvs[:, 2, :] = extra[:, 4:6]
    return uvs


@dataclass
class ResidentObject:
    """One object's triangles in its own frame, and where the frame lies in the world."""

    key: str
    local: np.ndarray  # (T, 3, 3) float64, relative to `origin`, in Morton order (chunks)
    origin: np.ndarray  # (3,) float64, in the object's frame
    matrix: np.ndarray  # (4, 4) float64 object -> world
    revision: int
    counts: SanitizeCounts = SanitizeCounts()
    chunks: Chunks | None = None
    alpha: AlphaMap | None = None  # the part's see-through material; None: opaque
    uvs: np.ndarray | None = None  # (T, 3, 2) float32 with `alpha`, in the order of `local`
    # A part of pieces: (T, 6) ra, rb, the first index and count of the run of the part's
    # pieces that make its curve, 1 for a ribbon, 1 for a curve with closed ends
    # (core/blockers.Pieces); None: triangles.
    piece_data: np.ndarray | None = None
    # A part of a homogeneous medium's closed triangles (core/media.py): no surface, the
    # footprint pass sums its crossings instead of storing a depth; None: a surface.
    medium: Medium | None = None
    # (T,) bool: an opaque part's triangles that another coplanar triangle of the object
    # overlaps (`overlapping_faces`); None: none.
    overlaps: np.ndarray | None = None
    _local_lo: np.ndarray = field(default_factory=lambda: np.zeros(3))
    _local_hi: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def triangles(self) -> int:
        """Primitives the footprint pass draws: triangles, or a part's pieces."""
        return int(len(self.local))

    @property
    def pieces(self) -> bool:
        """Whether this part holds pieces (hair, points) rather than triangles."""
        return self.piece_data is not None

    def offset(self, light_position: np.ndarray) -> np.ndarray:
        """Light-centred world position of the object's origin, in float64."""
        return self.matrix[:3, :3] @ self.origin + self.matrix[:3, 3] - np.asarray(light_position, np.float64)

    def light_local(self, light_position: np.ndarray) -> np.ndarray:
        """The light in the object's frame, relative to `origin` (float64)."""
        linear = self.matrix[:3, :3]
        return np.linalg.solve(linear, np.asarray(light_position, np.float64) - self.matrix[:3, 3]) - self.origin

    def light_split(self, light_position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`light_local` as double-single (hi, lo), as the depth pass takes it."""
        local = self.light_local(light_position)
        hi = local.astype(np.float32)
        return hi, (local - hi.astype(np.float64)).astype(np.float32)

    def light_centred(self, light_position: np.ndarray) -> np.ndarray:
        """(T, 3, 3) float64 light-centred world triangles, formed as the depth pass forms
        them (the light subtracted in the object's frame, then the matrix): a vertex placed
        at the light is exactly 0 here and on the GPU."""
        return (self.local - self.light_local(light_position)) @ self.matrix[:3, :3].T

    def world_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """World box of the transformed local box (8 corners), or None when empty."""
        if not len(self.local):
            return None
        lo, hi = self._local_lo, self._local_hi
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        world = (corners + self.origin) @ self.matrix[:3, :3].T + self.matrix[:3, 3]
        return world.min(axis=0), world.max(axis=0)

    def world_triangles(self) -> np.ndarray:
        """(T, 3, 3) float64 world triangles (for measurement and the unfold path)."""
        return (self.local + self.origin) @ self.matrix[:3, :3].T + self.matrix[:3, 3]

    def vertex_texels(self) -> np.ndarray:
        """The vertex texture: (rows, VERTEX_TEXTURE_WIDTH, 4) float32 (`vertex_texels`)."""
        return vertex_texels(self.local, _piece_uvs(self.piece_data) if self.pieces else self.uvs,
                             self.overlaps)


def vertex_texels(local: np.ndarray, uvs: np.ndarray | None = None,
                  overlaps: np.ndarray | None = None) -> np.ndarray:
    """(T, 3, 3) vertices -> (rows, VERTEX_TEXTURE_WIDTH, 4) float32: vertex i is texels 2i
    (hi = float32(p)) and 2i + 1 (lo = float32(p - hi)); their w hold the vertex's u and v
    when `uvs` (T, 3, 2) are given, else 0, but 1 in the hi texel of the first vertex of
    each triangle that `overlaps` (T,) flags (the exact pass reads it: footprint.vert)."""
    points = np.asarray(local, dtype=np.float64).reshape(-1, 3)
    hi = points.astype(np.float32)
    lo = (points - hi.astype(np.float64)).astype(np.float32)
    rows = max(1, -(-2 * len(points) // VERTEX_TEXTURE_WIDTH))
    texels = np.zeros((rows * VERTEX_TEXTURE_WIDTH, 4), dtype=np.float32)
    texels[0:2 * len(points):2, :3] = hi
    texels[1:2 * len(points):2, :3] = lo
    if uvs is not None:
        corners = np.asarray(uvs, dtype=np.float32).reshape(-1, 2)
        texels[0:2 * len(points):2, 3] = corners[:, 0]
        texels[1:2 * len(points):2, 3] = corners[:, 1]
    elif overlaps is not None:
        texels[0:2 * len(points):6, 3] = np.asarray(overlaps, dtype=np.float32)
    return texels.reshape(rows, VERTEX_TEXTURE_WIDTH, 4)


def _sanitized(triangles: np.ndarray) -> tuple[np.ndarray, SanitizeCounts]:
    """The triangles to keep: not non-finite, not of zero area (tessellate.sanitize's
    scene-only rules), as a boolean mask, with the counts of those left out.

    Triangles whose plane passes through the light cover no texel; the depth pass's
    inside test leaves them out per light, so they are not dropped here.
    """
    tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    finite = np.all(np.isfinite(tris) & (np.abs(tris) < MAX_COORDINATE), axis=(1, 2))
    keep = finite.copy()
    if not finite.any():
        return keep, SanitizeCounts(int(np.count_nonzero(~finite)), 0)
    kept = tris[finite]
    scale = float(np.max(np.abs(kept))) or 1.0
    area2 = np.linalg.norm(np.cross(kept[:, 1] - kept[:, 0], kept[:, 2] - kept[:, 0]), axis=1)
    degenerate = area2 <= (1e-12 * scale) ** 2
    keep[np.flatnonzero(finite)[degenerate]] = False
    return keep, SanitizeCounts(int(np.count_nonzero(~finite)), int(np.count_nonzero(degenerate)))


class ResidentScene:
    """Objects keyed by name; what the backends upload and the depth pass draws."""

    def __init__(self) -> None:
        self.objects: dict[str, ResidentObject] = {}
        # Density grids (core/media.GridMedium, world space), by key: Volume objects' media,
        # marched by the shadow test (lib/grids.glsl).
        self.grids: dict[str, GridMedium] = {}
        self.removed: set[str] = set()  # keys removed since the last sync: the backend frees them
        self.removed_grids: set[str] = set()  # density digests of grids dropped since the last sync
        self._parts: dict[str, list[str]] = {}  # object key -> its parts' keys (set_geometry)
        self._world: tuple[tuple, np.ndarray] | None = None

    @classmethod
    def of_triangles(cls, triangles: np.ndarray, key: str | None = None,
                     surface: Surface | None = None) -> "ResidentScene":
        """A scene of one object holding a world-space triangle soup (identity matrix),
        with its see-through materials when a `surface` is given.

        Its key is unique unless given, so several soups can be resident at once.
        """
        scene = cls()
        scene.set_geometry(key if key is not None else f"soup{next(_soups)}", triangles, surface=surface)
        return scene

    def set_geometry(self, key: str, triangles: np.ndarray, matrix: np.ndarray | None = None,
                     surface: Surface | None = None) -> ResidentObject:
        """Add or replace an object's triangles (in its own frame); the next frame uploads them.

        Beyond MAX_PART_TRIANGLES the object is kept as parts "key", "key#1", ... (one
        texture each), and so are its triangles of each see-through material of `surface`
        (their UVs and material indices, core/alpha.Surface); `set_matrix` and `remove`
        take the key and act on all of them.
        """
        matrix = self._matrix(matrix)  # checked first: a refused matrix leaves the object as it was
        tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        if surface is not None and len(surface) != len(tris):
            raise InputError(f"object {key!r}: {len(tris)} triangles but a surface of {len(surface)}")
        keep, counts = _sanitized(tris)
        groups: list[tuple[AlphaMap | None, Medium | None, np.ndarray]] = []
        if surface is not None and surface.has_media:
            # A medium's triangles are a part of their own each, never opaque (core/media.py).
            for index, medium in enumerate(surface.media):
                chosen = np.flatnonzero(keep & (surface.medium == index))
                if len(chosen) and not medium.clear:
                    groups.append((None, medium, chosen))
            keep = keep & (surface.medium < 0)
        if surface is None or not surface.see_through:
            groups.insert(0, (None, None, np.flatnonzero(keep)))
        else:
            for index in range(-1, len(surface.maps)):
                chosen = np.flatnonzero(keep & (surface.material == index))
                amap = surface.maps[index] if index >= 0 else None
                if amap is not None and amap.opaque:
                    amap = None  # drawn as plain geometry, in a part of its own
                if len(chosen) or index == -1:
                    groups.insert(len(groups) if index >= 0 else 0, (amap, None, chosen))
        self.remove(key)
        keys: list[str] = []
        for amap, medium, chosen in groups:
            order = chosen[morton_order(tris[chosen])]
            # Plain opaque triangles only carry the flag (a see-through part's w holds UVs).
            flags = overlapping_faces(tris[order]) if amap is None and medium is None else None
            for start in range(0, max(len(order), 1), MAX_PART_TRIANGLES):
                picked = order[start:start + MAX_PART_TRIANGLES]
                part_key = key if not keys else f"{key}#{len(keys)}"
                uvs = surface.uvs[picked] if amap is not None else None
                part_flags = None if flags is None or not flags.any() else flags[start:start + MAX_PART_TRIANGLES]
                self._add_part(part_key, tris[picked], matrix, counts if not keys else SanitizeCounts(), amap, uvs,
                               medium=medium, overlaps=part_flags)
                keys.append(part_key)
        self._parts[key] = keys
        return self.objects[key]

    def set_pieces(self, key: str, pieces: Pieces, matrix: np.ndarray | None = None) -> ResidentObject:
        """Add or replace an object of pieces (core/blockers.Pieces: hair and points) in its
        own frame; the next frame uploads them. Pieces not finite or beyond
        projection.MAX_COORDINATE are left out, and so are those of no radius (counted as
        degenerate). Curves are stored whole and together, in the Morton order of their
        first points (so a chunk is a compact cluster of curves); parts as `set_geometry`'s."""
        matrix = self._matrix(matrix)
        tris = np.stack([pieces.a, pieces.b, pieces.a], axis=1)
        radii = np.column_stack([pieces.ra, pieces.rb])
        finite = np.all(np.isfinite(tris) & (np.abs(tris) < MAX_COORDINATE), axis=(1, 2)) \
            & np.all(np.isfinite(radii), axis=1)
        keep = finite & (radii.max(axis=1) > 0.0)
        counts = SanitizeCounts(int(np.count_nonzero(~finite)), int(np.count_nonzero(finite & ~keep)))
        chosen = np.flatnonzero(keep)
        kept = pieces.take(chosen)
        first, count = kept.spans()
        heads = np.flatnonzero(first == np.arange(len(kept)))
        runs = heads[morton_order(tris[chosen][heads])]  # each curve's first piece, in Morton order
        sizes = count[runs]
        # Every curve's pieces in turn: its head plus 0, 1, ... (no Python loop over curves).
        order = np.repeat(runs, sizes) + np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)
        kept = kept.take(order)
        first, count = kept.spans()
        self.remove(key)
        keys: list[str] = []
        for start in range(0, max(len(kept), 1), MAX_PART_TRIANGLES):
            end = min(start + MAX_PART_TRIANGLES, len(kept))
            part_key = key if not keys else f"{key}#{len(keys)}"
            # Each piece's curve as the run of the part's pieces it lies in (a curve cut by
            # the part's end keeps its part's share).
            lo = np.maximum(first[start:end], start)
            hi = np.minimum(first[start:end] + count[start:end], end)
            extra = np.column_stack([np.maximum(kept.ra[start:end], 0.0), np.maximum(kept.rb[start:end], 0.0),
                                     lo - start, hi - lo, kept.flat[start:end], kept.closed[start:end]])
            self._add_part(part_key, np.stack([kept.a[start:end], kept.b[start:end], kept.a[start:end]], axis=1),
                           matrix, counts if not keys else SanitizeCounts(), None, None, extra)
            keys.append(part_key)
        self._parts[key] = keys
        return self.objects[key]

    def _add_part(self, part_key: str, part: np.ndarray, matrix: np.ndarray, counts: SanitizeCounts,
                  amap: AlphaMap | None, uvs: np.ndarray | None, piece_data: np.ndarray | None = None,
                  medium: Medium | None = None, overlaps: np.ndarray | None = None) -> None:
        if len(part):
            lo, hi = part.reshape(-1, 3).min(axis=0), part.reshape(-1, 3).max(axis=0)
        else:
            lo = hi = np.zeros(3)
        origin = 0.5 * (lo + hi)
        local = part - origin
        pieces = piece_data is not None
        chunks = piece_chunks(local, piece_data[:, :2]) if pieces else chunk_bounds(local)
        grow = float(piece_data[:, :2].max()) if pieces and len(piece_data) else 0.0  # boxes reach past the axis
        self.objects[part_key] = ResidentObject(part_key, local, origin, matrix.copy(), next(_revisions), counts,
                                                chunks, amap, uvs, piece_data, medium, overlaps,
                                                lo - origin - grow, hi - origin + grow)
        self.removed.discard(part_key)

    def set_grid(self, key: str, grid: GridMedium) -> None:
        """Add or replace a density grid (a Volume object's medium); the next frame uploads it
        unless a grid of the same digest is held already."""
        if not isinstance(grid, GridMedium):
            raise InputError(f"grid {key!r}: expected a core.media.GridMedium, got {type(grid).__name__}")
        held = self.grids.get(key)
        if held is not None and held.density_digest != grid.density_digest:
            self.removed_grids.add(held.density_digest)
        self.grids[key] = grid

    def subset(self, keys: Iterable[str]) -> "ResidentScene":
        """A scene of some of this scene's objects (by the keys `set_geometry` took), sharing
        them and so their vertex textures: one light's blockers, or what the camera sees.
        Edit the whole scene, never a subset."""
        part = ResidentScene()
        for key in keys:
            if key in self.grids:
                part.grids[key] = self.grids[key]
                continue
            part._parts[key] = list(self._parts[key])
            for part_key in part._parts[key]:
                part.objects[part_key] = self.objects[part_key]
        return part

    def keys(self) -> list[str]:
        """The keys objects and grids were set with (an object's parts share one)."""
        return list(self._parts) + [key for key in self.grids if key not in self._parts]

    def set_matrix(self, key: str, matrix: np.ndarray) -> None:
        """Move an object: no upload, only its uniforms change."""
        matrix = self._matrix(matrix)
        for part_key in self._parts[key]:
            self.objects[part_key].matrix = matrix.copy()

    def remove(self, key: str) -> None:
        """Drop an object (or a grid); the next sync frees its vertex textures (or density)."""
        grid = self.grids.pop(key, None)
        if grid is not None:
            self.removed_grids.add(grid.density_digest)
        for part_key in self._parts.pop(key, ()):
            if self.objects.pop(part_key, None) is not None:
                self.removed.add(part_key)

    @staticmethod
    def _matrix(matrix: np.ndarray | None) -> np.ndarray:
        """A finite, invertible 4x4: the depth pass takes the light into the object's frame."""
        m = np.eye(4) if matrix is None else np.asarray(matrix, dtype=np.float64)
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            raise InputError(f"an object matrix must be a finite 4x4, got shape {m.shape}")
        linear = m[:3, :3]
        if abs(np.linalg.det(linear)) <= 1e-12 * max(float(np.abs(linear).max()), 1e-300) ** 3:
            # A zero scale flattens the object: pass its world triangles with no matrix.
            raise InputError("an object matrix must be invertible (a zero scale flattens it); "
                             "pass its world-space triangles with the identity instead")
        return m

    @property
    def triangles(self) -> int:
        """Resident triangles (pieces not counted)."""
        return sum(obj.triangles for obj in self.objects.values() if not obj.pieces)

    @property
    def pieces(self) -> int:
        """Resident pieces of hair and points."""
        return sum(obj.triangles for obj in self.objects.values() if obj.pieces)

    @property
    def skipped(self) -> int:
        return sum(obj.counts.skipped for obj in self.objects.values())

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """World box of every object's box, or None for an empty scene."""
        boxes = [b for b in (obj.world_bounds() for obj in self.objects.values()) if b is not None]
        if not boxes:
            return None
        return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)

    def state(self) -> tuple:
        """What the scene's geometry is now: each object's key, revision and matrix. Equal
        states hold the same triangles in the same places (a host copy made of them may be kept)."""
        return tuple((key, obj.revision, obj.matrix.tobytes()) for key, obj in self.objects.items())

    def world_triangles(self) -> np.ndarray:
        """All objects' triangles in world space, (T, 3, 3) float64, pieces left out: a host
        copy, for measurement and the unfold method (kept until an object changes or moves)."""
        state = self.state()
        if self._world is None or self._world[0] != state:
            parts = [obj.world_triangles() for obj in self.objects.values()
                     if obj.triangles and not obj.pieces and obj.medium is None]
            self._world = (state, np.concatenate(parts) if parts else np.zeros((0, 3, 3)))
        return self._world[1]
