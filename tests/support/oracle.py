"""Exact numpy ray casting: the test oracle for tiny scenes (no Cycles, no GPU)."""
from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from addon.core.presets import build_preset
from addon.core.scene import CameraSpec, SceneSpec
from addon.render.pipeline import ViewSamples


CHUNK = 256  # triangles the ray caster tests at once


def _compact_chunks(tris: np.ndarray) -> list[np.ndarray]:
    """The triangles' indices in chunks of at most CHUNK that lie close together: halves
    split at the median of the centroids along their box's longest side, each chunk's
    indices ascending."""
    centroids = tris.mean(axis=1)
    pending, chunks = [np.arange(len(tris))], []
    while pending:
        ids = pending.pop()
        if len(ids) <= CHUNK:
            chunks.append(np.sort(ids))
            continue
        points = centroids[ids]
        axis = int(np.argmax(points.max(axis=0) - points.min(axis=0)))
        order = ids[np.argsort(points[:, axis], kind="stable")]
        pending += [order[:len(order) // 2], order[len(order) // 2:]]
    return chunks


def ray_hits(origins: np.ndarray, dirs: np.ndarray, tris: np.ndarray, t_max=None, eps: float = 1e-9):
    """Nearest hit distance (inf if none) and triangle index per ray (Moller-Trumbore); of
    equally near hits, the lowest index.

    Triangles go by spatially compact chunks; a chunk tests only the rays whose segment
    [0, t_max] passes within its bounding sphere (any hit lies inside it), so the answer
    is that of testing every ray against every triangle, at a fraction of the work."""
    origins = np.asarray(origins, dtype=np.float64)
    dirs = np.asarray(dirs, dtype=np.float64)
    tris = np.asarray(tris, dtype=np.float64)
    n = len(origins)
    best = np.full(n, np.inf)
    index = np.full(n, -1)
    limit = np.full(n, np.inf) if t_max is None else np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,))
    dir_sq = np.maximum(np.einsum("rk,rk->r", dirs, dirs), 1e-300)
    for ids in _compact_chunks(tris) if len(tris) else ():
        chunk = tris[ids]
        corners = chunk.reshape(-1, 3)
        centre = 0.5 * (corners.min(axis=0) + corners.max(axis=0))
        radius = float(np.sqrt(((corners - centre) ** 2).sum(axis=1).max())) * (1.0 + 1e-9) + 1e-12
        to_centre = centre - origins
        along = np.clip(np.einsum("rk,rk->r", to_centre, dirs) / dir_sq, 0.0, limit)
        gap = to_centre - along[:, None] * dirs
        rays = np.flatnonzero(np.einsum("rk,rk->r", gap, gap) <= radius * radius)
        if not len(rays):
            continue
        o, d, lim = origins[rays], dirs[rays], limit[rays]
        v0, e1, e2 = chunk[:, 0], chunk[:, 1] - chunk[:, 0], chunk[:, 2] - chunk[:, 0]
        pvec = np.cross(d[:, None, :], e2[None])
        det = np.einsum("tk,rtk->rt", e1, pvec)
        ok = np.abs(det) > 1e-14
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tvec = o[:, None, :] - v0[None]
        u = np.einsum("rtk,rtk->rt", tvec, pvec) * inv
        qvec = np.cross(tvec, e1[None])
        v = np.einsum("rk,rtk->rt", d, qvec) * inv
        t = np.einsum("tk,rtk->rt", e2, qvec) * inv
        valid = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > eps) & (t < lim[:, None])
        t = np.where(valid, t, np.inf)
        k = np.argmin(t, axis=1)  # the lowest index of the chunk's nearest (its ids ascend)
        tk = t[np.arange(len(rays)), k]
        hit = ids[k]
        better = (tk < best[rays]) | ((tk == best[rays]) & np.isfinite(tk) & (hit < index[rays]))
        best[rays[better]] = tk[better]
        index[rays[better]] = hit[better]
    return best, index


def camera_rays(camera: CameraSpec):
    """World origins and unit directions through pixel centres, row 0 at the top, (H*W, 3)
    each: the camera's own window (shift, fit, pixel aspect), perspective or orthographic."""
    origins, dirs = camera.pixel_rays()
    return origins.reshape(-1, 3), dirs.reshape(-1, 3)


def view_samples(scene: SceneSpec, occluders: np.ndarray | None = None):
    """View samples plus exact visibility (H, W) and the evaluable mask.

    `occluders` (T, 3, 3) replaces the scene's triangles for the shadow rays only
    (what blocks the light, as with visible_shadow off); the camera sees the scene.
    """
    camera = scene.camera
    width, height = camera.resolution
    tris = scene.world_triangles()
    origins, dirs = camera_rays(camera)
    t, idx = ray_hits(origins, dirs, tris)
    hit = np.isfinite(t)
    pos = np.where(hit[:, None], origins + dirs * np.where(hit, t, 0)[:, None], 0.0)
    ng = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    nrm = np.where(hit[:, None], ng[np.maximum(idx, 0)], 0.0)
    flip = np.einsum("ij,ij->i", nrm, dirs) > 0  # face the camera, as Cycles does
    nrm[flip] *= -1
    light = scene.light.position
    scale = max(1.0, float(np.abs(tris).max()))
    if occluders is not None:
        tris = np.asarray(occluders, dtype=np.float64).reshape(-1, 3, 3)
    if scene.light.emission == "sun":
        # Parallel light along the axis: cast from just off the receiver towards the sun.
        ldir = np.broadcast_to(-scene.light.axis, pos.shape)
        facing = np.einsum("ij,ij->i", nrm, ldir) > 0
        ts, _ = ray_hits(pos + ldir * (1e-6 * scale), ldir, tris)
    else:
        to_light = light - pos
        dist = np.linalg.norm(to_light, axis=1)
        ldir = to_light / np.maximum(dist, 1e-300)[:, None]
        facing = np.einsum("ij,ij->i", nrm, ldir) > 0
        # Cast from the light towards the receiver and stop just short of it: a ray that
        # starts exactly at the light meets a triangle touching the light at t = 0 only,
        # which `ray_hits` excludes, so edge-on geometry at the light casts no shadow.
        ts, _ = ray_hits(np.repeat(light[None], len(pos), axis=0), -ldir, tris, t_max=dist - 1e-7 * scale)
    lit = ~np.isfinite(ts)
    evaluable = hit & facing
    if scene.light.emission == "hemi":
        evaluable &= (pos - light) @ scene.light.axis > 0
    if scene.light.emission == "spot":
        evaluable &= -ldir @ scene.light.axis > np.cos(scene.light.spot_size / 2.0)
    shape = (height, width)
    samples = ViewSamples(pos.reshape(height, width, 3), nrm.reshape(height, width, 3), hit.reshape(shape), camera)
    return samples, lit.reshape(shape), evaluable.reshape(shape)


class PresetCase(NamedTuple):
    """A preset built at one camera size, its view samples and the ray caster's answer: what
    the exact and culling tests compare against (conftest.py's `preset_case`)."""

    name: str
    scene: SceneSpec
    samples: ViewSamples
    lit: np.ndarray  # (H, W) bool: reached by the light
    evaluable: np.ndarray  # (H, W) bool


@functools.cache
def preset_case_of(name: str, size: tuple[int, int]) -> PresetCase:
    """`PresetCase` of preset `name` at `size`, made once per test run (share, never modify)."""
    scene = build_preset(name, size)
    return PresetCase(name, scene, *view_samples(scene))


def transmittance(light: np.ndarray, points: np.ndarray, tris: np.ndarray, surface) -> np.ndarray:
    """The light that reaches each point from a point light through every triangle on the
    way: 0 past an opaque one, else the product of (1 - alpha) of the see-through ones at
    their crossings (UVs interpolated barycentrically; core/alpha.Surface)."""
    light = np.asarray(light, dtype=np.float64)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    tris = np.asarray(tris, dtype=np.float64).reshape(-1, 3, 3)
    to = pts - light
    dist = np.linalg.norm(to, axis=1)
    dirs = to / np.maximum(dist, 1e-300)[:, None]
    scale = max(1.0, float(np.abs(tris).max()))
    limit = dist - 1e-7 * scale
    out = np.ones(len(pts))
    opaque = surface.material < 0
    if opaque.any():
        ts, _ = ray_hits(np.repeat(light[None], len(pts), axis=0), dirs, tris[opaque], t_max=limit)
        out[np.isfinite(ts)] = 0.0
    for index in np.flatnonzero(~opaque):
        v0, v1, v2 = tris[index]
        e1, e2 = v1 - v0, v2 - v0
        pvec = np.cross(dirs, e2)
        det = pvec @ e1
        ok = np.abs(det) > 1e-14
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tvec = light - v0
        u = (pvec @ tvec) * inv
        qvec = np.cross(tvec, e1)
        v = (dirs @ qvec) * inv
        t = (qvec @ e2) * inv
        crossed = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9) & (t < limit)
        corners = surface.uvs[index].astype(np.float64)
        uv = (1 - u - v)[:, None] * corners[0] + u[:, None] * corners[1] + v[:, None] * corners[2]
        a = surface.maps[surface.material[index]].sample(uv)
        out = np.where(crossed, out * (1.0 - a), out)
    return out
