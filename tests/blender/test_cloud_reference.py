"""Volume objects' density grids, read as Cycles renders them (issue 43, grid media).

tests/support/make_cloud_blend.py builds clouds as artists make them: a Mesh to Volume
modifier filling an icosphere, a geometry-nodes Volume Cube of noise density on a mesh
(its material set by Set Material), a Volume object loading a saved .vdb file, and a haze of Cycles' default volume shader around
a figure, reaching below the ground. `volume_grids` reads each grid into a GridMedium:

- the read grid is Sample Grid's own trilinear field at random world points, its bounds
  those of the cloud, and it leaves nothing in bpy.data;
- the reference (two halves of 32 samples) on the ground, and on the figure standing in
  the haze, is `core.media.visibility(grid_optical_depths(...))` of the grids it stores,
  within the reference's own noise (Cycles' heterogeneous shadows are noisy).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("bpy", reason="the clouds and their reference need bpy")

from addon.core.media import GridMedium  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from addon.compat.blender import grid_nodes_available  # noqa: E402
from tests.support.cli_run import SUPPORT, checked_arrays, python_ok  # noqa: E402
from tests.support.plain_cycles import mean_visibilities  # noqa: E402
from tests.support.make_cloud_blend import VARIANTS  # noqa: E402
from tests.support.make_fog_blend import grids_oracle  # noqa: E402

pytestmark = pytest.mark.blender

# Each variant's extinction per unit density: Vapour's Principled Volume (density 2, colour
# 0.8: 2 (0.8 + 0.2)), and Cycles' default volume shader's (1) for the haze without a material.
SIGMA = {"mesh_to_volume": 2.0, "noise": 2.0, "vdb": 2.0, "inside": 1.0}
SOFT_SAMPLES = 64


@pytest.fixture(scope="module", params=VARIANTS)
def checked(request, tmp_path_factory):
    """(variant, the check's arrays: make_cloud_blend.check)."""
    if not grid_nodes_available():
        pytest.skip("this Blender line has no grid nodes to read or probe grids with (a line gap, "
                    "test_the_reference_is_the_grids_oracle checks what it does instead)")
    folder = tmp_path_factory.mktemp(f"check_{request.param}")
    return request.param, checked_arrays(SUPPORT / "make_cloud_blend.py", folder, "cloud.blend", request.param)


def test_the_grid_is_sample_grids_field(checked):
    name, found = checked
    grid = GridMedium(str(found["name"]), found["sigma"], found["density"], found["to_index"])
    sampled = found["sampled"].astype(np.float64)
    # The points cover the cloud and a margin: some in it, some out.
    assert 0.1 < float((sampled > 0.0).mean()) < 0.95 and sampled.max() > 0.5
    error = np.abs(grid.density_at(found["points"]) - sampled)
    assert error.max() < 1e-5 * sampled.max() + 1e-6, (name, error.max())
    assert np.allclose(grid.sigma, SIGMA[name])
    # Cropped to its non-zero voxels plus one: within the cloud's bounds and a voxel (a
    # voxel's world box: up to sqrt(3) voxels wide for a turned grid, the vdb's).
    lo, hi = grid.world_bounds()
    voxel = 1.01 * np.sqrt(3.0) * grid.voxel_size()
    assert np.all(lo >= found["box"][0] - voxel) and np.all(hi <= found["box"][1] + voxel), (lo, hi)
    inside = (found["points"] >= lo).all(axis=1) & (found["points"] <= hi).all(axis=1)
    assert not np.any(sampled[~inside] > 0.0)
    assert list(found["before"]) == list(found["after"])  # no reader left in bpy.data
    assert not len(found["left_out"])  # read: not named


def test_a_small_budget_reads_every_few_voxels(checked):
    """Past the budget the lattice strides: coarser voxels, a resampling error."""
    name, found = checked
    small = GridMedium("small", found["sigma"], found["small_density"], found["small_to_index"])
    full = GridMedium("full", found["sigma"], found["density"], found["to_index"])
    assert small.density.size <= 16 ** 3 < full.density.size
    assert small.voxel_size() >= 2.0 * full.voxel_size() - 1e-9
    error = np.abs(small.density_at(found["points"]) - found["sampled"])
    assert 0.0 < error.mean() < 0.1 * float(found["sampled"].max()), (name, error.mean())


@pytest.fixture(scope="module", params=VARIANTS)
def cloud(request, tmp_path_factory):
    """(variant, its reference)."""
    folder = tmp_path_factory.mktemp(f"cloud_{request.param}")
    python_ok(SUPPORT / "make_cloud_blend.py", folder / "cloud.blend", "--variant", request.param,
              "--reference", folder / "ref.npz", "--soft-samples", SOFT_SAMPLES)
    return request.param, ReferenceData.load(folder / "ref.npz"), folder / "ref.npz"


def test_the_reference_is_the_grids_oracle(cloud):
    name, ref, _ = cloud
    if not grid_nodes_available():
        # No grid is read on this line: the cloud is named, and every row says so.
        from addon.readers.volume_grids import NO_GRID_NODES

        assert ref.grids == () and any(NO_GRID_NODES in note for note in ref.meta["left_out"])
        return
    assert len(ref.grids) == 1 and np.allclose(ref.grids[0].sigma, SIGMA[name])
    assert not ref.meta["left_out"] and ref.meta["occluder_grids"] == 1
    # Camera rays cross the cloud (its volume acts on shadow rays alone): nearly every
    # pixel hits, a few whose first sample ended in the haze lose their position.
    assert ref.hit.mean() > 0.97 and ref.meta["positions_lost"] < 0.03 * ref.hit.size
    ratio, lit, ground, oracle, under = grids_oracle(ref)
    assert under.sum() > 1000 and float(oracle[under].mean()) < 0.9, (name, under.sum())
    noise = ref.visibility_noise
    for pixels in (ground, under):
        error = (ratio - oracle)[pixels]
        tolerance = 2.0 * float(noise[pixels].mean()) + 1e-3
        assert np.abs(error).mean() <= tolerance, (name, np.abs(error).mean(), tolerance)
        assert abs(float(error.mean())) <= 0.5 * float(noise[pixels].mean()) + 1e-3, (name, error.mean())
        # Without the cloud the ground would be lit: the test can tell.
        assert np.abs(1.0 - ratio[pixels]).mean() > tolerance
    if name == "inside":  # the figure stands in the haze: shadowed by it from itself on
        figure = lit & (np.abs(ref.position[..., 2]) >= 1e-3)
        error = np.abs(ratio - oracle)[figure]
        assert figure.sum() > 100 and float(oracle[figure].mean()) < 0.97
        assert error.mean() <= 2.0 * float(noise[figure].mean()) + 1e-3, (error.mean(), noise[figure].mean())


def test_the_grids_are_stored_and_loaded_back(cloud, tmp_path):
    if not grid_nodes_available():
        pytest.skip("this Blender line reads no grids (test_the_reference_is_the_grids_oracle checks it)")
    _, ref, path = cloud
    again = ReferenceData.load(ref.save(tmp_path / "again.npz"))
    (a,), (b,) = ref.grids, again.grids
    assert a.name == b.name and a.digest == b.digest
    assert np.array_equal(a.density, b.density) and np.array_equal(a.to_index, b.to_index)
    # A file written before grids (no grid arrays, no names) loads with none.
    with np.load(path) as npz:
        kept = {key: npz[key] for key in npz.files if not key.startswith("grid")}
    meta = dict(ref.meta)
    meta.pop("grids")
    kept["meta"] = np.array(json.dumps({**meta, "format_version": json.loads(str(kept["meta"]))["format_version"]}))
    np.savez(tmp_path / "old.npz", **kept)
    assert ReferenceData.load(tmp_path / "old.npz").grids == ()


def test_the_reference_matches_a_plain_render(cloud):
    """Within 1 point of a plain Cycles render's mean visibility (the file's own materials,
    one sample) over the pixels both hit: the plain render's camera rays cross the cloud,
    so some of its pixels end there and are left out."""
    _, ref, path = cloud
    ours, theirs, share = mean_visibilities(ref, path.parent / "cloud.blend", path.parent / "plain.npz")
    assert share > 0.5 and abs(ours - theirs) < 0.01, (ours, theirs, share)
