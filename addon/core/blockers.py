"""Blockers that are not triangles, as Cycles intersects them: spheres and strands.

Each kind is one object holding its world-space data and the one question a shadow
asks of it: which segments (from a view sample towards the light) it crosses. These are
the numpy oracle the GPU passes will be held to (issue 42), and what the reference
stores of a scene's point clouds and hair.

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
  `Strands.capsules` samples each span into short pieces; a segment crosses the strand
  where it passes within a piece's interpolated radius of the piece.

A hit closer to the segment's start than `eps` of its length is left out: the receiver's
own surface, as the exact pass leaves it out (passes/exact.EXACT_EPS).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Pieces a Catmull-Rom span is sampled into: the chord's sag below a piece is about
# (span length)^2 * curvature / (8 * 16^2), far below a strand's radius for hair.
PIECES_PER_SPAN = 16
# The GPU's pieces (`Strands.capsules(adaptive=True)`): as few a span as keep the chords'
# sag below this share of the curve's thinnest radius, at most PIECES_PER_SPAN.
SAG_SHARE = 0.05


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

    def crossed(self, starts: np.ndarray, ends: np.ndarray, eps: float = 1e-4) -> np.ndarray:
        """(M,) whether each segment start -> end meets a sphere beyond `eps` of its length
        from the start."""
        return _crossed(starts, ends, self.centres, self.centres, self.radii, self.radii, eps)


@dataclass(frozen=True)
class Strands:
    """Curves through `points` (P, 3) with `radii` (P,), curve k being the points
    offsets[k]:offsets[k + 1] (at least two each), world space."""

    points: np.ndarray
    radii: np.ndarray
    offsets: np.ndarray
    linear: np.ndarray | None = None  # (C,) bool: a poly curve, straight between its points

    def __post_init__(self) -> None:
        object.__setattr__(self, "points", np.asarray(self.points, dtype=np.float64).reshape(-1, 3))
        object.__setattr__(self, "radii", np.asarray(self.radii, dtype=np.float64).reshape(-1))
        object.__setattr__(self, "offsets", np.asarray(self.offsets, dtype=np.int64).reshape(-1))
        linear = np.zeros(max(len(self.offsets) - 1, 0), dtype=bool) if self.linear is None else self.linear
        object.__setattr__(self, "linear", np.asarray(linear, dtype=bool).reshape(-1))
        if len(self.linear) != max(len(self.offsets) - 1, 0):
            raise ValueError(f"{len(self.linear)} curve types for {len(self.offsets) - 1} curves")
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
                   np.concatenate(offsets), np.concatenate([p.linear for p in parts]))

    def curve_capsules(self, k: int, pieces: int | None = PIECES_PER_SPAN
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(a, b, ra, rb): curve k's spans sampled into `pieces` pieces each (None: as few as
        keep the sag below SAG_SHARE of its thinnest radius), from a to b (K, 3) with radii
        ra to rb (K,). A curve of one point is a sphere (a == b)."""
        lo, hi = int(self.offsets[k]), int(self.offsets[k + 1])
        points, radii = self.points[lo:hi], self.radii[lo:hi]
        if len(points) == 1:
            return points, points, radii, radii
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
        return (curve[:, :-1].reshape(-1, 3), curve[:, 1:].reshape(-1, 3), width[:, :-1].reshape(-1),
                width[:, 1:].reshape(-1))

    def capsules(self, pieces: int | None = PIECES_PER_SPAN
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every curve's `curve_capsules`, concatenated."""
        parts = [self.curve_capsules(k, pieces) for k in range(len(self))]
        if not parts:
            return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0)
        return tuple(np.concatenate(column) for column in zip(*parts))  # type: ignore[return-value]

    def crossed(self, starts: np.ndarray, ends: np.ndarray, eps: float = 1e-4,
                pieces: int = PIECES_PER_SPAN) -> np.ndarray:
        """(M,) whether each segment start -> end meets a strand beyond `eps` of its length
        from the start. Each curve's pieces are tested only against the segments that pass
        through its bounding sphere."""
        p = np.asarray(starts, dtype=np.float64).reshape(-1, 3)
        q = np.asarray(ends, dtype=np.float64).reshape(-1, 3)
        out = np.zeros(len(p), dtype=bool)
        for k in range(len(self) if len(p) else 0):
            a, b, ra, rb = self.curve_capsules(k, pieces)
            ends_k = np.concatenate([a, b])
            lo, hi = ends_k.min(axis=0), ends_k.max(axis=0)
            centre = np.broadcast_to(0.5 * (lo + hi), p.shape)
            reach = np.full(len(p), 0.5 * float(np.linalg.norm(hi - lo)) + float(max(ra.max(), rb.max())))
            # The segments that pass through the curve's bounding sphere: a sphere's own test.
            near = np.flatnonzero(_segment_capsule(p, q, centre, centre, reach, reach, 0.0))
            if len(near):
                out[near] |= _crossed(p[near], q[near], a, b, ra, rb, eps)
        return out


def _spline_pieces(points: np.ndarray, radii: np.ndarray) -> int:
    """Pieces a span of this Catmull-Rom curve needs: a chord over a parameter step h sags
    by at most h^2 max|C''| / 8, and on a span C'' is a mix of its four control points' two
    second differences, with weights of absolute sum at most 3 (2, -1 at t = 0 and -1, 2
    at t = 1, linear between)."""
    padded = np.concatenate([points[:1], points, points[-1:]])
    second = np.linalg.norm(padded[:-2] - 2.0 * padded[1:-1] + padded[2:], axis=1).max()
    tolerance = SAG_SHARE * max(float(radii.min()), 1e-12)
    return int(np.clip(np.ceil(np.sqrt(3.0 * second / (8.0 * tolerance))), 1, PIECES_PER_SPAN))


def pieces(spheres: "Spheres | None", strands: "Strands | None", adaptive: bool = True
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(a, b, ra, rb): every sphere (a == b) and strand piece, as the GPU draws them (the
    strands' spans in as few pieces as keep SAG_SHARE with `adaptive`)."""
    parts = []
    if spheres is not None and len(spheres):
        parts.append((spheres.centres, spheres.centres, spheres.radii, spheres.radii))
    if strands is not None and len(strands):
        parts.append(strands.capsules(None if adaptive else PIECES_PER_SPAN))
    if not parts:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0)
    return tuple(np.concatenate(column) for column in zip(*parts))  # type: ignore[return-value]


def catmull_rom_basis(t: np.ndarray) -> np.ndarray:
    """(len(t), 4) weights of P0..P3 of the uniform Catmull-Rom spline at t in [0, 1]
    (the curve runs from P1 to P2)."""
    t = np.asarray(t, dtype=np.float64)[:, None]
    t2, t3 = t * t, t * t * t
    return 0.5 * np.concatenate([-t3 + 2.0 * t2 - t, 3.0 * t3 - 5.0 * t2 + 2.0, -3.0 * t3 + 4.0 * t2 + t,
                                 t3 - t2], axis=1)


# Segment pairs tested at once (memory: a few arrays of this many float64).
_BATCH = 4_000_000


def _crossed(starts: np.ndarray, ends: np.ndarray, a: np.ndarray, b: np.ndarray, ra: np.ndarray,
             rb: np.ndarray, eps: float) -> np.ndarray:
    """(M,) whether segment m (starts -> ends) passes within the radius of capsule k (a -> b,
    radius from ra to rb along it) at a point beyond `eps` of its length from its start.
    Each capsule is first tested against the bounding sphere of each segment."""
    p = np.asarray(starts, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(ends, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(p), dtype=bool)
    if not len(p) or not len(a):
        return out
    mid, half = 0.5 * (p + q), 0.5 * np.linalg.norm(q - p, axis=1)
    c_mid, c_half = 0.5 * (a + b), 0.5 * np.linalg.norm(b - a, axis=1) + np.maximum(ra, rb)
    step = max(1, _BATCH // len(a))
    for first in range(0, len(p), step):
        rows = slice(first, first + step)
        near = np.linalg.norm(mid[rows, None, :] - c_mid[None], axis=2) <= half[rows, None] + c_half[None]
        m, k = np.nonzero(near)
        if not len(m):
            continue
        hit = _segment_capsule(p[rows][m], q[rows][m], a[k], b[k], ra[k], rb[k], eps)
        out[first + np.unique(m[hit])] = True
    return out


def _segment_capsule(p, q, a, b, ra, rb, eps):
    """Pairwise: segment p -> q, from `eps` of its length on, within the capsule a -> b
    (radius ra -> rb along it, sphere ends). The closest points of the two segments
    (Ericson, Real-Time Collision Detection 5.1.9) and the radius at the capsule's one."""
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
    return np.einsum("ij,ij->i", gap, gap) <= radius * radius
