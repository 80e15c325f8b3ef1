"""Exact coverage of a triangle in a curved, cropped and warped layer, without tessellation.

The numpy statement of the scheme the GPU-resident depth pass is built on:
each triangle is drawn as one conservative box (its footprint), and each texel in it
keeps the triangle only if the texel's own ray, through the inverse map, passes
inside the triangle. Coverage and depth are then exact at every texel centre, however
large the triangle or strong the curvature, so the seam split, the seam overlap and
the tessellation of curved chords are not needed.

- **Inside test.** Seen from the light (the origin of light-centred coordinates) a
  triangle is bounded by three planes through the light, one per edge. A ray d is
  inside when d . (v_i x v_i+1) has the sign of det(v0, v1, v2) for all three edges.
  That sign also rejects -d, so no hemisphere test is needed. A triangle whose plane
  passes through the light (det = 0) is seen edge-on and covers nothing, as the
  exact ray caster has it.
- **Paraboloid footprint.** The paraboloid map is the stereographic projection from
  the opposite pole. The triangle is first clipped to the layer's hemisphere (z >= 0),
  which leaves a polygon of up to four 3D edges. Each edge spans a minor great-circle
  arc, and its image is an arc of a circle. The image of the polygon is bounded by
  the images of its edges, so its box is the box of the vertices' images and of the
  arcs' interior extremes. Along the arc p(t) = cos t a + sin t e, dx/dt = 0 exactly
  where e_x cos t - a_x sin t = a_x e_z - e_x a_z (and the same for y), which has a
  closed-form solution.
- **Cube footprint.** The face's projection is linear, so the box is the box of the
  triangle's corners after clipping to z >= `near`.
- **Crop and warp.** The DV crop is affine. A NoTW or RTW warp is increasing along
  each axis, and its offsets change across rows by at most `max_shear` per unit
  (`warping.max_shear`). So the box of a warped box follows from its corners and
  centre lines, widened by that Lipschitz bound.
"""
from __future__ import annotations

import numpy as np

from .warping import LayerMapping, Warp, family_offset, max_shear

# A triangle is seen edge-on when |det(v0, v1, v2)| <= EDGE_ON |v0| |(v1 - v0) x (v2 - v0)|:
# its plane passes within EDGE_ON |v0| of the light.
EDGE_ON = 1e-12
# The float32 depth pass's margin (OW_EDGE_ON in gpu_shaders/lib/footprint.glsl, which a
# test checks against this): host counts of what the GPU draws use it.
GPU_EDGE_ON = 1e-6
# The scene's own edge-on distance, relative to the depth range's far end (the host
# sanitiser's 1e-9 far): a vertex within this of the light counts as at it.
EDGE_ON_SCENE = 1e-9
EMPTY = np.array([np.inf, -np.inf, np.inf, -np.inf])  # (x0, x1, y0, y1) of nothing


def edge_planes(tris: np.ndarray, edge_on: float = EDGE_ON,
                distance: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Light-centred triangles (T, 3, 3) -> edge-plane normals (T, 3, 3) and orientation (T,).

    Orientation is the sign of det(v0, v1, v2), or 0 for a triangle seen edge-on: its
    plane within max(`edge_on` |v0|, `distance`) of the light (the GPU pass uses
    GPU_EDGE_ON, and EDGE_ON_SCENE times far).
    """
    v = np.asarray(tris, dtype=np.float64)
    normals = np.cross(v, np.roll(v, -1, axis=1))  # n_i = v_i x v_{i+1}
    # det from the edge vectors: rounding relative to the triangle's size, not its distance.
    plane = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    det = np.einsum("ti,ti->t", v[:, 0], plane)
    scale = np.maximum(edge_on * np.linalg.norm(v[:, 0], axis=1), distance) * np.linalg.norm(plane, axis=1)
    sign = np.where(np.abs(det) > scale, np.sign(det), 0.0)
    return normals, sign


def inside(dirs: np.ndarray, normals: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """(R, T) bool: ray directions (R, 3) inside each triangle's three edge planes."""
    d = np.einsum("rk,tek->rte", np.asarray(dirs, dtype=np.float64), normals)
    return (sign[None, :] != 0.0) & np.all(d * sign[None, :, None] >= 0.0, axis=2)


def clip_polygon(poly: np.ndarray, z_min: float = 0.0) -> np.ndarray:
    """The part of a convex polygon (k, 3) with z >= z_min (Sutherland-Hodgman), (m, 3)."""
    out = []
    count = len(poly)
    for i in range(count):
        p, q = poly[i], poly[(i + 1) % count]
        p_in, q_in = p[2] >= z_min, q[2] >= z_min
        if p_in:
            out.append(p)
        if p_in != q_in:
            t = (z_min - p[2]) / (q[2] - p[2])
            out.append(p + t * (q - p))
    return np.array(out, dtype=np.float64).reshape(-1, 3)


def _stereographic(v: np.ndarray) -> np.ndarray:
    u = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return u[..., :2] / (1.0 + u[..., 2:3])


def arc_extremes(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unit directions (n, 3) inside the minor arc from a to b where the paraboloid x or y is extreme."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    e = b - np.dot(a, b) * a
    length = np.linalg.norm(e)
    if length < 1e-15:
        return np.zeros((0, 3))
    e /= length
    span = np.arctan2(length, np.dot(a, b))  # the arc's angle, in (0, pi)
    found = []
    for k in (0, 1):  # x, then y
        radius = np.hypot(e[k], a[k])
        rhs = a[k] * e[2] - e[k] * a[2]
        if radius < 1e-15 or abs(rhs) > radius:
            continue
        phase = np.arctan2(a[k], e[k])  # e_k cos t - a_k sin t = radius cos(t + phase)
        for t in (np.arccos(rhs / radius) - phase, -np.arccos(rhs / radius) - phase):
            t = np.mod(t, 2.0 * np.pi)
            if 0.0 < t < span:
                found.append(np.cos(t) * a + np.sin(t) * e)
    return np.array(found, dtype=np.float64).reshape(-1, 3)


def paraboloid_box(tri: np.ndarray) -> np.ndarray:
    """(x0, x1, y0, y1) of a light-centred triangle's image in the paraboloid layer (z >= 0)."""
    poly = clip_polygon(np.asarray(tri, dtype=np.float64), 0.0)
    if len(poly) < 3:
        return EMPTY.copy()
    points = [poly]
    for i in range(len(poly)):
        points.append(arc_extremes(poly[i], poly[(i + 1) % len(poly)]))
    dirs = np.concatenate(points, axis=0)
    dirs = dirs[np.linalg.norm(dirs, axis=1) > 0.0]
    xy = np.clip(_stereographic(dirs), -1.0, 1.0)  # z >= 0: inside the unit disk up to rounding
    return np.array([xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()])


def cube_box(tri: np.ndarray, near: float) -> np.ndarray:
    """(x0, x1, y0, y1) of a face-local triangle's image on the cube face (z >= near), clamped
    to [-1, 1]; EMPTY when the image lies beside the face."""
    poly = clip_polygon(np.asarray(tri, dtype=np.float64), near)
    if len(poly) < 3:
        return EMPTY.copy()
    xy = poly[:, :2] / poly[:, 2:3]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    if np.any(lo > 1.0) or np.any(hi < -1.0):
        return EMPTY.copy()
    lo, hi = np.clip(lo, -1.0, 1.0), np.clip(hi, -1.0, 1.0)
    return np.array([lo[0], hi[0], lo[1], hi[1]])


def map_box(box: np.ndarray, mapping: LayerMapping) -> np.ndarray:
    """A projection box (x0, x1, y0, y1) in the layer's map uv: through the DV crop, which
    is affine and increasing (its corners), then the warp (`warp_box`)."""
    crop = LayerMapping(mapping.lo, mapping.hi)
    (u0, v0), (u1, v1) = crop.forward(np.array([[box[0], box[2]], [box[1], box[3]]], dtype=np.float64))
    return warp_box(np.array([u0, u1, v0, v1]), mapping.warp)


def warp_box(box: np.ndarray, warp: Warp | None) -> np.ndarray:
    """A conservative box of the warped image of the uv box (u0, u1, v0, v1).

    u' = u + o_r(u; v) grows with u, and o_r changes across rows by at most L_r per
    unit of v, so over the box u' >= u'(u0, v_mid) - L_r (v1 - v0) / 2 and
    u' <= u'(u1, v_mid) + L_r (v1 - v0) / 2. The same holds for v' over the u' range.
    """
    u0, u1, v0, v1 = (float(x) for x in box)
    if warp is None or not (u0 <= u1 and v0 <= v1):
        return np.asarray(box, dtype=np.float64)
    rows_l, cols_l = max_shear(warp.rows), max_shear(warp.cols)
    v_mid, v_half = 0.5 * (v0 + v1), 0.5 * (v1 - v0)
    w0 = u0 + float(family_offset(warp.rows, np.array(u0), np.array(v_mid))) - rows_l * v_half
    w1 = u1 + float(family_offset(warp.rows, np.array(u1), np.array(v_mid))) + rows_l * v_half
    w_mid, w_half = 0.5 * (w0 + w1), 0.5 * (w1 - w0)
    z0 = v0 + float(family_offset(warp.cols, np.array(v0), np.array(w_mid))) - cols_l * w_half
    z1 = v1 + float(family_offset(warp.cols, np.array(v1), np.array(w_mid))) + cols_l * w_half
    return np.array([w0, w1, z0, z1])


def texel_range(box: np.ndarray, resolution: int) -> tuple[int, int, int, int]:
    """Texels (i0, i1, j0, j1), inclusive, whose centres lie in the uv box; i1 < i0 when none."""
    u0, u1, v0, v1 = np.clip(np.asarray(box, dtype=np.float64), -1.0, 2.0)  # EMPTY stays empty
    i0 = max(int(np.ceil(u0 * resolution - 0.5)), 0)
    i1 = min(int(np.floor(u1 * resolution - 0.5)), resolution - 1)
    j0 = max(int(np.ceil(v0 * resolution - 0.5)), 0)
    j1 = min(int(np.floor(v1 * resolution - 0.5)), resolution - 1)
    return i0, i1, j0, j1
