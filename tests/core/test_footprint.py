"""Footprints and the exact inside test (addon.core.footprint) against the exact ray caster.

For random triangles (seen whole, straddling the seam, covering the pole, grazing the
light, huge), every texel centre of a 64x64 layer whose own ray hits the triangle
must lie in the triangle's footprint: plain paraboloid and cube layers, and layers
with a DV crop and a NoTW warp. The plain paraboloid and cube boxes are exact: they
match the box of 40,000 projected points of the triangle (its edges included) to
within 0.01 map units.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from addon.core import footprint as fp
from addon.core.projection import cube_unproject, paraboloid_unproject
from addon.core.warping import LayerMapping, Warp, build_notw
from tests.support.oracle import ray_hits

RES = 64
CENTRES = (np.arange(RES) + 0.5) / RES  # texel centres in uv


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _triangle(rng: np.random.Generator, kind: str) -> np.ndarray:
    """A light-centred triangle of one of the hard kinds."""
    if kind == "front":
        centre = rng.normal(size=3) * 0.4 + np.array([0.0, 0.0, 2.0])
        return centre + rng.normal(size=(3, 3)) * 0.6
    if kind == "seam":  # crosses z = 0
        tri = rng.normal(size=(3, 3))
        tri[:, 2] = [-0.8, 0.5, 1.1] + rng.normal(size=3) * 0.1
        return tri + np.array([0.0, 0.0, 0.0])
    if kind == "pole":  # the layer's axis passes through it
        angles = rng.uniform(0, 2 * np.pi) + np.array([0.0, 2.1, 4.2])
        ring = np.stack([np.cos(angles), np.sin(angles), np.full(3, 0.0)], axis=1) * rng.uniform(0.5, 3.0)
        return ring + np.array([0.0, 0.0, rng.uniform(0.2, 2.0)])
    if kind == "near_light":  # one vertex almost at the light
        tri = rng.normal(size=(3, 3))
        tri[0] = rng.normal(size=3) * 1e-4
        return tri
    if kind == "huge":
        return rng.normal(size=(3, 3)) * 1e4 + np.array([0.0, 0.0, 10.0])
    raise ValueError(kind)


KINDS = ("front", "seam", "pole", "near_light", "huge")


def _hits(dirs: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Exact: the ray from the light along each direction meets the triangle."""
    t, _ = ray_hits(np.zeros_like(dirs), dirs, tri[None], eps=0.0)
    return np.isfinite(t)


def _covered(dirs_of_texels: np.ndarray, valid: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(RES, RES) texels (row j, column i) whose ray hits the triangle."""
    flat = dirs_of_texels.reshape(-1, 3)
    hit = np.zeros(len(flat), dtype=bool)
    hit[valid.ravel()] = _hits(flat[valid.ravel()], tri)
    return hit.reshape(RES, RES)


def _assert_inside_range(covered: np.ndarray, box: np.ndarray) -> tuple[int, int, int, int] | None:
    """Every covered texel lies in the box's texel range; return the covered texels' own range."""
    i0, i1, j0, j1 = fp.texel_range(box, RES)
    rows, cols = np.nonzero(covered)
    if not len(rows):
        return None
    assert cols.min() >= i0 and cols.max() <= i1 and rows.min() >= j0 and rows.max() <= j1, (
        (cols.min(), cols.max(), rows.min(), rows.max()), (i0, i1, j0, j1))
    return cols.min(), cols.max(), rows.min(), rows.max()


def _layer_dirs(unproject, mapping: LayerMapping) -> tuple[np.ndarray, np.ndarray]:
    """Each texel centre's ray (RES, RES, 3), through the inverse map, and where it is defined."""
    u, v = np.meshgrid(CENTRES, CENTRES)  # [j, i]
    dirs = unproject(mapping.inverse(np.stack([u, v], axis=-1)))
    return dirs, np.all(np.isfinite(dirs), axis=-1)


@pytest.mark.parametrize("kind", KINDS)
def test_inside_test_matches_the_ray_caster(kind):
    rng = np.random.default_rng(KINDS.index(kind))
    for _ in range(20):
        tri = _triangle(rng, kind)
        dirs = rng.normal(size=(400, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        normals, sign = fp.edge_planes(tri[None])
        ours = fp.inside(dirs, normals, sign)[:, 0]
        exact = _hits(dirs, tri)
        # Rays within 1e-9 rad of an edge plane may go either way.
        margin = np.min(np.abs(dirs @ (normals[0] / np.linalg.norm(normals[0], axis=1, keepdims=True)).T), axis=1)
        clear = margin > 1e-9
        assert np.array_equal(ours[clear], exact[clear])


def test_a_triangle_through_the_light_covers_nothing():
    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    normals, sign = fp.edge_planes(tri[None])
    assert sign[0] == 0.0
    assert not fp.inside(np.array([[0.3, 0.3, 1.0]]), normals, sign).any()


@pytest.mark.parametrize("kind", KINDS)
def test_paraboloid_footprint_covers_and_is_tight(kind):
    rng = np.random.default_rng(10 + KINDS.index(kind))
    dirs, valid = _layer_dirs(paraboloid_unproject, LayerMapping.identity())
    valid &= np.linalg.norm(dirs[..., :2] / (1.0 + dirs[..., 2:3]), axis=-1) <= 1.0  # the disk
    checked = 0
    for _ in range(25):
        tri = _triangle(rng, kind) @ _random_rotation(rng).T
        box = fp.paraboloid_box(tri)
        covered = _covered(dirs, valid, tri)
        own = _assert_inside_range(covered, fp.map_box(box, LayerMapping.identity()))
        if own is None:
            continue
        checked += 1
        _assert_tight(box, _sampled_box(tri, 0.0, lambda p: p[:, :2] / (np.linalg.norm(p, axis=1) + p[:, 2])[:, None]))
    assert checked >= 5


def _sampled_box(tri: np.ndarray, z_min: float, project) -> np.ndarray:
    """Box of the projections of many points of the triangle (edges included) with z >= z_min."""
    rng = np.random.default_rng(0)
    w = rng.dirichlet(np.ones(3), size=30_000)
    # Dense near both ends too: near a vertex at the light, directions turn fast.
    ends = np.geomspace(1e-9, 0.5, 1000)
    edge_t = np.concatenate([np.linspace(0.0, 1.0, 3334), ends, 1.0 - ends])[:, None]
    edges = [tri[k] + edge_t * (tri[(k + 1) % 3] - tri[k]) for k in range(3)]
    # Where the triangle meets the plane z = z_min: the clipped polygon's own edge.
    crossings = [tri[k] + (z_min - tri[k, 2]) / (tri[(k + 1) % 3, 2] - tri[k, 2]) * (tri[(k + 1) % 3] - tri[k])
                 for k in range(3) if (tri[k, 2] - z_min) * (tri[(k + 1) % 3, 2] - z_min) < 0.0]
    if len(crossings) == 2:
        segment = crossings[0] + edge_t * (crossings[1] - crossings[0])
        segment[:, 2] = z_min  # on the plane exactly (rounding would drop half of it)
        edges.append(segment)
    points = np.concatenate([w @ tri, *edges])
    xy = np.clip(project(points[points[:, 2] >= z_min]), -1.0, 1.0)
    return np.array([xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()])


def _assert_tight(box: np.ndarray, sampled: np.ndarray, tolerance: float = 0.01) -> None:
    """The exact box holds the sampled one and exceeds it by at most `tolerance` on any side."""
    assert box[0] <= sampled[0] + 1e-9 and box[1] >= sampled[1] - 1e-9
    assert box[2] <= sampled[2] + 1e-9 and box[3] >= sampled[3] - 1e-9
    assert np.all(np.abs(box - sampled) <= tolerance), (box, sampled)


@pytest.mark.parametrize("kind", ("front", "seam", "pole", "huge"))
def test_cube_footprint_covers_and_is_tight(kind):
    rng = np.random.default_rng(20 + KINDS.index(kind))
    dirs, valid = _layer_dirs(cube_unproject, LayerMapping.identity())
    checked = 0
    for _ in range(25):
        tri = _triangle(rng, kind) @ _random_rotation(rng).T
        box = fp.cube_box(tri, 1e-6 * np.abs(tri).max())
        covered = _covered(dirs, valid, tri)
        own = _assert_inside_range(covered, fp.map_box(box, LayerMapping.identity()))
        if own is None:
            continue
        checked += 1
        near = 1e-6 * np.abs(tri).max()
        _assert_tight(box, _sampled_box(tri, near, lambda p: p[:, :2] / p[:, 2:3]))
    assert checked >= 5


def _warp(rng: np.random.Generator) -> Warp:
    """A strong NoTW warp from clustered samples."""
    centres = rng.uniform(0.2, 0.8, size=(3, 2))
    uv = np.concatenate([c + rng.normal(size=(3000, 2)) * 0.05 for c in centres])
    return build_notw(np.clip(uv, 0.0, 1.0), 32)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(KINDS))
def test_warped_cropped_paraboloid_footprint_covers(seed, kind):
    rng = np.random.default_rng(seed)
    warp = _warp(rng)
    lo = rng.uniform(0.0, 0.3, size=2)
    hi = lo + rng.uniform(0.3, 1.0 - lo.max(), size=2)
    mapping = LayerMapping(lo, hi, warp)
    dirs, valid = _layer_dirs(paraboloid_unproject, mapping)
    valid &= np.linalg.norm(dirs[..., :2] / (1.0 + dirs[..., 2:3]), axis=-1) <= 1.0
    tri = _triangle(rng, kind) @ _random_rotation(rng).T
    box = fp.map_box(fp.paraboloid_box(tri), mapping)
    _assert_inside_range(_covered(dirs, valid, tri), box)


def test_warped_footprints_cover_across_many_layers():
    """The same as above over fixed seeds, requiring that most triangles do cover texels."""
    covering = 0
    for seed in range(40):
        rng = np.random.default_rng(1000 + seed)
        warp = _warp(rng)
        lo, hi = np.array([0.1, 0.05]), np.array([0.85, 0.9])
        mapping = LayerMapping(lo, hi, warp)
        dirs, valid = _layer_dirs(paraboloid_unproject, mapping)
        valid &= np.linalg.norm(dirs[..., :2] / (1.0 + dirs[..., 2:3]), axis=-1) <= 1.0
        tri = _triangle(rng, KINDS[seed % len(KINDS)]) @ _random_rotation(rng).T
        box = fp.map_box(fp.paraboloid_box(tri), mapping)
        covering += _assert_inside_range(_covered(dirs, valid, tri), box) is not None
    assert covering >= 20


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_map_stretch_bounds_every_warped_box(seed):
    """The host's point-sprite choice rests on map_stretch: a plain box of side d is at most
    map_stretch * d a side after the crop and warp_box, wherever it lies."""
    from addon.render.parameterizations import map_stretch

    rng = np.random.default_rng(seed)
    lo = rng.uniform(0.0, 0.3, size=2)
    mapping = LayerMapping(lo, lo + rng.uniform(0.2, 1.0 - lo.max(), size=2), _warp(rng))
    stretch = map_stretch(mapping)
    for _ in range(200):
        side = rng.uniform(1e-4, 0.05, size=2)
        u0, v0 = rng.uniform(0.0, 1.0 - side)
        box = np.array([u0, u0 + side[0], v0, v0 + side[1]])
        mapped = fp.map_box(box, mapping)
        assert max(mapped[1] - mapped[0], mapped[3] - mapped[2]) <= stretch * side.max() * (1 + 1e-9) + 1e-12
