"""Light frames: the map layers (paraboloid sides or cube faces) of one light.

Each layer has a fixed slot index, a kind and a rotation taking world directions
into the layer's local frame, whose +Z is the layer axis.

Slots:
  dpsm: 0 = the side looking along the light's local -Z (its axis; the only side
        of a hemispherical light), 1 = the side looking along local +Z.
  cube: 0..5 = faces looking along local +X, -X, +Y, -Y, +Z, -Z. A hemispherical
        light drops face 4 (+Z), which looks away from its axis: at most 5 faces.
  unfold: the two halves of one sphere-unfolding map, centred on the same poles as
        the dpsm sides (0 = local -Z, 1 = local +Z), drawn in one pass. A
        hemispherical light uses half 0 only.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from .errors import InputError
from .projection import CUBE, PARABOLOID, PROJECTIVE, UNFOLD
from .scene import PROJECTIVE_EMISSIONS, LightSpec

Parameterization = Literal["dpsm", "cube", "ipsm", "unfold", "sm", "psm"]
POINT_PARAMETERIZATIONS = ("dpsm", "cube", "ipsm", "unfold")  # omni and hemi lights
PROJECTIVE_PARAMETERIZATIONS = ("sm", "psm")  # spot (cone below 180 degrees) and sun lights

CUBE_FACE_NAMES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
CUBE_FACE_AXES = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64
)
PARABOLOID_SIDE_NAMES = ("axis(-Z)", "back(+Z)")
UNFOLD_HALF_NAMES = ("unfold(-Z)", "unfold(+Z)")
# Side 0's frame in light space: x = +X_l, y = -Y_l, z = -Z_l (right-handed); side 1's
# is the identity. So side 1 = FLIP_YZ @ side 0 (the depth pass and seam split use this).
FLIP_YZ = np.diag([1.0, -1.0, -1.0])
HEMI_DROPPED_CUBE_FACE = 4


@dataclass(frozen=True)
class Layer:
    """One map layer of a light."""

    slot: int
    kind: int  # PARABOLOID or CUBE
    name: str
    rotation: np.ndarray  # (3, 3) world direction -> layer local (rows are layer axes in world)

    def to_local(self, world_offsets: np.ndarray) -> np.ndarray:
        """Rotate light-centred world vectors (..., 3) into the layer frame."""
        return np.asarray(world_offsets, dtype=np.float64) @ self.rotation.T


def _frame_from_axis(axis_local: np.ndarray) -> np.ndarray:
    """Right-handed local frame (rows x, y, z) with z = `axis_local`, in light space."""
    z = axis_local / np.linalg.norm(axis_local)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.5 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z])


def light_layers(light: LightSpec, parameterization: Parameterization) -> list[Layer]:
    """Every layer the light's emission can use (before any culling)."""
    light_rot = light.rotation  # light local -> world
    world_to_light = light_rot.T
    layers: list[Layer] = []
    if parameterization in ("dpsm", "unfold"):
        side_frames = [FLIP_YZ, np.eye(3)]
        count = 1 if light.emission == "hemi" else 2
        kind, names = (PARABOLOID, PARABOLOID_SIDE_NAMES) if parameterization == "dpsm" else (UNFOLD, UNFOLD_HALF_NAMES)
        for slot in range(count):
            layers.append(Layer(slot, kind, names[slot], side_frames[slot] @ world_to_light))
    elif parameterization == "cube":
        for slot, axis in enumerate(CUBE_FACE_AXES):
            if light.emission == "hemi" and slot == HEMI_DROPPED_CUBE_FACE:
                continue
            layers.append(Layer(slot, CUBE, CUBE_FACE_NAMES[slot], _frame_from_axis(axis) @ world_to_light))
    else:
        raise InputError(f"unknown parameterization {parameterization!r}; use 'dpsm', 'cube' or 'unfold'")
    return layers


def ipsm_layer(axis_world: np.ndarray) -> Layer:
    """The single paraboloid of IPSM (thesis 4.1), looking along the cone axis C (world)."""
    return Layer(0, PARABOLOID, "ipsm", _frame_from_axis(np.asarray(axis_world, dtype=np.float64)))


def parameterizations_for(emission: str) -> tuple[str, ...]:
    """The parameterizations that fit a light's emission: spot cones and suns take the
    projective maps, omni and hemi lights the omnidirectional ones."""
    return PROJECTIVE_PARAMETERIZATIONS if emission in PROJECTIVE_EMISSIONS else POINT_PARAMETERIZATIONS


# The parameterizations a warp applies to. unfold draws its two halves in one pass with
# one projection, and PSM is itself a global warp, so neither takes one.
WARPABLE_PARAMETERIZATIONS = ("dpsm", "cube", "ipsm")


def takes_warp(parameterization: str) -> bool:
    """True for the parameterizations a NoTW or RTW warp applies to."""
    return parameterization in WARPABLE_PARAMETERIZATIONS


# The parameterizations the exact pass (the irregular z-buffer) runs over: the ones whose
# triangles are drawn over conservative footprints in the resident pass. unfold draws a
# tessellated host stream, and PSM's post-perspective map would only move texels that
# the exact pass does not need; spot and sun lights take their plain map (sm).
EXACT_PARAMETERIZATIONS = ("dpsm", "cube", "ipsm", "sm")


def takes_exact(parameterization: str) -> bool:
    """True for the parameterizations the exact pass runs over."""
    return parameterization in EXACT_PARAMETERIZATIONS


def projective_layer(parameterization: Parameterization) -> Layer:
    """The one layer of a spot or sun map; its matrix lives in the plan, not in the frame."""
    return Layer(0, PROJECTIVE, parameterization, np.eye(3))


def slot_count(parameterization: Parameterization) -> int:
    """Number of slots of a parameterization (2 sides or halves, or 6 faces)."""
    return 2 if parameterization in ("dpsm", "unfold") else 6


def pick_slot(parameterization: Parameterization, light_local_dirs: np.ndarray) -> np.ndarray:
    """Slot each light-local direction (..., 3) falls in; same rule as the GLSL test.

    ipsm: always slot 0.
    dpsm, unfold: local z <= 0 -> slot 0 (the axis side, or the nearer pole), else slot 1.
    cube: the major axis; ties go to X before Y before Z.
    """
    d = np.asarray(light_local_dirs, dtype=np.float64)
    if parameterization == "ipsm":
        return np.zeros(d.shape[:-1], dtype=np.int64)  # one layer; the cone holds every sample
    if parameterization in ("dpsm", "unfold"):
        return np.where(d[..., 2] <= 0.0, 0, 1)
    ax, ay, az = np.abs(d[..., 0]), np.abs(d[..., 1]), np.abs(d[..., 2])
    use_x = (ax >= ay) & (ax >= az)
    use_y = ~use_x & (ay >= az)
    slot_x = np.where(d[..., 0] >= 0, 0, 1)
    slot_y = np.where(d[..., 1] >= 0, 2, 3)
    slot_z = np.where(d[..., 2] >= 0, 4, 5)
    return np.where(use_x, slot_x, np.where(use_y, slot_y, slot_z))


def in_emission(light: LightSpec, world_offsets: np.ndarray) -> np.ndarray:
    """True where a light-centred world vector lies in the light's emission domain."""
    if light.emission == "omni":
        return np.ones(np.asarray(world_offsets).shape[:-1], dtype=bool)
    return np.asarray(world_offsets, dtype=np.float64) @ light.axis > 0.0
