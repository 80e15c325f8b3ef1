"""Homogeneous media: smoke, fog and tinted glass-like volumes on closed meshes.

A shadow ray through a medium of extinction sigma (per metre, one value per RGB channel)
keeps exp(-sigma L) of its light, L the length of the ray inside the medium; Cycles
integrates this exactly for a homogeneous medium (docs/notebook/2026-12-volumes.md). A
medium here is a material's volume whose extinction does not vary in space (a constant
Principled Volume, Volume Absorption or Volume Scatter; `readers/material_media.py`
reads it from the node graph) on a closed mesh: Cycles enters the medium where a ray
meets a face from its front (the side its winding makes outward) and leaves it at a back
face.

The length inside along the segment from the light to a receiver p follows from the
segment's crossings with the medium's triangles alone. With s the distance from a
crossing to p, and the light inside the medium or not (`light_inside`, its winding
number):

    L = inside(light) |p| + sum over entering crossings of s - sum over leaving ones of s

which holds for any closed mesh, any number of crossings, and p inside or outside (a
receiver inside the fog gets the length from itself to where the fog begins). This is
what the `exact` pass sums per view sample, in fixed point (`FIXED_RANGE`), and
`optical_depths` is its numpy oracle. The reference's visibility is the mean over RGB of
the light that passes (capture.py), so a tinted medium's is `visibility` of its three
optical depths.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError

# The exact pass sums each sample's signed optical depths in 32-bit integers (two's
# complement wraps, so the order of the additions does not matter); the frame's scale puts
# the largest optical depth a sample can have, the sum of every medium's extinction times
# the farthest sample's distance, at FIXED_RANGE units.
FIXED_RANGE = float(1 << 30)


@dataclass(frozen=True, eq=False)
class Medium:
    """One homogeneous medium: its extinction per metre for R, G and B."""

    name: str
    sigma: np.ndarray  # (3,) float64, >= 0
    digest: str = field(init=False, default="")

    def __post_init__(self) -> None:
        sigma = np.asarray(self.sigma, dtype=np.float64).reshape(-1)
        if sigma.size == 1:
            sigma = np.repeat(sigma, 3)
        if sigma.shape != (3,) or not np.all(np.isfinite(sigma)) or np.any(sigma < 0.0):
            raise InputError(f"medium {self.name!r}: the extinction must be 1 or 3 finite values >= 0, "
                             f"got {self.sigma!r}")
        object.__setattr__(self, "sigma", sigma)
        h = hashlib.sha1(f"{self.name}|".encode() + sigma.tobytes())
        object.__setattr__(self, "digest", h.hexdigest()[:16])

    @property
    def clear(self) -> bool:
        """True when the medium lets all light through (no extinction in any channel)."""
        return not np.any(self.sigma > 0.0)


def visibility(depths: np.ndarray) -> np.ndarray:
    """The reference's visibility of RGB optical depths (..., 3): the mean of exp(-depth)."""
    return np.exp(-np.asarray(depths, dtype=np.float64)).mean(axis=-1)


def winding_numbers(point: np.ndarray, triangles: np.ndarray) -> float:
    """The generalised winding number of closed triangles (T, 3, 3) about `point`: 1 inside
    a closed mesh wound outward, 0 outside (the solid angles' sum over 4 pi, Van Oosterom
    and Strackee's formula; robust to small gaps)."""
    tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3) - np.asarray(point, dtype=np.float64)
    if not len(tris):
        return 0.0
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la \
        + np.einsum("ij,ij->i", c, a) * lb
    return float(np.sum(2.0 * np.arctan2(det, den)) / (4.0 * np.pi))


def light_inside(light: np.ndarray, triangles: np.ndarray, medium: np.ndarray, count: int) -> np.ndarray:
    """(count,) how many times the light lies inside each medium's closed triangles (its
    winding number, rounded): 0 outside; 2 where two objects of one medium overlap, whose
    densities Cycles adds."""
    tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    medium = np.asarray(medium).reshape(-1)
    return np.array([round(winding_numbers(light, tris[medium == m])) for m in range(count)], dtype=np.float64)


def light_sigma(light: np.ndarray, triangles: np.ndarray, medium: np.ndarray, media: tuple[Medium, ...]) -> np.ndarray:
    """(3,) the extinction at the light itself: the sum of the media it lies inside."""
    inside = light_inside(light, triangles, medium, len(media))
    sigma = np.zeros(3)
    for m, times in enumerate(inside):
        sigma += max(times, 0.0) * media[m].sigma
    return sigma


def fixed_scale(media: tuple[Medium, ...], reach: float) -> float:
    """Units per optical depth in the exact pass's sums: the largest optical depth a
    sample within `reach` of the light can have maps to FIXED_RANGE (0 without media)."""
    total = sum(float(m.sigma.max()) for m in media)
    if total <= 0.0 or not (reach > 0.0) or not np.isfinite(reach):
        return 0.0
    return FIXED_RANGE / (total * float(reach))


def optical_depths(light: np.ndarray, points: np.ndarray, triangles: np.ndarray, medium: np.ndarray,
                   media: tuple[Medium, ...]) -> np.ndarray:
    """(N, 3) RGB optical depth of each segment light -> point through the media: the
    triangles (T, 3, 3) world, wound outward, with `medium` (T,) their medium's index or -1.
    The numpy oracle of the exact pass (float64, no margin at the receiver)."""
    light = np.asarray(light, dtype=np.float64)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3) - light
    tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3) - light
    medium = np.asarray(medium).reshape(-1)
    depth = np.zeros((len(pts), 3))
    if not len(media) or not len(pts):
        return depth
    dist = np.linalg.norm(pts, axis=1)
    inside = light_inside(np.zeros(3), tris, medium, len(media))
    for m, med in enumerate(media):
        length = max(inside[m], 0.0) * dist
        for tri in tris[medium == m]:
            length += _signed_crossings(pts, dist, tri)
        depth += length[:, None] * med.sigma[None, :]
    return depth


def _signed_crossings(pts: np.ndarray, dist: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Each light-centred segment 0 -> p's crossing of one triangle: +s entering (against
    its outward normal), -s leaving, 0 when it misses; s the distance from the crossing to p."""
    a, b, c = tri
    normal = np.cross(b - a, c - a)
    along = pts @ normal  # the segment's direction against the normal
    with np.errstate(divide="ignore", invalid="ignore"):
        f = (a @ normal) / along  # where the plane cuts the segment, 1 at p
    # The crossing lies inside the triangle when the segment's direction lies inside the three
    # planes through the light and each edge (as lib/exact_walk.glsl tests), oriented inward.
    orient = 1.0 if a @ np.cross(b, c) >= 0.0 else -1.0
    inside = np.ones(len(pts), dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= inside_edge(pts, orient * np.cross(u, v))
    hit = inside & (along != 0.0) & (f > 0.0) & (f < 1.0)
    s = np.where(hit, (1.0 - np.where(hit, f, 0.0)) * dist, 0.0)
    return np.where(along < 0.0, s, -s)


def inside_edge(pts: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """Whether directions lie on the inner side of an edge plane (normal `edge`), a direction
    on the plane counting for one of the two triangles that share the edge only: it is moved
    by (e, e^2, e^3) for a vanishing e, so its side is that of the normal's first non-zero
    component (the two triangles' normals of one edge are exact opposites). A medium's
    crossings must count once each, where an opaque crossing may count twice
    (lib/exact_walk.glsl's ow_medium_inside)."""
    side = np.asarray(pts, dtype=np.float64) @ edge
    first = next((float(x) for x in edge if x != 0.0), 0.0)
    return (side > 0.0) | ((side == 0.0) & (first > 0.0))


@dataclass(frozen=True, eq=False)
class GridMedium:
    """A heterogeneous medium: a density grid (a Volume object's, an OpenVDB grid) times an
    extinction per unit density. sigma_t(x) = sigma * density(x), density sampled
    trilinearly between voxel centres (Cycles' default interpolation), 0 outside the grid.

    `density` is (nz, ny, nx) float32; `to_index` (4, 4) maps world points to index space,
    where voxel (i, j, k) (x, y, z) has its centre at (i, j, k)."""

    name: str
    sigma: np.ndarray  # (3,) float64, per unit density
    density: np.ndarray  # (nz, ny, nx) float32, >= 0
    to_index: np.ndarray  # (4, 4) float64
    # The density's own digest (what the GPU's copy is keyed by); `moved` hands it over with
    # the density, so a moved grid is neither checked nor hashed again.
    density_digest: str = field(default="", repr=False)
    digest: str = field(init=False, default="")

    def __post_init__(self) -> None:
        sigma = np.asarray(self.sigma, dtype=np.float64).reshape(-1)
        if sigma.size == 1:
            sigma = np.repeat(sigma, 3)
        to_index = np.asarray(self.to_index, dtype=np.float64)
        if sigma.shape != (3,) or not np.all(np.isfinite(sigma)) or np.any(sigma < 0.0):
            raise InputError(f"grid medium {self.name!r}: sigma must be 1 or 3 finite values >= 0")
        if to_index.shape != (4, 4) or not np.all(np.isfinite(to_index)):
            raise InputError(f"grid medium {self.name!r}: to_index must be a finite 4x4 matrix")
        if not self.density_digest:
            density = np.ascontiguousarray(np.asarray(self.density, dtype=np.float32))
            if density.ndim != 3 or min(density.shape) < 1 or not np.all(np.isfinite(density)):
                raise InputError(f"grid medium {self.name!r}: the density must be a finite 3D array, "
                                 f"got {density.shape}")
            density = np.maximum(density, 0.0)
            object.__setattr__(self, "density", density)
            object.__setattr__(self, "density_digest",
                               hashlib.sha1(f"{density.shape}|".encode() + density.tobytes()).hexdigest()[:16])
        object.__setattr__(self, "sigma", sigma)
        object.__setattr__(self, "to_index", to_index)
        h = hashlib.sha1(f"{self.name}|{self.density_digest}|".encode() + sigma.tobytes() + to_index.tobytes())
        object.__setattr__(self, "digest", h.hexdigest()[:16])

    def moved(self, to_index: np.ndarray) -> "GridMedium":
        """The same grid under another world-to-index matrix (its object moved): the
        density and its digest are shared, not copied."""
        return GridMedium(self.name, self.sigma, self.density, to_index, density_digest=self.density_digest)

    def voxel_size(self) -> float:
        """The smallest voxel edge in world units."""
        to_world = np.linalg.inv(self.to_index)[:3, :3]
        return float(np.linalg.norm(to_world, axis=0).min())

    def world_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The world box of the grid's extent (half a voxel past the outer centres)."""
        nz, ny, nx = self.density.shape
        lo, hi = np.array([-0.5, -0.5, -0.5]), np.array([nx - 0.5, ny - 0.5, nz - 0.5])
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        world = corners @ np.linalg.inv(self.to_index).T
        return world[:, :3].min(axis=0), world[:, :3].max(axis=0)

    def density_at(self, points: np.ndarray) -> np.ndarray:
        """Trilinear density at world points (N, 3), 0 outside the grid's extent."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        idx = np.concatenate([pts, np.ones((len(pts), 1))], axis=1) @ self.to_index.T
        nz, ny, nx = self.density.shape
        x, y, z = idx[:, 0], idx[:, 1], idx[:, 2]
        i0, j0, k0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64), np.floor(z).astype(np.int64)
        fx, fy, fz = x - i0, y - j0, z - k0
        out = np.zeros(len(pts))
        inside = (x >= -0.5) & (x <= nx - 0.5) & (y >= -0.5) & (y <= ny - 0.5) & (z >= -0.5) & (z <= nz - 0.5)
        for di in (0, 1):
            for dj in (0, 1):
                for dk in (0, 1):
                    i = np.clip(i0 + di, 0, nx - 1)
                    j = np.clip(j0 + dj, 0, ny - 1)
                    k = np.clip(k0 + dk, 0, nz - 1)
                    w = (fx if di else 1 - fx) * (fy if dj else 1 - fy) * (fz if dk else 1 - fz)
                    out += w * self.density[k, j, i]
        return np.where(inside, out, 0.0)


def grid_optical_depths(origin: np.ndarray, points: np.ndarray, grids: tuple[GridMedium, ...],
                        steps: int = 2048) -> np.ndarray:
    """(N, 3) RGB optical depth of each segment origin -> point through the grids, by the
    midpoint rule with `steps` steps (the numpy oracle of the GPU's march); `origin` is one
    point (3,) or one per point (N, 3) (a sun's: upstream of each)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    origin = np.asarray(origin, dtype=np.float64)
    depth = np.zeros((len(pts), 3))
    length = np.linalg.norm(pts - origin, axis=-1)
    for grid in grids:
        total = np.zeros(len(pts))
        for t in (np.arange(steps) + 0.5) / steps:
            total += grid.density_at(origin + t * (pts - origin))
        depth += (total * length / steps)[:, None] * grid.sigma[None, :]
    return depth
