"""Blockers that are not triangles, as Cycles intersects them: spheres and strands.

Each kind is one object holding its world-space data and the one question a shadow
asks of it: which segments (from a view sample towards the light) it crosses. These are
the numpy oracle the GPU passes are held to, what the reference stores of a
scene's point clouds and hair, and, as **Pieces**, what the GPU draws of both.

- **Spheres** (point clouds): a centre and a radius each; Cycles intersects each point
  as a sphere.
- **Strands** (hair curves): control points with a radius each, in curves given by
  offsets. Cycles draws a strand as a sphere of the interpolated radius swept along the
  curve through the control points (its "3D curves"; its ribbons face the ray with the
  same width, so a shadow ray passing within the radius of the centre line meets
  either): a uniform Catmull-Rom spline, the first and last points repeated as the end
  tangents' neighbours, for hair's own curve type; straight pieces between the points
  for a poly curve (`linear`; measured against Cycles 5.2.3 on spirals of a few points a
  turn: the polyline matched to the pixel, the spline missed 125 of 18,103 pixels).
  `Strands.pieces` samples each span into short pieces; a segment crosses the strand
  where it passes within a piece's interpolated radius of the piece.

A hit closer to the segment's start than `eps` of its length is left out: the receiver's
own surface, as the exact pass leaves it out (passes/exact.EXACT_EPS); and a segment that
starts on a curve (or a point's sphere) is never blocked by it (Cycles' rays skip the
primitive they leave, and a curve is one primitive). Which curve a start lies on is told
by its normal (Cycles' true normal, as the view samples carry it): a round curve's point
lies on its tube with the normal along the direction from the axis, a ribbon's lies in
the plane through the axis that faces the camera ray, its true normal. A start inside
another curve's tube is shadowed by it. Cycles' tube ends at a curve's ends in the plane
across its axis, with no half sphere past it (`Pieces.end_planes`), and it ignores a
ribbon's hits nearer than RIBBON_AVOIDANCE radii. Measured against Cycles 5.2.3 in the
notebook (docs/notebook/2026-12-hair-points.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Pieces a Catmull-Rom span is sampled into: the chord's sag below a piece is about
# (span length)^2 * curvature / (8 * 16^2), far below a strand's radius for hair.
PIECES_PER_SPAN = 16
# The GPU's pieces (`Strands.pieces(None)`, `pieces(adaptive=True)`): as few a span as keep
# the chords' sag below this share of the curve's thickest radius, at most PIECES_PER_SPAN.
# (The thinnest would be 0 at a closed tip: every tapering strand at the most pieces.)
SAG_SHARE = 0.05


@dataclass(frozen=True)
class Pieces:
    """Spheres swept from `a` to `b` (N, 3), their radius from `ra` to `rb` (N,), as the
    GPU draws hair and points (a sphere: a == b), world space, float64, each of one
    `curve` (N,) int: a strand's pieces share their strand's, a sphere has its own; a
    curve's pieces are consecutive.

    `flat` (N,) bool: a piece of a curve Cycles draws as a ribbon (the scene's curve shape);
    None: all round. `closed` (N,) bool: a piece of a curve that ends in half spheres (a
    poly curve, which Cycles 5.x draws as round linear segments whatever the shape:
    Strands.pieces); None: none (a Catmull-Rom curve's tube ends flat, `end_planes`).

    A segment that starts on a curve (`on_curve`) is never blocked by that curve: Cycles
    never shadows a point with the primitive it lies on, and its primitive is the whole
    curve (Cycles packs the segment into the type, the prim is the curve). Measured on
    tests/support/make_left_out_blend.py --blockers at 5.2.3: with the span as the
    primitive 39 (ribbons) and 9 (3D curves) of about 18,000 pixels differ from Cycles,
    with the curve 15 and 4."""

    a: np.ndarray
    b: np.ndarray
    ra: np.ndarray
    rb: np.ndarray
    curve: np.ndarray
    flat: np.ndarray | None = None
    closed: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ("a", "b"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=np.float64).reshape(-1, 3))
        for name in ("ra", "rb"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=np.float64).reshape(-1))
        object.__setattr__(self, "curve", np.asarray(self.curve, dtype=np.int64).reshape(-1))
        for name in ("flat", "closed"):
            given = getattr(self, name)
            object.__setattr__(self, name, np.asarray(np.zeros(len(self.curve), dtype=bool) if given is None else given,
                                                      dtype=bool).reshape(-1))
        sizes = {len(getattr(self, name)) for name in _PIECE_FIELDS}
        if len(sizes) != 1:
            raise ValueError(f"pieces of unequal lengths: {sorted(sizes)}")

    def __len__(self) -> int:
        return len(self.ra)

    @classmethod
    def empty(cls) -> "Pieces":
        return cls(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0, np.int64))

    def take(self, index: np.ndarray) -> "Pieces":
        """The pieces at `index` (an index array or a mask), in its order."""
        return Pieces(*(getattr(self, name)[index] for name in _PIECE_FIELDS))

    @classmethod
    def concatenate(cls, parts: "list[Pieces]") -> "Pieces":
        """The parts in order, their curves numbered on (each part's curves stay its own)."""
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls.empty()
        curves, base = [], 0
        for part in parts:
            curves.append(part.curve - part.curve.min() + base)
            base = int(curves[-1].max()) + 1
        return cls(*(np.concatenate([getattr(p, name) for p in parts]) for name in _PIECE_FIELDS[:4]),
                   np.concatenate(curves), np.concatenate([p.flat for p in parts]),
                   np.concatenate([p.closed for p in parts]))

    def spans(self) -> tuple[np.ndarray, np.ndarray]:
        """(first, count) (N,) each: the run of consecutive pieces of each piece's curve."""
        n = len(self)
        if not n:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        starts = np.flatnonzero(np.r_[True, self.curve[1:] != self.curve[:-1]])
        counts = np.diff(np.r_[starts, n])
        run = np.repeat(np.arange(len(starts)), counts)
        return starts[run], counts[run]

    def crossed(self, starts: np.ndarray, ends: np.ndarray, eps: float = 1e-4,
                normals: np.ndarray | None = None) -> np.ndarray:
        """(M,) whether each segment start -> end meets a piece beyond `eps` of its length
        from the start, not of a curve it starts on (`on_curve`, with the starts' unit
        `normals`; None: the starts lie on no curve)."""
        return _crossed(starts, ends, self.a, self.b, self.ra, self.rb, eps, own=self, normals=normals,
                        flat=self.flat, planes=self.end_planes(), tangents=self.joint_tangents())

    def holds(self, points: np.ndarray, grow: float = 1.0) -> np.ndarray:
        """(M,) whether each point lies within `grow` times a piece's radius of it."""
        return _held(points, self.a, self.b, self.ra * grow, self.rb * grow)

    def end_planes(self) -> np.ndarray:
        """(N, 2, 4): the planes that end each piece's curve, at its first and its last
        point, across its direction there, each as (n, w) with n . x + w >= 0 on the
        curve's side. Cycles ends a Catmull-Rom curve's tube so (kernel/geom/
        curve_intersect.h's cap planes): no half sphere reaches past its ends, whatever
        piece's it would be. Zero (no cut) for a point and for a closed (linear) curve."""
        first, count = self.spans()
        last = first + count - 1
        out = np.zeros((len(self), 2, 4))
        for side, index, sign, at in ((0, first, 1.0, self.a), (1, last, -1.0, self.b)):
            direction = self.b[index] - self.a[index]
            length = np.linalg.norm(direction, axis=1, keepdims=True)
            normal = sign * np.divide(direction, length, out=np.zeros_like(direction), where=length > 0.0)
            normal[self.closed] = 0.0
            out[:, side, :3] = normal
            out[:, side, 3] = -np.einsum("ij,ij->i", normal, at[index])
        return out

    def joint_tangents(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) each: the curve's direction at a piece's a end and at its b end, the
        bisector of its own and its neighbour's (its own at the curve's ends). A ribbon's
        stretch ends across them: Cycles' strip bends with the curve, with no gap or
        overlap at a joint."""
        own = self.b - self.a
        length = np.linalg.norm(own, axis=1, keepdims=True)
        unit = np.divide(own, length, out=np.zeros_like(own), where=length > 0.0)
        first, count = self.spans()
        index = np.arange(len(self))
        before = np.where(index > first, index - 1, index)
        after = np.where(index < first + count - 1, index + 1, index)
        at_a, at_b = unit[before] + unit, unit + unit[after]
        return at_a, at_b

    def on_curve(self, points: np.ndarray, normals: np.ndarray, pieces: np.ndarray) -> np.ndarray:
        """Pairwise: whether point m, of unit normal normals[m], lies on the curve of piece
        pieces[m]: on the surface of one of its pieces as Cycles intersects it (`_on_piece`)."""
        first, count = self.spans()
        planes = self.end_planes()
        out = np.zeros(len(points), dtype=bool)
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        longest = int(count[pieces].max()) if len(pieces) else 0
        for step in range(longest):
            live = np.flatnonzero(~out & (step < count[pieces]))
            if not len(live):
                break
            j = first[pieces[live]] + step
            out[live] = _on_piece(p[live], n[live], self.a[j], self.b[j], self.ra[j], self.rb[j], self.flat[j],
                                  planes[j])
        return out


_PIECE_FIELDS = ("a", "b", "ra", "rb", "curve", "flat", "closed")


@dataclass(frozen=True)
class Spheres:
    """Spheres (N,) of `centres` (N, 3) and `radii` (N,), world space, float64."""

    centres: np.ndarray
    radii: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "centres", np.asarray(self.centres, dtype=np.float64).reshape(-1, 3))
        object.__setattr__(self, "radii", np.asarray(self.radii, dtype=np.float64).reshape(-1))
        if len(self.centres) != len(self.radii):
            raise ValueError(f"{len(self.centres)} sphere centres but {len(self.radii)} radii")

    def __len__(self) -> int:
        return len(self.radii)

    @classmethod
    def empty(cls) -> "Spheres":
        return cls(np.zeros((0, 3)), np.zeros(0))

    @classmethod
    def concatenate(cls, parts: "list[Spheres]") -> "Spheres":
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls.empty()
        return cls(np.concatenate([p.centres for p in parts]), np.concatenate([p.radii for p in parts]))

    def pieces(self) -> Pieces:
        """Each sphere as a piece of no length, a curve of its own."""
        return Pieces(self.centres, self.centres, self.radii, self.radii, np.arange(len(self)))

    def crossed(self, starts: np.ndarray, ends: np.ndarray, eps: float = 1e-4,
                normals: np.ndarray | None = None) -> np.ndarray:
        """(M,) whether each segment start -> end meets a sphere beyond `eps` of its length
        from the start (not the sphere it starts on: Pieces.crossed)."""
        return self.pieces().crossed(starts, ends, eps, normals)

    def holds(self, points: np.ndarray, grow: float = 1.0) -> np.ndarray:
        """(M,) whether each point lies on or in a sphere of `grow` times its radius."""
        return self.pieces().holds(points, grow)


@dataclass(frozen=True)
class Strands:
    """Curves through `points` (P, 3) with `radii` (P,), curve k being the points
    offsets[k]:offsets[k + 1] (at least two each), world space."""

    points: np.ndarray
    radii: np.ndarray
    offsets: np.ndarray
    linear: np.ndarray | None = None  # (C,) bool: a poly curve, straight between its points
    flat: np.ndarray | None = None  # (C,) bool: the scene draws curves as ribbons (not its linear ones)

    def __post_init__(self) -> None:
        object.__setattr__(self, "points", np.asarray(self.points, dtype=np.float64).reshape(-1, 3))
        object.__setattr__(self, "radii", np.asarray(self.radii, dtype=np.float64).reshape(-1))
        object.__setattr__(self, "offsets", np.asarray(self.offsets, dtype=np.int64).reshape(-1))
        linear = np.zeros(max(len(self.offsets) - 1, 0), dtype=bool) if self.linear is None else self.linear
        object.__setattr__(self, "linear", np.asarray(linear, dtype=bool).reshape(-1))
        flat = np.zeros_like(self.linear) if self.flat is None else self.flat
        object.__setattr__(self, "flat", np.asarray(flat, dtype=bool).reshape(-1))
        if not len(self.linear) == len(self.flat) == max(len(self.offsets) - 1, 0):
            raise ValueError(f"{len(self.linear)} curve types and {len(self.flat)} shapes for "
                             f"{len(self.offsets) - 1} curves")
        if len(self.points) != len(self.radii):
            raise ValueError(f"{len(self.points)} strand points but {len(self.radii)} radii")
        if len(self.offsets) < 1 or self.offsets[0] != 0 or self.offsets[-1] != len(self.points) \
                or np.any(np.diff(self.offsets) < 1):
            raise ValueError("strand offsets must rise from 0 to the point count")

    def __len__(self) -> int:
        return len(self.offsets) - 1

    @classmethod
    def empty(cls) -> "Strands":
        return cls(np.zeros((0, 3)), np.zeros(0), np.zeros(1, dtype=np.int64))

    @classmethod
    def concatenate(cls, parts: "list[Strands]") -> "Strands":
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls.empty()
        offsets, base = [np.zeros(1, dtype=np.int64)], 0
        for part in parts:
            offsets.append(part.offsets[1:] + base)
            base += len(part.points)
        return cls(np.concatenate([p.points for p in parts]), np.concatenate([p.radii for p in parts]),
                   np.concatenate(offsets), np.concatenate([p.linear for p in parts]),
                   np.concatenate([p.flat for p in parts]))

    def curve_pieces(self, k: int, pieces: int | None = PIECES_PER_SPAN) -> Pieces:
        """Curve k's spans sampled into `pieces` pieces each (None: as few as keep the sag
        below SAG_SHARE of its thickest radius), all of curve 0. A curve of one point is a
        sphere."""
        lo, hi = int(self.offsets[k]), int(self.offsets[k + 1])
        points, radii = self.points[lo:hi], self.radii[lo:hi]
        if len(points) == 1:
            return Spheres(points, radii).pieces()  # a point is a sphere whatever the shape
        if pieces is None:
            pieces = 1 if self.linear[k] else _spline_pieces(points, radii)
        t = np.linspace(0.0, 1.0, pieces + 1)
        if self.linear[k]:
            weights = np.stack([np.zeros_like(t), 1.0 - t, t, np.zeros_like(t)], axis=1)
        else:
            weights = catmull_rom_basis(t)  # (pieces + 1, 4)
        index = np.arange(len(points) - 1)
        controls = np.stack([np.maximum(index - 1, 0), index, index + 1, np.minimum(index + 2, len(points) - 1)],
                            axis=1)  # (S, 4): the ends repeated
        curve = np.einsum("tj,sjc->stc", weights, points[controls])  # (S, pieces + 1, 3)
        width = np.maximum(np.einsum("tj,sj->st", weights, radii[controls]), 0.0)
        return Pieces(curve[:, :-1].reshape(-1, 3), curve[:, 1:].reshape(-1, 3), width[:, :-1].reshape(-1),
                      width[:, 1:].reshape(-1), np.zeros(len(index) * pieces, np.int64),
                      np.full(len(index) * pieces, bool(self.flat[k] and not self.linear[k])),
                      np.full(len(index) * pieces, bool(self.linear[k])))

    def pieces(self, pieces: int | None = PIECES_PER_SPAN) -> Pieces:
        """Every curve's `curve_pieces`, in curve order, curve k numbered k: worked out a
        group of curves at a time (the same point count, pieces a span and type), so that
        100,000 strands take numpy calls, not Python loops."""
        sizes = np.diff(self.offsets)
        if not len(sizes):
            return Pieces.empty()
        per_span = np.ones(len(sizes), np.int64)
        if pieces is not None:
            per_span[:] = pieces
        parts = []
        for n in np.unique(sizes):
            curves = np.flatnonzero(sizes == n)
            points = self.points[self.offsets[curves][:, None] + np.arange(n)]  # (C, n, 3)
            radii = self.radii[self.offsets[curves][:, None] + np.arange(n)]
            if n == 1:
                parts.append((curves, Pieces(points[:, 0], points[:, 0], radii[:, 0], radii[:, 0], curves)))
                continue
            if pieces is None:
                per_span[curves] = np.where(self.linear[curves], 1, _spline_pieces_many(points, radii))
            for count in np.unique(per_span[curves]):
                for linear in (False, True):
                    pick = (per_span[curves] == count) & (self.linear[curves] == linear)
                    if pick.any():
                        parts.append((curves[pick], _sampled(points[pick], radii[pick], int(count), linear,
                                                             curves[pick], self.flat[curves[pick]] & (not linear))))
        merged = Pieces.concatenate([part for _, part in parts])
        curve = np.concatenate([part.curve for _, part in parts])
        order = np.argsort(curve, kind="stable")  # back in curve order, each curve's pieces in turn
        return Pieces(merged.a[order], merged.b[order], merged.ra[order], merged.rb[order], curve[order],
                      merged.flat[order], merged.closed[order])

    def holds(self, points: np.ndarray, grow: float = 1.0, pieces: int | None = PIECES_PER_SPAN) -> np.ndarray:
        """(M,) whether each point lies on or in a strand of `grow` times its radius."""
        return self.pieces(pieces).holds(points, grow)

    def crossed(self, starts: np.ndarray, ends: np.ndarray, eps: float = 1e-4,
                normals: np.ndarray | None = None, pieces: int | None = PIECES_PER_SPAN) -> np.ndarray:
        """(M,) whether each segment start -> end meets a strand beyond `eps` of its length
        from the start, not the curve it starts on (Pieces.crossed). Each curve's pieces are
        tested only against the segments that pass through its bounding sphere."""
        p = np.asarray(starts, dtype=np.float64).reshape(-1, 3)
        q = np.asarray(ends, dtype=np.float64).reshape(-1, 3)
        n = None if normals is None else np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        out = np.zeros(len(p), dtype=bool)
        for k in range(len(self) if len(p) else 0):
            part = self.curve_pieces(k, pieces)
            ends_k = np.concatenate([part.a, part.b])
            lo, hi = ends_k.min(axis=0), ends_k.max(axis=0)
            centre = np.broadcast_to(0.5 * (lo + hi), p.shape)
            reach = np.full(len(p), 0.5 * float(np.linalg.norm(hi - lo)) + float(max(part.ra.max(), part.rb.max())))
            # The segments that pass through the curve's bounding sphere: a sphere's own test.
            near = np.flatnonzero(_segment_capsule(p, q, centre, centre, reach, reach, 0.0))
            if len(near):
                out[near] |= part.crossed(p[near], q[near], eps, None if n is None else n[near])
        return out


def pieces(spheres: "Spheres | None", strands: "Strands | None", adaptive: bool = True) -> Pieces:
    """Every sphere and strand piece, as the GPU draws them (the strands' spans in as few
    pieces as keep SAG_SHARE with `adaptive`)."""
    parts = []
    if spheres is not None and len(spheres):
        parts.append(spheres.pieces())
    if strands is not None and len(strands):
        parts.append(strands.pieces(None if adaptive else PIECES_PER_SPAN))
    return Pieces.concatenate(parts)


def _spline_pieces(points: np.ndarray, radii: np.ndarray) -> int:
    """Pieces a span of this Catmull-Rom curve needs (`_spline_pieces_many` of one curve)."""
    return int(_spline_pieces_many(points[None], radii[None])[0])


# The counts a span's pieces are chosen from, fewest first (PIECES_PER_SPAN the last).
_PIECE_COUNTS = (1, 2, 3, 4, 6, 8, 12, PIECES_PER_SPAN)
# Curves whose sag is measured at once.
_SAG_BATCH = 4096


def _spline_pieces_many(points: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Pieces a span each of curves (C, n, 3) with radii (C, n) need: the fewest of
    _PIECE_COUNTS whose chords sag below SAG_SHARE of the curve's thickest radius, the sag
    measured at each piece's middle (where a span's near-parabolic arc is farthest from
    its chord). Measured, not bounded by |C''|: a curve's repeated end points bend its
    parameter without bending the curve, which a bound counts as sag."""
    count, n = radii.shape
    if n < 2:
        return np.ones(count, dtype=np.int64)
    if count > _SAG_BATCH:  # memory: each candidate count evaluates (C, spans, pieces, 3) points
        return np.concatenate([_spline_pieces_many(points[k:k + _SAG_BATCH], radii[k:k + _SAG_BATCH])
                               for k in range(0, count, _SAG_BATCH)])
    out = np.full(count, PIECES_PER_SPAN, dtype=np.int64)
    index = np.arange(n - 1)
    controls = points[:, np.stack([np.maximum(index - 1, 0), index, index + 1, np.minimum(index + 2, n - 1)],
                                  axis=1)]  # (C, S, 4, 3)
    tolerance = SAG_SHARE * np.maximum(radii.max(axis=1), 1e-12)
    open_ = np.ones(count, dtype=bool)
    for pieces in _PIECE_COUNTS[:-1]:
        ends = np.einsum("tj,csjk->cstk", catmull_rom_basis(np.linspace(0.0, 1.0, pieces + 1)), controls)
        mids = np.einsum("tj,csjk->cstk", catmull_rom_basis((np.arange(pieces) + 0.5) / pieces), controls)
        a, b = ends[:, :, :-1], ends[:, :, 1:]
        chord = b - a
        length2 = np.einsum("cstk,cstk->cst", chord, chord)
        along = np.clip(np.einsum("cstk,cstk->cst", mids - a, chord) / np.maximum(length2, 1e-300), 0.0, 1.0)
        sag = np.linalg.norm(mids - (a + along[..., None] * chord), axis=-1).max(axis=(1, 2))
        fits = open_ & (sag <= tolerance)
        out[fits] = pieces
        open_ &= ~fits
        if not open_.any():
            break
    return out


def _sampled(points: np.ndarray, radii: np.ndarray, pieces: int, linear: bool, curves: np.ndarray,
             flat: np.ndarray) -> Pieces:
    """Curves (C, n, 3) of one type, their spans sampled into `pieces` pieces each, as in
    `Strands.curve_pieces`; curve c numbered curves[c], a ribbon where flat[c], closed at
    its ends where linear."""
    count, n = radii.shape
    t = np.linspace(0.0, 1.0, pieces + 1)
    if linear:
        weights = np.stack([np.zeros_like(t), 1.0 - t, t, np.zeros_like(t)], axis=1)
    else:
        weights = catmull_rom_basis(t)
    index = np.arange(n - 1)
    controls = np.stack([np.maximum(index - 1, 0), index, index + 1, np.minimum(index + 2, n - 1)], axis=1)
    curve = np.einsum("tj,csjk->cstk", weights, points[:, controls])  # (C, S, pieces + 1, 3)
    width = np.maximum(np.einsum("tj,csj->cst", weights, radii[:, controls]), 0.0)
    return Pieces(curve[:, :, :-1].reshape(-1, 3), curve[:, :, 1:].reshape(-1, 3), width[:, :, :-1].reshape(-1),
                  width[:, :, 1:].reshape(-1), np.repeat(curves, (n - 1) * pieces), np.repeat(flat, (n - 1) * pieces),
                  np.full(count * (n - 1) * pieces, linear))


def catmull_rom_basis(t: np.ndarray) -> np.ndarray:
    """(len(t), 4) weights of P0..P3 of the uniform Catmull-Rom spline at t in [0, 1]
    (the curve runs from P1 to P2)."""
    t = np.asarray(t, dtype=np.float64)[:, None]
    t2, t3 = t * t, t * t * t
    return 0.5 * np.concatenate([-t3 + 2.0 * t2 - t, 3.0 * t3 - 5.0 * t2 + 2.0, -3.0 * t3 + 4.0 * t2 + t,
                                 t3 - t2], axis=1)


# Segment pairs tested at once (memory: a few arrays of this many float64).
_BATCH = 4_000_000

# A point lies on a piece's surface as Cycles intersects it (`_on_piece`) within this
# share of the piece's radius: above SAG_SHARE, so that a point on Cycles' curve lies on
# the pieces drawn for it.
OWN_SLACK = 0.1
# A round piece's point has its normal within this cosine of the direction from the axis,
# either way (about 8 degrees; a chord within SAG_SHARE of the curve turns it by under 3).
OWN_COS = 0.99
# Cycles ignores a ribbon's hit nearer the ray's start than this many radii (its
# self-intersection avoidance, kernel/geom/curve_intersect.h).
RIBBON_AVOIDANCE = 2.0


def _crossed(starts: np.ndarray, ends: np.ndarray, a: np.ndarray, b: np.ndarray, ra: np.ndarray,
             rb: np.ndarray, eps: float, own: "Pieces | None" = None, normals: np.ndarray | None = None,
             flat: np.ndarray | None = None, planes: np.ndarray | None = None,
             tangents: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(M,) whether segment m (starts -> ends) meets capsule k (a -> b, radius from ra to rb
    along it; a ribbon where flat[k], its stretch ending across the joint `tangents`, cut
    by its curve's end `planes`: `_segment_capsule`) beyond `eps` of its length from its
    start, and does not start on its curve (`own`, the Pieces that a..rb are, with the
    starts' `normals`: Pieces.on_curve; either None: every capsule blocks). Each capsule
    is first tested against the bounding sphere of each segment."""
    p = np.asarray(starts, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(ends, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(p), dtype=bool)
    if not len(p) or not len(a):
        return out
    by_curve = own is not None and normals is not None
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3) if by_curve else None
    mid, half = 0.5 * (p + q), 0.5 * np.linalg.norm(q - p, axis=1)
    c_mid, c_half = 0.5 * (a + b), 0.5 * np.linalg.norm(b - a, axis=1) + np.maximum(ra, rb)
    step = max(1, _BATCH // len(a))
    for first in range(0, len(p), step):
        rows = slice(first, first + step)
        near = np.linalg.norm(mid[rows, None, :] - c_mid[None], axis=2) <= half[rows, None] + c_half[None]
        m, k = np.nonzero(near)
        if not len(m):
            continue
        hit = _segment_capsule(p[rows][m], q[rows][m], a[k], b[k], ra[k], rb[k], eps,
                               None if flat is None else flat[k],
                               None if planes is None else planes[k],
                               None if tangents is None else (tangents[0][k], tangents[1][k]))
        m, k = m[hit], k[hit]
        if by_curve and len(m):
            keep = ~own.on_curve(p[rows][m], n[rows][m], k)
            m = m[keep]
        out[first + np.unique(m)] = True
    return out


def _segment_capsule(p, q, a, b, ra, rb, eps, flat=None, planes=None, tangents=None):
    """Pairwise: segment p -> q, from `eps` of its length on, within the capsule a -> b
    (radius ra -> rb along it, sphere ends): the closest points of the two segments
    (Ericson, Real-Time Collision Detection 5.1.9) and the radius at the capsule's one.
    `planes` (M, 2, 4): the planes that end the capsule's curve (Pieces.end_planes), where
    Cycles' tube ends: a round capsule is met only on their curve's side (`_capped_tube`).
    Where `flat`, a ribbon (`_segment_ribbon`, its `tangents` at its ends)."""
    d1, d2, r = q - p, b - a, p - a
    aa = np.einsum("ij,ij->i", d1, d1)
    ee = np.einsum("ij,ij->i", d2, d2)
    bb = np.einsum("ij,ij->i", d1, d2)
    cc = np.einsum("ij,ij->i", d1, r)
    ff = np.einsum("ij,ij->i", d2, r)
    denom = aa * ee - bb * bb
    with np.errstate(divide="ignore", invalid="ignore"):
        parallel = denom <= 1e-12 * aa * ee
        s = np.clip(np.where(parallel, eps, (bb * ff - cc * ee) / np.where(parallel, 1.0, denom)), eps, 1.0)
        point = ee <= 0.0  # a capsule of no length: a sphere, whose point is the segment's closest
        s = np.where(point, np.clip(-cc / aa, eps, 1.0), s)
        u = np.where(point, 0.0, (bb * s + ff) / np.where(point, 1.0, ee))
        below, above = u < 0.0, u > 1.0
        s = np.where(below, np.clip(-cc / aa, eps, 1.0), s)
        s = np.where(above, np.clip((bb - cc) / aa, eps, 1.0), s)
        u = np.clip(u, 0.0, 1.0)
    gap = p + s[:, None] * d1 - (a + u[:, None] * d2)
    radius = ra + u * (rb - ra)
    hit = np.einsum("ij,ij->i", gap, gap) <= radius * radius
    if planes is not None:
        planes = np.asarray(planes, dtype=np.float64)
        cut = np.any(planes[:, :, :3] != 0.0, axis=(1, 2))
        hit &= ~cut | _capped_tube(p, d1, a, d2, ee, radius, eps, planes)
    if flat is not None and np.any(flat):
        flat = np.asarray(flat, dtype=bool)
        hit = np.where(flat, _segment_ribbon(p, d1, a, b, ra, rb, eps, tangents), hit)
    return hit


def _segment_ribbon(p, d1, a, b, ra, rb, eps, tangents=None):
    """Pairwise: segment p -> p + d1 against a ribbon's stretch a -> b (half width ra ->
    rb along it) as Cycles meets a ribbon: facing the ray, where the ray's line passes the
    axis line (the closest approach of the two lines), at the axis's depth there, which
    must lie on the segment more than RIBBON_AVOIDANCE half widths from p (Cycles ignores
    nearer hits). The stretch ends across the curve's directions at its ends (`tangents`
    (ta, tb), Pieces.joint_tangents; None: its own), seen across the ray, so that the
    stretches of a bending curve meet."""
    d2 = b - a
    aa = np.einsum("ij,ij->i", d1, d1)
    ee = np.einsum("ij,ij->i", d2, d2)
    bb = np.einsum("ij,ij->i", d1, d2)
    cc = np.einsum("ij,ij->i", d1, p - a)
    ff = np.einsum("ij,ij->i", d2, p - a)
    denom = aa * ee - bb * bb
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing = denom > 1e-12 * aa * ee  # a ribbon along the ray is seen edge on
        s = np.where(crossing, (bb * ff - cc * ee) / np.where(crossing, denom, 1.0), -np.inf)
        u = np.where(ee > 0.0, (bb * s + ff) / np.where(ee > 0.0, ee, 1.0), 0.0)
    u = np.where(crossing, u, 0.0)
    gap = p + np.where(crossing, s, 0.0)[:, None] * d1 - (a + u[:, None] * d2)
    radius = ra + np.clip(u, 0.0, 1.0) * (rb - ra)
    ta, tb = (d2, d2) if tangents is None else (np.asarray(t, dtype=np.float64) for t in tangents)
    scale = np.maximum(aa, 1e-300)
    across_a = ta - (np.einsum("ij,ij->i", ta, d1) / scale)[:, None] * d1
    across_b = tb - (np.einsum("ij,ij->i", tb, d1) / scale)[:, None] * d1
    within = (np.einsum("ij,ij->i", p - a, across_a) >= 0.0) & (np.einsum("ij,ij->i", p - b, across_b) <= 0.0)
    near = RIBBON_AVOIDANCE * radius / np.sqrt(scale)
    return crossing & within & (np.einsum("ij,ij->i", gap, gap) <= radius * radius) \
        & (s >= np.maximum(eps, near)) & (s <= 1.0)


def _capped_tube(p, d1, a, d2, ee, radius, eps, planes):
    """Pairwise, for a capsule the segment p -> p + d1 passes within its radius: whether it
    meets it as Cycles' tube, which its curve's end `planes` (M, 2, 4) cut rather than a
    half sphere: some point of the segment more than `eps` of its length on lies within
    the cylinder of the radius at the closest approach and on the curve's side of both."""
    with np.errstate(divide="ignore", invalid="ignore"):
        axis = d2 / np.sqrt(np.where(ee > 0.0, ee, 1.0))[:, None]
        w = (p - a) - np.einsum("ij,ij->i", p - a, axis)[:, None] * axis
        v = d1 - np.einsum("ij,ij->i", d1, axis)[:, None] * axis
        qa = np.einsum("ij,ij->i", v, v)
        qb = 2.0 * np.einsum("ij,ij->i", w, v)
        qc = np.einsum("ij,ij->i", w, w) - radius * radius
        disc = qb * qb - 4.0 * qa * qc
        root = np.sqrt(np.maximum(disc, 0.0))
        moving = qa > 0.0
        lo = np.where(moving, (-qb - root) / (2.0 * np.where(moving, qa, 1.0)), np.where(qc <= 0.0, -np.inf, np.inf))
        hi = np.where(moving, (-qb + root) / (2.0 * np.where(moving, qa, 1.0)), np.where(qc <= 0.0, np.inf, -np.inf))
        lo = np.where(moving & (disc < 0.0), np.inf, lo)
        for side in (0, 1):
            # start + s rate >= 0 on the curve's side of the plane.
            normal, offset = planes[:, side, :3], planes[:, side, 3]
            start = np.einsum("ij,ij->i", normal, p) + offset
            rate = np.einsum("ij,ij->i", normal, d1)
            cross = -start / np.where(rate != 0.0, rate, 1.0)
            lo = np.where(rate > 0.0, np.maximum(lo, cross), lo)
            hi = np.where(rate < 0.0, np.minimum(hi, cross), hi)
            lo = np.where((rate == 0.0) & (start < 0.0), np.inf, lo)
    return np.maximum(lo, eps) <= np.minimum(hi, 1.0)


def _on_piece(p, n, a, b, ra, rb, flat, planes=None):
    """Pairwise: whether p, of unit normal n, lies on the piece a -> b (radius ra -> rb
    along it) as Cycles intersects it, within OWN_SLACK of the radius there (plus
    float32's rounding of p). A round piece (flat False): on its surface, n within
    OWN_COS of the direction from the axis, either way (the true normal as the shader
    sees it faces the camera). A ribbon (flat True): within its radius, in the plane
    through the axis normal to n (a ribbon faces the ray that meets it, and its true
    normal is that ray's).

    Nothing lies on a piece past its curve's end `planes` (M, 2, 4; `_segment_capsule`)."""
    d2 = b - a
    ee = np.einsum("ij,ij->i", d2, d2)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(ee > 0.0, np.clip(np.einsum("ij,ij->i", p - a, d2) / np.where(ee > 0.0, ee, 1.0), 0.0, 1.0), 0.0)
    radial = p - (a + u[:, None] * d2)
    dist = np.linalg.norm(radial, axis=1)
    radius = ra + u * (rb - ra)
    slack = OWN_SLACK * radius + 1e-6 * np.linalg.norm(p, axis=1)
    along = np.einsum("ij,ij->i", radial, n)
    round_on = (np.abs(dist - radius) <= slack) & (np.abs(along) >= OWN_COS * dist)
    flat_on = (dist <= radius + slack) & (np.abs(along) <= slack)
    on = np.where(flat, flat_on, round_on)
    if planes is not None:
        planes = np.asarray(planes, dtype=np.float64)
        for side in (0, 1):
            on &= np.einsum("ij,ij->i", planes[:, side, :3], p) + planes[:, side, 3] >= 0.0
    return on


def _within(p, a, b, ra, rb, slack=0.0):
    """Pairwise: whether p lies within the capsule a -> b (radius ra -> rb along it) grown
    by `slack`."""
    d2 = b - a
    ee = np.einsum("ij,ij->i", d2, d2)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(ee > 0.0, np.clip(np.einsum("ij,ij->i", p - a, d2) / np.where(ee > 0.0, ee, 1.0), 0.0, 1.0), 0.0)
    gap = p - (a + u[:, None] * d2)
    reach = ra + u * (rb - ra) + slack
    return np.einsum("ij,ij->i", gap, gap) <= reach * reach


def _held(points: np.ndarray, a: np.ndarray, b: np.ndarray, ra: np.ndarray, rb: np.ndarray) -> np.ndarray:
    """(M,) whether each point lies within one of the capsules."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(p), dtype=bool)
    if not len(p) or not len(a):
        return out
    c_mid, c_half = 0.5 * (a + b), 0.5 * np.linalg.norm(b - a, axis=1) + np.maximum(ra, rb)
    step = max(1, _BATCH // len(a))
    for first in range(0, len(p), step):
        rows = slice(first, first + step)
        m, k = np.nonzero(np.linalg.norm(p[rows, None, :] - c_mid[None], axis=2) <= c_half[None] + 1e-9)
        if len(m):
            out[first + np.unique(m[_within(p[rows][m], a[k], b[k], ra[k], rb[k])])] = True
    return out
