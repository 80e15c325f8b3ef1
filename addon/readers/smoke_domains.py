"""A fluid simulation's smoke domain, read as the Volume geometry Cycles renders.

Cycles does not render a gas domain's mesh (`Fluid` modifier, domain type Gas): it makes
the object Volume geometry whose grids are the simulation's (its Blender sync,
`sync_smoke_volume`), bounded by the voxels that hold smoke. So:

- the domain's triangles are no surface and no medium (`is_gas_domain`: the render
  geometry leaves them out, in the capture and in the viewport alike);
- its density is `FluidDomainSettings.density_grid` (`flame_grid`, `heat_grid`,
  `temperature_grid` for a material that reads those), res x, y, z voxels (x fastest),
  times the noise's upres factor when the noise is on (heat stays at the base
  resolution). The voxels fill the domain mesh's texture space box, each value at its
  cell's centre; outside the box the density is 0;
- the material's extinction per unit density and the grid it reads are the Volume
  objects' (`material_media.grid_sigma`);
- outside the cache's frame range, or with no simulation data (an unbaked domain: every
  voxel 0), the domain casts nothing, as Cycles renders it.

The density is read with `foreach_get`, no geometry nodes: it works on every Blender line.
Past `volume_grids.BUDGET` voxels every s-th voxel is kept (the same lattice as the grid
readers). bpy is only touched through the objects passed in.
"""
from __future__ import annotations

import logging
from typing import Any

import numpy as np

from ..core.media import GridMedium
from .material_media import GridSigma
from .volume_grids import BUDGET, VolumeSource, dense_medium, lattice, object_grid_sigma

log = logging.getLogger(__name__)

# The grids a smoke domain hands a volume shader, by attribute name (Cycles' standard names).
SMOKE_GRIDS = {"density": "density_grid", "flame": "flame_grid", "heat": "heat_grid",
               "temperature": "temperature_grid"}
# Cycles reads these at the base resolution even with the noise's upres on.
_BASE_RESOLUTION = {"heat"}


def gas_domain(obj: Any) -> Any | None:
    """The FluidDomainSettings of an object's gas domain, or None (Cycles'
    `object_fluid_gas_domain_find`: the first Fluid modifier that is a gas domain)."""
    for modifier in getattr(obj, "modifiers", ()):
        if modifier.type == "FLUID" and modifier.fluid_type == "DOMAIN":
            settings = modifier.domain_settings
            if settings is not None and settings.domain_type == "GAS":
                return settings
    return None


def is_gas_domain(obj: Any) -> bool:
    """Whether Cycles renders this mesh object as smoke (Volume geometry), not as a mesh."""
    return getattr(obj, "type", None) == "MESH" and gas_domain(obj) is not None


def index_to_object(resolution: tuple[int, int, int], location: np.ndarray, size: np.ndarray) -> np.ndarray:
    """(4, 4): a voxel's index (i, j, k), its centre, to object space. The voxels tile the
    texture space box [location - size, location + size]."""
    step = 2.0 * np.asarray(size, dtype=np.float64) / np.asarray(resolution, dtype=np.float64)
    out = np.eye(4)
    out[:3, :3] = np.diag(step)
    out[:3, 3] = np.asarray(location, dtype=np.float64) - np.asarray(size, dtype=np.float64) + 0.5 * step
    return out


def domain_grid(settings: Any, grid: str) -> tuple[tuple[int, int, int], np.ndarray | None]:
    """((x, y, z) resolution, the grid's values (nz, ny, nx) float32) of a domain; None
    when it holds no data of that size (Cycles then loads nothing)."""
    resolution = tuple(int(v) for v in settings.domain_resolution)
    amplify = int(settings.noise_scale) if settings.use_noise and grid not in _BASE_RESOLUTION else 1
    nx, ny, nz = (v * amplify for v in resolution)
    prop = getattr(settings, SMOKE_GRIDS[grid])
    if len(prop) != nx * ny * nz or not len(prop):
        log.debug("smoke grid %s: %d values for %dx%dx%d voxels: none", grid, len(prop), nx, ny, nz)
        return (nx, ny, nz), None
    values = np.empty(len(prop), dtype=np.float32)
    prop.foreach_get(values)
    return (nx, ny, nz), values.reshape(nz, ny, nx)


def smoke_medium(inst: Any, frame: float, materials: dict[str, GridSigma] | None = None
                 ) -> GridMedium | str | None:
    """The grid medium of one gas-domain instance of a render depsgraph at `frame`: None
    when it holds no smoke (it blocks nothing), or why it was not read. `materials` caches
    `grid_sigma` by material name."""
    obj = inst.object
    parent = inst.parent if inst.is_instance else None
    settings = gas_domain(obj)
    if settings is None:
        return None
    if not settings.cache_frame_start <= frame <= settings.cache_frame_end:
        return None  # Cycles clears the grids outside the cache's frames
    sigma, grid = object_grid_sigma(obj, materials)
    if sigma is None:
        return grid
    if grid not in SMOKE_GRIDS:
        return f"a smoke domain has no grid named {grid!r}: not read"
    mesh = obj.data
    location = np.array(mesh.texspace_location, dtype=np.float64)
    size = np.array(mesh.texspace_size, dtype=np.float64)
    if np.any(np.abs(size) < 1e-12):
        return "a smoke domain whose texture space is flat: not read"
    resolution, values = domain_grid(settings, grid)
    if values is None or not np.any(values > 0.0):
        return None
    # One zero voxel beyond each face: the grid's background, which the trilinear
    # interpolation reaches over the outer half voxel.
    stride, axes = lattice(((-1, -1, -1), resolution), BUDGET)
    padded = np.pad(values, ((1, stride),) * 3)  # the lattice's last point may pass the grid
    z, y, x = (np.asarray(a, dtype=np.int64) + 1 for a in axes[::-1])
    sampled = padded[np.ix_(z, y, x)]
    source = VolumeSource(obj.original.name_full, None if parent is None else parent.original.name_full,
                          np.array(inst.matrix_world, dtype=np.float64), grid, np.asarray(sigma, dtype=np.float64),
                          index_to_object(resolution, location, size))
    medium = dense_medium(source, stride, axes, sampled.reshape(-1))
    if medium is not None:
        log.info("smoke medium %s: %s voxels of %.4g m (stride %d), density up to %.4g", medium.name,
                 "x".join(map(str, medium.density.shape[::-1])), medium.voxel_size(), stride,
                 float(medium.density.max()))
    return medium
