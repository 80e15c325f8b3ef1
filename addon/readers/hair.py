"""Hair and points as Cycles draws them, read from an evaluated object of the render
depsgraph (`render_geometry.collect`): a point cloud's spheres, hair curves' strands and
a mesh's particle hair drawn as paths, in world space, their radii through the object's
or emitter's scale as Cycles' sync and its baking of transforms give them
(`strand_radius_scale`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..compat import blender as blender_compat
from ..core.blockers import Spheres, Strands
from .left_out import path_hair_systems

# Radii Cycles gives points and curve points without a radius attribute (its Blender sync).
DEFAULT_POINT_RADIUS = 0.01
DEFAULT_CURVE_RADIUS = 0.005


def _attribute(data: Any, name: str, width: int, count: int) -> np.ndarray | None:
    """A float attribute of a point cloud's or curves' points, (count, width), or None."""
    attribute = data.attributes.get(name)
    if attribute is None or attribute.domain != "POINT":
        return None
    values = np.empty(count * width, dtype=np.float32)
    attribute.data.foreach_get("vector" if width == 3 else "value", values)
    return values.reshape(count, width) if width > 1 else values


@dataclass(frozen=True)
class CurveShape:
    """How Cycles draws a scene's curves (`scene.cycles_curves.shape`): straight between
    their points ("Linear 3D Curves") and as ribbons facing the ray ("Ribbons")."""

    linear: bool = False
    flat: bool = False

    @classmethod
    def of(cls, scene: Any) -> "CurveShape":
        shape = getattr(getattr(scene, "cycles_curves", None), "shape", "")
        return cls(linear=shape == "THICK_LINEAR", flat=shape == "RIBBONS")


def points_or_strands(obj: Any, matrix: np.ndarray, shape: CurveShape = CurveShape()) -> "Spheres | Strands | None":
    """An evaluated point cloud's spheres, or hair curves' strands, in world space. Radii
    scale as `strand_radius_scale` says (a point's by the matrix's mean scale: a
    non-uniform scale makes ellipsoids in Cycles, which these are not). As Cycles does, an
    object's strands are straight between their points when its first curve is a poly
    curve (5.x), or when the scene's curve shape is "Linear 3D Curves"; else Catmull-Rom."""
    data = obj.data
    count = len(data.points)
    positions = _attribute(data, "position", 3, count)
    if positions is None or not count:
        return None
    world = positions.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    scale = abs(float(np.linalg.det(matrix[:3, :3]))) ** (1.0 / 3.0)
    radii = _attribute(data, "radius", 1, count)
    if obj.type == "POINTCLOUD":
        radii = np.full(count, DEFAULT_POINT_RADIUS) if radii is None else radii.astype(np.float64)
        return Spheres(world, radii * scale)
    radii = np.full(count, DEFAULT_CURVE_RADIUS) if radii is None else radii.astype(np.float64)
    offsets = np.empty(len(data.curve_offset_data), dtype=np.int32)
    data.curve_offset_data.foreach_get("value", offsets)
    curves = len(offsets) - 1
    linear = shape.linear or (blender_compat.has_linear_curves() and _first_curve_type(data, curves) == CURVE_POLY)
    scales = strand_radius_scale(matrix, positions.astype(np.float64), offsets)
    return Strands(world, radii * scales, offsets, np.full(curves, linear), np.full(curves, shape.flat))


def uniform_scale(matrix: np.ndarray) -> bool:
    """Whether a world matrix scales every axis alike (and keeps them at right angles), as
    Cycles asks before it bakes a transform into curves and points."""
    linear = np.asarray(matrix, dtype=np.float64)[:3, :3]
    gram = linear.T @ linear
    scale = float(np.trace(gram)) / 3.0
    return bool(np.abs(gram - scale * np.eye(3)).max() <= 1e-5 * max(scale, 1e-30))


def strand_radius_scale(matrix: np.ndarray, local: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """What a curve's radius at each of its points (`local`, object space, curves split at
    `offsets`) is multiplied by in world space, as Cycles draws it. A uniform scale s is
    baked into the keys and scales radii by s. A non-uniform one is not baked (Cycles
    cannot draw it with round tubes): the ray meets the round tube in object space, which
    is an elliptic tube in world space; it is drawn here as the round tube of the same
    cross-section area, whose radius is r sqrt(|det M| / |M t|) for a unit object-space
    tangent t (the cofactor identity: the circle's image has area pi r^2 |det M| |M^-T t|,
    its normal at 1 / (|M^-T t| |M t|) to the world tangent)."""
    linear = np.asarray(matrix, dtype=np.float64)[:3, :3]
    det = abs(float(np.linalg.det(linear)))
    uniform = det ** (1.0 / 3.0)
    if not len(local) or uniform_scale(matrix):
        return np.full(len(local), uniform)
    index = np.arange(len(local))
    sizes = np.diff(offsets)
    start = np.repeat(np.asarray(offsets[:-1]), sizes)
    end = np.repeat(np.asarray(offsets[1:]), sizes)
    tangent = local[np.minimum(index + 1, end - 1)] - local[np.maximum(index - 1, start)]
    length = np.linalg.norm(tangent, axis=1)
    world = np.linalg.norm(tangent @ linear.T, axis=1)
    ok = (length > 0.0) & (world > 0.0)
    out = np.full(len(local), uniform)
    out[ok] = np.sqrt(det * length[ok] / world[ok])
    return out


def _shape_radius(shape: float, root: float, tip: float, time: np.ndarray) -> np.ndarray:
    """A particle strand's radius along its length (time 0 at the root, 1 at the tip): from
    root to tip, bent by the settings' shape in (-1, 1), as Cycles' particle hair has it."""
    radius = 1.0 - np.asarray(time, dtype=np.float64)
    if shape < 0.0:
        radius = radius ** (1.0 + shape)
    elif shape > 0.0:
        radius = radius ** (1.0 / (1.0 - shape))
    return radius * (root - tip) + tip


def particle_strands(obj: Any, shape: CurveShape, matrix: np.ndarray | None = None) -> list[Strands]:
    """The strands of an evaluated mesh's hair particle systems drawn as paths, in world
    space, as Cycles reads them: 2^render_step + 1 keys a strand (more for a spiral kink),
    the children alone when there are any, the radius from the settings' root, tip and
    shape along the strand's length (0 at a closed tip); Catmull-Rom through the keys.
    Cycles keeps the keys in the emitter's space (`matrix`): each strand's length, and so
    its taper, is measured there, and its radius goes to world space as
    `strand_radius_scale` says (a scaled emitter scales its hair's thickness)."""
    out = []
    matrix = np.eye(4) if matrix is None else np.asarray(matrix, dtype=np.float64)
    inverse = np.linalg.inv(matrix)
    for system in path_hair_systems(obj):
        settings = system.settings
        steps = 2 ** int(settings.render_step) + 1
        if settings.kink == "SPIRAL":
            steps += int(settings.kink_extra_steps)
        parents, children = len(system.particles), len(system.child_particles)
        first = parents if settings.child_type != "NONE" and children else 0
        indices = range(first, parents + (children if first else 0))
        if not len(indices):
            continue
        points = np.array([[system.co_hair(object=obj, particle_no=index, step=step) for step in range(steps)]
                           for index in indices], dtype=np.float64)  # (curves, steps, 3)
        local = points @ inverse[:3, :3].T + inverse[:3, 3]
        lengths = np.concatenate([np.zeros((len(points), 1)),
                                  np.cumsum(np.linalg.norm(np.diff(local, axis=1), axis=2), axis=1)], axis=1)
        time = np.divide(lengths, lengths[:, -1:], out=np.zeros_like(lengths), where=lengths[:, -1:] > 0.0)
        width = 0.5 * float(settings.radius_scale)
        radii = _shape_radius(float(settings.shape), width * float(settings.root_radius),
                              width * float(settings.tip_radius), time)
        radii = radii * strand_radius_scale(matrix, local.reshape(-1, 3),
                                            np.arange(len(points) + 1) * steps).reshape(radii.shape)
        if settings.use_close_tip:
            radii[:, -1] = 0.0
        offsets = np.arange(len(points) + 1) * steps
        out.append(Strands(points.reshape(-1, 3), radii.reshape(-1), offsets, np.full(len(points), shape.linear),
                           np.full(len(points), shape.flat)))
    return out


# Blender's curve types (the `curve_type` attribute; absent: all Catmull-Rom, hair's own).
# Cycles reads the control points of every type (Bezier and NURBS too) as those of a
# Catmull-Rom spline, or of straight pieces.
CURVE_CATMULL_ROM, CURVE_POLY = 0, 1


def _first_curve_type(data: Any, curves: int) -> int:
    """The type of an object's first curve, which Cycles takes for all of them."""
    attribute = data.attributes.get("curve_type")
    if attribute is None or attribute.domain != "CURVE" or not curves:
        return CURVE_CATMULL_ROM
    types = np.empty(curves, dtype=np.int32)
    attribute.data.foreach_get("value", types)
    return int(types[0])
