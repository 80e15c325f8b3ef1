"""Soft visibility of a sized light by numpy integration over the light: the test oracle of
the soft filter and of the sized Cycles reference (issue 27). A point sees the share of
the light's power that reaches it unblocked, cosine-weighted at its own surface: over the
sphere's visible cap (uniform radiance, so uniform in solid angle) or over an area light's
surface (Lambertian: cosine at the emitter over the squared distance, and Cycles' spread
weight below 180 degrees), or over a sun's disk
(directions within half its angle, uniform in solid angle: the rays go on forever)."""
from __future__ import annotations

import math

import numpy as np

from addon.core.light_shape import Area, Sphere, SunDisk, stratified_points, stratified_unit_square
from addon.core.scene import LightSpec
from tests.support.oracle import ray_hits


def _blocked(points: np.ndarray, targets: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(P, M) bool: the segment from each point to each of its M targets crosses a triangle."""
    p, m = targets.shape[:2]
    origins = np.repeat(points, m, axis=0)
    d = targets.reshape(-1, 3) - origins
    t, _ = ray_hits(origins, d, tris, t_max=np.full(len(origins), 1.0 - 1e-6))
    return np.isfinite(t).reshape(p, m)


def sphere_targets(center: np.ndarray, radius: float, points: np.ndarray, n: int) -> np.ndarray:
    """(P, n, 3) points of the sphere's cap each point sees, uniform in solid angle."""
    to_c = center - points
    dist = np.linalg.norm(to_c, axis=1)
    w = to_c / dist[:, None]
    cos_max = np.sqrt(np.maximum(1.0 - (radius / dist) ** 2, 0.0))
    uv = stratified_unit_square(n)
    cos_t = 1.0 - uv[None, :, 0] * (1.0 - cos_max[:, None])
    sin_t = np.sqrt(np.maximum(1.0 - cos_t ** 2, 0.0))
    phi = 2.0 * math.pi * uv[None, :, 1]
    helper = np.where(np.abs(w[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    a = np.cross(w, helper)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(w, a)
    d = ((sin_t * np.cos(phi))[..., None] * a[:, None] + (sin_t * np.sin(phi))[..., None] * b[:, None]
         + cos_t[..., None] * w[:, None])
    along = np.einsum("pmi,pi->pm", d, to_c)
    t = along - np.sqrt(np.maximum(along ** 2 - (dist ** 2 - radius ** 2)[:, None], 0.0))
    return points[:, None, :] + t[..., None] * d


def spot_weights(light: LightSpec, emitted: np.ndarray) -> np.ndarray:
    """Cycles' cone of a spot, per light point: smoothstep((cos a - cos half) / ((1 - cos half)
    blend)) for light leaving along `emitted` (..., 3) at angle a from the axis; a step at the
    cone's edge without a blend."""
    cos_a = np.einsum("...i,i->...", emitted, light.axis) / np.linalg.norm(emitted, axis=-1)
    cos_half = math.cos(0.5 * light.spot_size)
    width = (1.0 - cos_half) * light.spot_blend
    if width <= 0.0:
        return (cos_a > cos_half).astype(np.float64)
    x = np.clip((cos_a - cos_half) / width, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def soft_visibility(light: LightSpec, points: np.ndarray, normals: np.ndarray, tris: np.ndarray,
                    n: int = 256, chunk: int = 256) -> np.ndarray:
    """(P,) the share of a sphere, area or sun light each point (P, 3), normal (P, 3), sees."""
    out = np.zeros(len(points))
    shape = light.shape
    for start in range(0, len(points), chunk):
        p = points[start:start + chunk]
        nrm = normals[start:start + chunk]
        if isinstance(shape, Sphere):
            q = sphere_targets(light.position, shape.radius, p, n)
            d = q - p[:, None]
            weight = np.maximum(np.einsum("pmi,pi->pm", d, nrm), 0.0) / np.linalg.norm(d, axis=-1)
            if light.emission in ("spot", "hemi"):  # a hemi sphere is Blender's 180 degree spot
                weight = weight * spot_weights(light, -d)
        elif isinstance(shape, Area):
            uv = stratified_unit_square(n) - 0.5
            local = np.column_stack([uv * [shape.size_x, shape.size_y], np.zeros(n), np.ones(n)])
            q = np.broadcast_to((local @ light.matrix_world.T)[None, :, :3], (len(p), n, 3))
            d = q - p[:, None]
            r = np.linalg.norm(d, axis=-1)
            cos_r = np.maximum(np.einsum("pmi,pi->pm", d, nrm), 0.0) / r
            cos_e = np.maximum(-np.einsum("pmi,i->pm", d, -light.rotation[:, 2]), 0.0) / r
            weight = cos_r * cos_e / r ** 2
            if shape.spread < math.pi:
                # Cycles' soft-box grid: max(tan(spread / 2) - tan a, 0) at angle a from the normal.
                tan_e = np.sqrt(np.maximum(1.0 - cos_e ** 2, 0.0)) / np.maximum(cos_e, 1e-300)
                weight = weight * np.maximum(math.tan(0.5 * shape.spread) - tan_e, 0.0)
        elif isinstance(shape, SunDisk):
            directions = stratified_points(shape, n) @ light.rotation.T  # towards the sun
            far = 1e4 * max(1.0, float(np.abs(tris).max()), float(np.abs(p).max()))
            d = np.broadcast_to(directions[None], (len(p), n, 3))
            q = p[:, None] + far * d
            weight = np.maximum(np.einsum("pmi,pi->pm", d, nrm), 0.0)
        else:
            raise ValueError(f"no soft oracle for {shape!r}")
        lit = ~_blocked(p, q, tris)
        total = weight.sum(axis=1)
        out[start:start + chunk] = np.divide((weight * lit).sum(axis=1), total, out=np.zeros(len(p)),
                                             where=total > 0)
    return out


def reached(light: LightSpec, points: np.ndarray, normals: np.ndarray, n: int = 256) -> np.ndarray:
    """(P,) bool: the points some of the light reaches with nothing in the way (an area light
    of narrow spread leaves the rest dark, and Cycles' reference leaves them unevaluated)."""
    nothing = np.full((1, 3, 3), 1e6) + np.eye(3)[None]  # one triangle far beside everything
    return soft_visibility(light, points, normals, nothing, n=n) > 0.5
