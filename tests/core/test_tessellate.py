"""Sanitising, seam splitting and adaptive tessellation (addon/core/tessellate.py)."""
from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from addon.core import projection as P
from addon.core import tessellate as T
from addon.core.scene import SceneBuilder

FAST = settings(max_examples=60, deadline=None)


def _areas(tris: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


def _normals(tris: np.ndarray) -> np.ndarray:
    return np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])


def _paraboloid_texels(res: int):
    """Map (n, 3) layer-local points to paraboloid texel coordinates at resolution res."""
    return lambda p: P.xy_to_texel(P.paraboloid_project(p), res)


def _edge_bends(tris: np.ndarray, to_texels) -> np.ndarray:
    """Texel distance between each edge's projected midpoint and its chord's midpoint."""
    a = tris.reshape(-1, 3)
    b = np.roll(tris, -1, axis=1).reshape(-1, 3)
    pa, pb, pm = to_texels(a), to_texels(b), to_texels((a + b) / 2.0)
    return np.linalg.norm(pm - (pa + pb) / 2.0, axis=1)


def _floor_quad(half: float, height: float = 1.0) -> np.ndarray:
    """Two triangles of the square |x|, |y| <= half at z = height, facing -z (the light)."""
    c = np.array([[-half, -half, height], [half, -half, height], [half, half, height], [-half, half, height]])
    return np.stack([c[[0, 2, 1]], c[[0, 3, 2]]])


def _box(center, size) -> np.ndarray:
    b = SceneBuilder("t")
    b.box("box", center, size)
    return b._meshes[0].world_triangles()


def _tetrahedron() -> np.ndarray:
    v = np.array([[0.0, 0.0, 0.6], [4.0, -1.0, 2.0], [-1.0, 5.0, 1.5], [-3.0, -4.0, 3.0]])
    faces = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]]
    tris = v[faces]
    centroid = v.mean(axis=0)
    for k, t in enumerate(tris):  # orient outwards
        if np.dot(np.cross(t[1] - t[0], t[2] - t[0]), t[0] - centroid) < 0:
            tris[k] = t[[0, 2, 1]]
    return tris


def _directed_edges(tris: np.ndarray) -> list[tuple]:
    out = []
    for t in tris:
        for k in range(3):
            out.append((tuple(t[k]), tuple(t[(k + 1) % 3])))
    return out


# ---------------------------------------------------------------- sanitize


def test_sanitize_counts_each_reason_exactly():
    """NaN/inf, zero-area and through-the-light triangles are dropped and counted;
    the good ones come out unchanged and in order."""
    light = np.array([0.0, 0.0, 0.0])
    good1 = [[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]]
    good2 = [[5.0, 5.0, -2.0], [6.0, 5.0, -2.0], [5.0, 7.0, -1.0]]
    nan = [[np.nan, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]]
    inf = [[1.0, 0.0, 1.0], [0.0, np.inf, 1.0], [0.0, 0.0, -np.inf]]
    nan_and_flat = [[np.nan, 0.0, 0.0], [np.nan, 0.0, 0.0], [np.nan, 0.0, 0.0]]  # counted once, as non-finite
    collinear = [[0.0, 0.0, 2.0], [1.0, 1.0, 2.0], [2.0, 2.0, 2.0]]
    repeated = [[3.0, 1.0, 1.0], [3.0, 1.0, 1.0], [0.0, 4.0, 1.0]]
    vertex_at_light = [[0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]
    plane_through_light = [[1.0, 1.0, 0.0], [2.0, 1.0, 0.0], [1.0, 3.0, 0.0]]  # z = 0 plane, light at origin
    tris = np.array([good1, nan, collinear, vertex_at_light, good2, inf, repeated, plane_through_light, nan_and_flat])
    out, report = T.sanitize(tris, light, scale=10.0)
    assert (report.nonfinite, report.degenerate, report.edge_on) == (3, 2, 2)
    assert report.skipped == 7
    assert np.array_equal(out, np.array([good1, good2]))


def test_sanitize_keeps_small_and_nearly_edge_on_triangles_at_small_scale():
    """A millimetre scene keeps its tiny triangles; a plane 1e-6 scene units from the
    light is not edge-on (the thresholds scale with the scene)."""
    s = 1e-3
    light = np.zeros(3)
    tiny = np.array([[[0.0, 0.0, s], [0.1 * s, 0.0, s], [0.0, 0.1 * s, s]]])
    out, report = T.sanitize(tiny, light, scale=s)
    assert len(out) == 1 and report.skipped == 0
    close = np.array([[[1.0, 0.0, 1e-6], [0.0, 1.0, 1e-6], [1.0, 1.0, 1e-6]]])
    out, report = T.sanitize(close, light, scale=1.0)
    assert len(out) == 1 and report.edge_on == 0


def test_sanitize_empty_input():
    """No triangles in: none out, nothing counted."""
    out, report = T.sanitize(np.zeros((0, 3, 3)), np.zeros(3), scale=1.0)
    assert out.shape == (0, 3, 3) and report.skipped == 0


# ---------------------------------------------------------------- seam split


def _straddling_triangle(rng) -> np.ndarray:
    while True:
        t = rng.normal(scale=3.0, size=(3, 3))
        if t[:, 2].min() < 0 < t[:, 2].max() and _areas(t[None])[0] > 1e-3:
            return t


@FAST
@given(st.integers(0, 2**32 - 1))
def test_split_at_seam_straddling(seed):
    """Random triangles straddling z = 0: front pieces have z >= 0, back pieces z <= 0,
    the pieces keep the orientation and plane of the original and their areas add up."""
    rng = np.random.default_rng(seed)
    tris = np.stack([_straddling_triangle(rng) for _ in range(8)])
    front, back = T.split_at_seam(tris)
    assert front[..., 2].min() >= -1e-12
    assert back[..., 2].max() <= 1e-12
    total = _areas(front).sum() + _areas(back).sum()
    assert total == pytest.approx(_areas(tris).sum(), rel=1e-9)
    # Each straddling triangle gives 1 + 2 or 2 + 1 pieces.
    assert len(front) + len(back) == 3 * len(tris)
    for t in tris:
        n = _normals(t[None])[0]
        on_plane = lambda p: np.abs((p - t[0]) @ n) <= 1e-9 * np.linalg.norm(n) * (1 + np.abs(p).max())  # noqa: E731
        mine_f = [p for p in front if np.all(on_plane(p))]
        mine_b = [p for p in back if np.all(on_plane(p))]
        assert sum(_areas(np.array(m)).sum() for m in (mine_f, mine_b) if m) == pytest.approx(
            _areas(t[None])[0], rel=1e-9)
    for pieces in (front, back):
        n = _normals(pieces)
        big = _areas(pieces) > 1e-9
        # every piece is parallel to and oriented like one of the originals
        orig = _normals(tris)
        cosines = (n[big] @ orig.T) / np.outer(np.linalg.norm(n[big], axis=1), np.linalg.norm(orig, axis=1))
        assert np.all(cosines.max(axis=1) > 1 - 1e-9)


@FAST
@given(st.integers(0, 2**32 - 1))
def test_clip_halfspace_general_plane(seed):
    """clip_halfspace keeps exactly the part with signed >= 0 for any plane; the two
    complementary clips add up to the original area."""
    rng = np.random.default_rng(seed)
    tris = rng.normal(scale=2.0, size=(10, 3, 3))
    normal = rng.normal(size=3)
    offset = float(rng.normal())
    signed = tris @ normal - offset
    keep = T.clip_halfspace(tris, signed)
    drop = T.clip_halfspace(tris, -signed)
    assert np.all(keep.reshape(-1, 3) @ normal - offset >= -1e-9)
    assert np.all(drop.reshape(-1, 3) @ normal - offset <= 1e-9)
    assert _areas(keep).sum() + _areas(drop).sum() == pytest.approx(_areas(tris).sum(), rel=1e-9)


def test_split_one_sided_triangles_pass_unchanged():
    """Triangles strictly on one side go to that side bit for bit, nothing to the other."""
    up = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 2.0], [0.0, 1.0, 0.5]]])
    down = up * np.array([1.0, 1.0, -1.0])
    front, back = T.split_at_seam(np.concatenate([up, down]))
    assert np.array_equal(front, up) and np.array_equal(back, down)


def test_split_drops_triangles_in_the_seam_plane():
    """A triangle lying in z = 0 subtends no solid angle: dropped from both sides."""
    flat = np.array([[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [2.0, 2.0, 0.0]]])
    front, back = T.split_at_seam(flat)
    assert len(front) == 0 and len(back) == 0


@pytest.mark.parametrize(
    "tri",
    [
        [[1.0, 0.0, 0.0], [0.0, 1.0, 1.0], [2.0, 1.0, 1.0]],  # one vertex on the seam
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [2.0, 1.0, 1.0]],  # one edge on the seam
    ],
    ids=["vertex", "edge"],
)
def test_split_touching_triangle_goes_to_one_side_only(tri):
    """A triangle touching the seam from the front (z >= 0, a vertex or edge at z = 0)
    lies entirely in the front half-space: it passes through unchanged and leaves no
    (zero-area) pieces on the back side; mirrored for the back."""
    t = np.array([tri])
    front, back = T.split_at_seam(t)
    assert np.array_equal(front, t)
    assert len(back) == 0, f"back got {len(back)} piece(s) of area {_areas(back).tolist()}"
    mirrored = t * np.array([1.0, 1.0, -1.0])
    front, back = T.split_at_seam(mirrored)
    assert np.array_equal(back, mirrored)
    assert len(front) == 0, f"front got {len(front)} piece(s) of area {_areas(front).tolist()}"


# ---------------------------------------------------------------- tessellate


@pytest.mark.parametrize("res, tolerance", [(256, 1.0), (1024, 0.5)])
@pytest.mark.parametrize(
    "half, offset",
    [(50.0, (3.7, -1.3)), (50.0, (0.5, 0.3)), (50.0, (0.0, 0.0)), (4.0, (0.0, 0.0))],
    ids=["huge-offcentre", "huge-room-like", "huge-centred", "room-centred"],
)
def test_tessellate_floor_until_flat(res, tolerance, half, offset):
    """A floor quad 1 unit under the light is refined until every edge bends by at most
    the tolerance (projected midpoint vs chord midpoint, in texels); the reported
    count, the area, plane and orientation all hold.

    The centred cases put the quad's diagonal exactly under the light, as for a
    light above the middle of a room: that diagonal's midpoint projects onto its
    chord's midpoint although the edge is far from linear in the map.
    """
    quad = _floor_quad(half) + np.array([offset[0], offset[1], 0.0])
    to_texels = _paraboloid_texels(res)
    assert _edge_bends(quad, to_texels).max() > 10 * tolerance  # it really needs work
    out, added = T.tessellate(quad, to_texels, tolerance)
    assert added == len(out) - len(quad) > 0
    assert _areas(out).sum() == pytest.approx(_areas(quad).sum(), rel=1e-9)
    assert np.all(out[..., 2] == 1.0)
    assert np.all(_normals(out)[:, 2] < 0)  # same facing as the input (towards the light)
    worst = _edge_bends(out, to_texels).max()
    assert worst <= tolerance, f"{len(out)} triangles, an edge still bends {worst:.1f} texels"


def test_tessellate_small_far_triangle_untouched():
    """A 1 cm triangle 10 m away spans far less than a texel: no triangle is added."""
    tri = np.array([[[0.3, 0.2, 10.0], [0.31, 0.2, 10.0], [0.3, 0.21, 10.0]]])
    out, added = T.tessellate(tri, _paraboloid_texels(1024), 1.0)
    assert added == 0
    assert np.array_equal(out, tri)


def test_tessellate_empty_input():
    """No triangles: nothing out, nothing added."""
    out, added = T.tessellate(np.zeros((0, 3, 3)), _paraboloid_texels(256), 1.0)
    assert len(out) == 0 and added == 0


@pytest.mark.parametrize("mesh", ["box", "tetrahedron"])
@pytest.mark.parametrize("res", [128, 1024])
def test_tessellate_is_conforming(mesh, res):
    """A closed mesh in front of the light stays closed and crack-free: every
    undirected edge of the output is shared by exactly two triangles, and every
    directed edge meets its reverse (no T-junctions, consistent orientation)."""
    tris = _box((0.3, -0.2, 2.0), (6.0, 5.0, 2.5)) if mesh == "box" else _tetrahedron()
    assert tris[..., 2].min() > 0  # all in the paraboloid's front half-space
    out, added = T.tessellate(tris, _paraboloid_texels(res), 1.0)
    assert added > 0
    directed = Counter(_directed_edges(out))
    undirected = Counter(frozenset(e) for e in directed.elements())
    assert set(undirected.values()) == {2}
    assert all(directed[(b, a)] == 1 for (a, b), n in directed.items() if n == 1)
    assert set(directed.values()) == {1}


@pytest.mark.parametrize("mesh", ["floor", "box"])
def test_tessellate_monotone_in_resolution(mesh):
    """A finer map never yields fewer triangles."""
    tris = _floor_quad(20.0, 2.0) if mesh == "floor" else _box((0.0, 0.0, 2.0), (6.0, 5.0, 2.5))
    counts = [len(T.tessellate(tris, _paraboloid_texels(res), 1.0)[0]) for res in (16, 64, 128, 256, 512, 1024)]
    assert counts == sorted(counts), counts
    assert counts[-1] > counts[0]



def _inside_any(points: np.ndarray, pieces: np.ndarray) -> np.ndarray:
    """(N,) True where a point lies in one of the (coplanar) triangles, edges included."""
    inside = np.zeros(len(points), dtype=bool)
    for a, b, c in pieces:
        n = np.cross(b - a, c - a)
        scale = np.linalg.norm(n)
        on_plane = np.abs((points - a) @ n) <= 1e-7 * scale * (np.abs(points).max() + 1.0)
        edges = [np.cross(q - p, points - p) @ n for p, q in ((a, b), (b, c), (c, a))]
        inside |= on_plane & np.all(np.stack(edges) >= -1e-9 * scale * scale, axis=0)
    return inside


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 100_000), st.floats(1e-4, 0.05))
def test_split_at_seam_overlap_reach(seed, overlap):
    """With an overlap, a crossing triangle's pieces reach past the seam by at least the
    overlap angle along the cut (where the cap does not apply) and by at most twice it
    anywhere; one-sided triangles stay on their side only."""
    rng = np.random.default_rng(seed)
    tris = rng.normal(size=(12, 3, 3)) * rng.uniform(0.1, 50.0)
    z = tris[..., 2]
    one_sided = ~((z.max(axis=1) > 0) & (z.min(axis=1) < 0))
    front, back = T.split_at_seam(tris[one_sided], overlap)
    exact_front, exact_back = T.split_at_seam(tris[one_sided])
    assert np.array_equal(front, exact_front) and np.array_equal(back, exact_back)
    for tri in tris[~one_sided]:
        front, back = T.split_at_seam(tri[None], overlap)
        for pieces, sign in ((front, 1.0), (back, -1.0)):
            if len(pieces) == 0:
                continue
            elevation = np.arcsin(np.clip(sign * pieces[..., 2] / np.linalg.norm(pieces, axis=2), -1, 1))
            assert np.all(elevation >= -2.0 * overlap * (1 + 1e-9))
        # Along the cut: points of the triangle just past the seam, 0.99 overlap deep.
        normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        normal /= np.linalg.norm(normal)
        plane_distance = abs(normal @ tri[0])
        line = np.cross(normal, [0.0, 0.0, 1.0])
        if np.linalg.norm(line) < 1e-6:
            continue
        line /= np.linalg.norm(line)
        down = np.cross(normal, line)  # in the plane, across the cut
        down *= -np.sign(down[2]) if down[2] != 0 else 1.0  # pointing to z < 0
        za, zb = tri[:, 2], np.roll(tri, -1, axis=0)[:, 2]
        cuts = (za > 0) != (zb > 0)
        t = za[cuts] / (za[cuts] - zb[cuts])
        ends = tri[cuts] + t[:, None] * (np.roll(tri, -1, axis=0)[cuts] - tri[cuts])
        if len(ends) < 2 or np.sin(overlap) * np.linalg.norm(ends, axis=1).max() > np.sin(2 * overlap) * plane_distance:
            continue  # the cap applies: only the upper bound is promised
        on_cut = ends[0] + np.linspace(0.02, 0.98, 25)[:, None] * (ends[1] - ends[0])
        depth = np.sin(0.99 * overlap) * np.linalg.norm(on_cut, axis=1) / max(abs(down[2]), 1e-12)
        probe = on_cut + depth[:, None] * down
        inside_tri = _inside_any(probe, tri[None])
        if inside_tri.any():
            assert _inside_any(probe[inside_tri], front).all()
