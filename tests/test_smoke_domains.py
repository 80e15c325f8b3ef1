"""readers/smoke_domains.py maps a smoke domain's voxels as Cycles' sync does (issue 43).

Mantaflow does not run in the PyPI bpy, so no baked domain can be made here: these tests
hand `smoke_medium` stand-ins for the depsgraph instance, its modifier settings and its
mesh, and check the GridMedium against the voxel values at their world centres (the
texture space box, the object's matrix, x fastest), the frame range, the noise's upres,
the budget's stride, and what is not read.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from addon.readers import smoke_domains


class _Grid:
    """A float array property: len() and foreach_get, as bpy's."""

    def __init__(self, values: np.ndarray) -> None:
        self.values = np.asarray(values, dtype=np.float32).reshape(-1)

    def __len__(self) -> int:
        return len(self.values)

    def foreach_get(self, out: np.ndarray) -> None:
        out[...] = self.values


def _instance(values: np.ndarray, resolution, matrix=np.eye(4), location=(0.0, 0.0, 0.0), size=(1.0, 1.0, 1.0),
              frames=(1, 250), noise: int = 0, flame: np.ndarray | None = None):
    settings = SimpleNamespace(domain_type="GAS", domain_resolution=resolution, use_noise=noise > 0,
                               noise_scale=max(noise, 1), cache_frame_start=frames[0], cache_frame_end=frames[1],
                               density_grid=_Grid(values), heat_grid=_Grid(values),
                               flame_grid=_Grid(values if flame is None else flame), temperature_grid=_Grid([]))
    modifier = SimpleNamespace(type="FLUID", fluid_type="DOMAIN", domain_settings=settings)
    obj = SimpleNamespace(type="MESH", modifiers=[modifier], material_slots=[],
                          original=SimpleNamespace(name_full="Smoke Domain"),
                          data=SimpleNamespace(texspace_location=location, texspace_size=size))
    return SimpleNamespace(object=obj, is_instance=False, parent=None, matrix_world=matrix)


def _matrix() -> np.ndarray:
    angle = 0.4
    m = np.eye(4)
    m[:3, :3] = np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0],
                          [0.0, 0.0, 1.0]]) * 1.5
    m[:3, 3] = (0.3, -0.2, 1.1)
    return m


def _centres(resolution, location, size, matrix) -> np.ndarray:
    """World centres of every voxel, (nz, ny, nx, 3)."""
    nx, ny, nz = resolution
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    u = (np.stack([i, j, k], axis=-1) + 0.5) / np.array([nx, ny, nz])
    local = np.asarray(location) - np.asarray(size) + 2.0 * np.asarray(size) * u
    return local @ matrix[:3, :3].T + matrix[:3, 3]


def test_the_voxels_fill_the_texture_space_box():
    rng = np.random.default_rng(3)
    resolution, location, size = (6, 5, 4), (0.2, 0.1, 1.0), (1.0, 0.8, 1.3)
    values = rng.uniform(0.0, 2.0, size=(4, 5, 6))
    matrix = _matrix()
    medium = smoke_domains.smoke_medium(_instance(values, resolution, matrix, location, size), 1)
    assert medium is not None and medium.name == "Smoke Domain"
    centres = _centres(resolution, location, size, matrix)
    assert np.allclose(medium.density_at(centres.reshape(-1, 3)), values.reshape(-1), atol=1e-5)
    # Beyond the box the background is 0: at a corner of the box (half a voxel past the
    # outer centres on three axes) the corner voxel's value falls to an eighth, one voxel
    # past them to 0.
    signs = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], dtype=float)
    step = 2.0 * np.asarray(size) / np.array(resolution)
    for past, weight in ((0.0, 0.125), (0.5, 0.0)):
        local = np.asarray(location) + signs * (np.asarray(size) + past * step)
        world = local @ matrix[:3, :3].T + matrix[:3, 3]
        corner_values = values[[0, -1]][:, [0, -1]][:, :, [0, -1]].reshape(-1)
        assert np.allclose(medium.density_at(world), weight * corner_values, atol=1e-5), past


def test_empty_or_out_of_range_domains_cast_nothing():
    values = np.ones((4, 5, 6))
    assert smoke_domains.smoke_medium(_instance(np.zeros((4, 5, 6)), (6, 5, 4)), 1) is None
    assert smoke_domains.smoke_medium(_instance(values, (6, 5, 4), frames=(10, 20)), 9) is None
    assert smoke_domains.smoke_medium(_instance(values, (6, 5, 4), frames=(10, 20)), 20) is not None
    # A grid of the wrong size (a cache from other settings): Cycles loads nothing.
    assert smoke_domains.smoke_medium(_instance(values, (6, 5, 5)), 1) is None


def test_the_noise_upres_multiplies_the_resolution():
    rng = np.random.default_rng(5)
    values = rng.uniform(0.1, 1.0, size=(8, 6, 4))  # a 2x upres of 2 x 3 x 4
    medium = smoke_domains.smoke_medium(_instance(values, (2, 3, 4), noise=2), 1)
    assert medium is not None and medium.density.shape[::-1] >= (4, 6, 8)
    centres = _centres((4, 6, 8), (0, 0, 0), (1, 1, 1), np.eye(4))
    assert np.allclose(medium.density_at(centres.reshape(-1, 3)), values.reshape(-1), atol=1e-5)
    # At the base resolution the upres grid does not fit: nothing is loaded.
    assert smoke_domains.smoke_medium(_instance(values, (2, 3, 4)), 1) is None


def test_past_the_budget_every_other_voxel_is_kept(monkeypatch):
    rng = np.random.default_rng(7)
    values = rng.uniform(0.1, 1.0, size=(8, 8, 8))
    monkeypatch.setattr(smoke_domains, "BUDGET", 6 ** 3)
    medium = smoke_domains.smoke_medium(_instance(values, (8, 8, 8)), 1)
    assert medium is not None and medium.voxel_size() == pytest.approx(2 * 2.0 / 8)
    centres = _centres((8, 8, 8), (0, 0, 0), (1, 1, 1), np.eye(4))
    kept = centres[1::2, 1::2, 1::2].reshape(-1, 3)  # the lattice from index -1 in steps of 2
    assert np.allclose(medium.density_at(kept), values[1::2, 1::2, 1::2].reshape(-1), atol=1e-5)


def test_what_is_not_read_says_why():
    values = np.ones((4, 5, 6))
    flat = _instance(values, (6, 5, 4), size=(1.0, 0.0, 1.0))
    assert "flat" in smoke_domains.smoke_medium(flat, 1)
    liquid = _instance(values, (6, 5, 4))
    liquid.object.modifiers[0].domain_settings.domain_type = "LIQUID"
    assert not smoke_domains.is_gas_domain(liquid.object) and smoke_domains.smoke_medium(liquid, 1) is None
    assert smoke_domains.is_gas_domain(_instance(values, (6, 5, 4)).object)
