"""The unfold method's depth stream, built on the host (Stockli Contreras et al.).

Dual sphere-unfolding draws each triangle whole into the half of its nearer pole and
interpolates its projection in the vertex stage, so its coverage still comes from
tessellated chords: sanitised, culled, split at the seam and tessellated per frame.
The other point methods draw resident footprints instead (parameterizations.py).
Also the edge-distance antialiasing parameters of unfold+aa.
"""
from __future__ import annotations

import math

import numpy as np

from ..core import projection, tessellate
from ..core.plan import Plan, outside_region
from ..core.scene import LightSpec
from ..core.warping import LayerMapping, singular_values_2x2
from .frame import PreparedGeometry, ShadowSettings

# Floats per vertex of a depth-pass stream: light-centred position (3), then the
# triangle's plane (unit normal, offset), repeated on its three vertices.
VERTEX_FLOATS = 7

# A triangle drawn whole into the unfold half of its nearer pole must keep clear of
# the opposite pole, where the projection is singular (the pole becomes the rim).
# Beyond this angle from the pole, or covering the opposite pole, it is split at the
# seam instead (docs/unfold_psm.md).
UNFOLD_WHOLE_MAX_ANGLE = math.radians(120.0)


def _vertex_stream(tris_centred: np.ndarray) -> np.ndarray:
    """(n*3, VERTEX_FLOATS) float32: position and plane (normal, offset) per vertex."""
    if len(tris_centred) == 0:
        return np.zeros((0, VERTEX_FLOATS), dtype=np.float32)
    normal = np.cross(tris_centred[:, 1] - tris_centred[:, 0], tris_centred[:, 2] - tris_centred[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    offset = np.einsum("ij,ij->i", normal, tris_centred[:, 0])
    per_tri = np.concatenate([normal, offset[:, None]], axis=1)
    stream = np.concatenate([tris_centred, np.repeat(per_tri[:, None, :], 3, axis=1)], axis=2)
    return stream.reshape(-1, VERTEX_FLOATS).astype(np.float32)


def _map_texels(kind: int, mapping: LayerMapping, res: int):
    """Layer-local points -> texel coordinates of the final (cropped, warped) map."""

    def to_texels(points: np.ndarray) -> np.ndarray:
        return mapping.forward(projection.project(kind, points)) * res

    return to_texels


# Seam-cut pieces reach this many texels past the seam (tessellate.split_at_seam):
# one for the texel ring straddling the rim, one for the chord's sag (the bend
# tolerance), half for the normal offset.
SEAM_OVERLAP_TEXELS = 2.5


def seam_overlap(kind: int, res: int) -> float:
    """Angle (radians) that a side's seam-cut pieces reach past the seam: SEAM_OVERLAP_TEXELS
    texels of that map at the seam (a paraboloid's rim, an unfold half's equator)."""
    at_seam = np.array([[1.0, 0.0]]) if kind == projection.PARABOLOID else np.array([[0.5, 0.0]])
    return SEAM_OVERLAP_TEXELS * float(projection.texel_angle(kind, at_seam, res)[0])


def texel_angle_floor(kind: int, mapping: LayerMapping, res: int) -> float:
    """A lower bound of one texel's angle anywhere inside a (cropped, warped) map.

    Plain maps: 2/res at a paraboloid's rim, (2/res)/sqrt(3) at a cube face's corner.
    The crop and the warp shrink it by at most their largest stretch; the warp's is
    taken at the cell centres and doubled, as its Jacobian is piecewise bilinear.
    """
    if kind == projection.UNFOLD:
        # Tangentially pi sin(theta)/theta per unit of map radius, smallest at the widest
        # angle a drawn triangle reaches (UNFOLD_WHOLE_MAX_ANGLE; split pieces stay within 90).
        theta = UNFOLD_WHOLE_MAX_ANGLE
        base = 2.0 / res * math.pi * math.sin(theta) / theta
    else:
        base = 2.0 / res if kind == projection.PARABOLOID else 2.0 / res / math.sqrt(3.0)
    stretch = float(np.max(mapping.scale))
    if mapping.warp is not None:
        size = mapping.warp.size
        centres = (np.arange(size) + 0.5) / size
        grid = np.stack(np.meshgrid(centres, centres), axis=-1).reshape(-1, 2)
        stretch *= 2.0 * float(singular_values_2x2(mapping.warp.jacobian(grid))[0].max())
    return base / stretch


def prepare_unfold(light: LightSpec, triangles: np.ndarray, plan: Plan, settings: ShadowSettings,
                   depth_range: tuple[float, float]) -> PreparedGeometry:
    """The unfold method's one vertex stream, built on the host: sanitised, culled, split
    and tessellated (the other point methods draw resident footprints instead).

    The unfold draw picks each triangle's half in the vertex stage and interpolates its
    projection, so its coverage still comes from tessellated chords (docs/unfold_psm.md).
    """
    near, far = depth_range
    tris, report = tessellate.sanitize(triangles, light.position, scale=max(far, 1e-30))
    if settings.cull:
        # Object culling: only triangles inside conv(light, view frustum) can shadow
        # something in view (docs/culling.md).
        tris = tris[~outside_region(tris, plan.occluder_planes)]
    stream, split, added = _unfold_stream(tris - light.position, plan, settings)
    return PreparedGeometry({0: stream} if plan.drawn else {}, near, far, report.skipped, added, split)


def _contains_ray(tris: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """(T,) True where the ray from the origin along `direction` meets the triangle
    (Moller-Trumbore with the origin as ray start; edges count as inside)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = b - a, c - a
    pvec = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, pvec)
    ok = np.abs(det) > 1e-300
    inv = 1.0 / np.where(ok, det, 1.0)
    tvec = -a
    u = np.einsum("ij,ij->i", tvec, pvec) * inv
    qvec = np.cross(tvec, e1)
    v = (qvec @ direction) * inv
    t = np.einsum("ij,ij->i", e2, qvec) * inv
    return ok & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > 0.0)


def _unfold_stream(centred: np.ndarray, plan: Plan, settings: ShadowSettings) -> tuple[np.ndarray, int, int]:
    """One vertex stream for both unfold halves: half 0's triangles, then half 1's.

    Dual sphere-unfolding draws each triangle whole into the half of its nearer pole
    (by the mean of its corner directions). Alone that leaves pinholes along the
    edges shared by triangles of different halves: a direction on such an edge is
    looked up in one half, whose texel centre may fall on the neighbour's side,
    which that half never drew. So each half also gets the pieces, cut at the seam
    (reaching a little past it, see `seam_overlap`), of the triangles on its side that
    went to the other half; a lookup in the half of
    the direction's own hemisphere then sees every occluder. Triangles reaching past
    UNFOLD_WHOLE_MAX_ANGLE from their pole, or covering the opposite pole, are cut at
    the seam instead of drawn whole. All of it is still one draw call.
    """
    res = settings.resolution
    local = plan.all_layers[0].to_local(centred)  # half 0's frame: +z is its pole
    if len(plan.drawn) == 1:
        # Hemispherical light: only half 0; nothing behind the light plane can shadow.
        halves = [tessellate.split_at_seam(local, seam_overlap(projection.UNFOLD, res))[0]]
    else:
        z = projection.unit_directions(local)[..., 2]
        nearer0 = z.mean(axis=1) >= 0.0
        limit = math.cos(UNFOLD_WHOLE_MAX_ANGLE)
        reach = np.where(nearer0, z.min(axis=1) < limit, -z.max(axis=1) < limit)
        reach |= np.where(nearer0, _contains_ray(local, np.array([0.0, 0.0, -1.0])),
                          _contains_ray(local, np.array([0.0, 0.0, 1.0])))
        straddle = (z.max(axis=1) > 0.0) & (z.min(axis=1) < 0.0)
        whole0, whole1 = nearer0 & ~reach, ~nearer0 & ~reach
        overlap = seam_overlap(projection.UNFOLD, res)
        front_of_1, _ = tessellate.split_at_seam(local[(whole1 & straddle) | reach], overlap)
        _, back_of_0 = tessellate.split_at_seam(local[(whole0 & straddle) | reach], overlap)
        halves = [np.concatenate([local[whole0], front_of_1]),
                  np.concatenate([local[whole1], back_of_0]) * np.array([1.0, -1.0, -1.0])]
    streams, added = [], 0
    mapping = LayerMapping.identity()
    for layer, tris in zip(plan.drawn, halves):
        refined, n_added = tessellate.tessellate(tris, _map_texels(layer.kind, mapping, res),
                                                 settings.tessellation_tolerance, window=float(res),
                                                 texel_angle_floor=texel_angle_floor(layer.kind, mapping, res))
        added += n_added
        streams.append(_vertex_stream(refined @ layer.rotation))
    split = len(streams[0]) if streams else 0
    return (np.concatenate(streams) if streams else np.zeros((0, VERTEX_FLOATS), np.float32)), split, added


# Edge-distance antialiasing (unfold+aa): the steepest receiver whose own depth change
# must not read as an edge, as the tangent of its angle to the light ray (80 degrees).
EDGE_AA_MAX_TAN = math.tan(math.radians(80.0))


def edge_aa_parameters(resolution: int, near: float, far: float) -> tuple[int, float]:
    """R (texels) and eps (normalised depth) of the unfold map's edge-distance antialiasing.

    R = max(2, res / 256): the soft band keeps the same angular width (about 4 texels
    at 1024) at every resolution. eps: within R texels a smooth surface tilted up to 80
    degrees from the light ray changes its distance by at most R tan(80) (pi 2/res) L;
    with L <= far that is below eps, so only true steps towards a nearer occluder count.
    """
    radius = max(2, int(resolution) // 256)
    texel_angle = math.pi * 2.0 / resolution  # the unfold map's bound (projection.texel_angle)
    eps = radius * EDGE_AA_MAX_TAN * texel_angle * far / max(far - near, 1e-30)
    return radius, float(eps)
