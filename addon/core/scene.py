"""Scene description shared by presets, the Cycles reference and the pipeline.

A `SceneSpec` is plain numpy data: meshes in object space with a world matrix, one
light and one camera. Preset modules fill it through a `SceneBuilder`, so the same
builder feeds the Blender scene (reference, UI) and the bpy-free pipeline.

Conventions (Blender's): world is right-handed and Z-up. A camera looks along its
local -Z with +Y up. A light's axis (for hemispherical emission) is its local -Z,
the direction a Blender spot light points.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from . import validate
from .alpha import AlphaMap, Surface
# CameraSpec lives in camera.py; it is re-exported here, where the other scene types are.
from .camera import CameraSpec, blender_camera_window, camera_from_matrices  # noqa: F401
from .errors import InputError
from .light_shape import POINT, Area, LightShape, Sphere, SunDisk

Emission = Literal["omni", "hemi", "spot", "sun"]
# Point-light emissions (a position, every direction or a half space) take the
# omnidirectional methods; a narrower spot cone and the sun take the projective ones.
POINT_EMISSIONS = ("omni", "hemi")
PROJECTIVE_EMISSIONS = ("spot", "sun")
# A spot cone of 179 degrees or more is the hemispherical light (Blender stops at 180).
MAX_SPOT_SIZE = math.radians(179.0)
# spot_size is stored as a float32 in Blender: allow its rounding below the threshold.
SPOT_SIZE_TOLERANCE = 1e-6


def spot_emission(spot_size: float) -> Emission:
    """'hemi' for a spot cone of 179 degrees or more, else 'spot'; the one rule the
    reference capture and the UI share."""
    return "hemi" if float(spot_size) >= MAX_SPOT_SIZE - SPOT_SIZE_TOLERANCE else "spot"


@dataclass
class MeshSpec:
    """One triangle mesh: object-space vertices, triangle indices and a world matrix."""

    name: str
    vertices: np.ndarray  # (n, 3) float64, object space
    triangles: np.ndarray  # (m, 3) int64
    matrix_world: np.ndarray = field(default_factory=lambda: np.eye(4))
    # A see-through material: its alpha over the per-vertex UVs; None: opaque.
    alpha: AlphaMap | None = None
    uvs: np.ndarray | None = None  # (n, 2) float64 per vertex, with `alpha`

    def surface(self) -> Surface:
        """Per-triangle UVs and material (index 0 of its own maps, or -1 when opaque)."""
        if self.alpha is None or self.uvs is None:
            return Surface.opaque(len(self.triangles))
        uvs = np.asarray(self.uvs, dtype=np.float64)[np.asarray(self.triangles, dtype=np.int64)]
        return Surface(uvs, np.zeros(len(self.triangles), np.int32), (self.alpha,))

    def world_triangles(self) -> np.ndarray:
        """Return (m, 3, 3) float64 world-space triangle corners."""
        v = np.asarray(self.vertices, dtype=np.float64)
        homo = np.concatenate([v, np.ones((len(v), 1))], axis=1)
        world = (homo @ np.asarray(self.matrix_world, dtype=np.float64).T)[:, :3]
        return world[np.asarray(self.triangles, dtype=np.int64)]


@dataclass
class LightSpec:
    """One light.

    omni: a POINT; hemi: a 180 degree SPOT along local -Z; spot: a SPOT whose full
    cone angle `spot_size` (radians) is below 180 degrees, with blend 0; sun: a SUN
    (angle 0) whose light travels along local -Z. A sun's position only fixes the
    origin the pipeline centres coordinates on. `shape` is the light's own size
    (core/light_shape.py): a sphere for omni, hemi and spot, a disk for a sun, and an
    area light's outline, which takes the hemispherical emission (it is one-sided).
    """

    emission: Emission
    matrix_world: np.ndarray
    energy: float = 1000.0  # W for point and spot lights, W/m^2 (strength) for the sun
    spot_size: float = math.pi
    shape: LightShape = POINT
    # A spot's blend (Blender's spot_blend): its cone fades over that share of the cone's
    # 1 - cos(half angle). The maps' cone stays hard; a sized spot's light points are weighed
    # by it (render/soft.py's spot_cone, as Cycles attenuates each light sample).
    spot_blend: float = 0.0

    def __post_init__(self) -> None:
        if self.emission not in ("omni", "hemi", "spot", "sun"):
            raise InputError(f"unknown light emission {self.emission!r}; use omni, hemi, spot or sun")
        # A NaN or infinite transform would plan no layer and evaluate no pixel: refuse it here,
        # where every caller (presets, references, the UI) passes.
        self.matrix_world = validate.finite_matrix("the light's transform (matrix_world)", self.matrix_world)
        self.energy = validate.finite_number("the light's energy", self.energy, low=0.0)
        self.spot_size = validate.finite_number("the light's spot size (radians)", self.spot_size)
        self.spot_blend = validate.finite_number("the spot's blend", self.spot_blend, low=0.0)
        if self.emission == "spot" and not (float(self.spot_size) > 0.0 and spot_emission(self.spot_size) == "spot"):
            raise InputError(f"spot cone {math.degrees(self.spot_size):.4g} degrees is outside (0, 179): "
                             "a cone of 179 degrees or more is the hemispherical light")
        fits = {Sphere: ("omni", "hemi", "spot"), SunDisk: ("sun",), Area: ("hemi",)}.get(type(self.shape))
        if fits is not None and self.emission not in fits:
            raise InputError(f"a {self.emission} light cannot have the shape {self.shape.describe()!r}")

    @property
    def sized(self) -> bool:
        """True when the light has a size, so its shadows have penumbrae."""
        return self.shape.sized

    @property
    def position(self) -> np.ndarray:
        return np.asarray(self.matrix_world, dtype=np.float64)[:3, 3].copy()

    @property
    def rotation(self) -> np.ndarray:
        """Orthonormal 3x3 light-to-world rotation (scale removed). Kept for the matrix it
        came from (a frame asks for it several times; the SVD is most of its cost)."""
        m = np.asarray(self.matrix_world, dtype=np.float64)[:3, :3]
        key = m.tobytes()
        cached = self.__dict__.get("_rotation")
        if cached is None or cached[0] != key:
            cached = self.__dict__["_rotation"] = (key, orthonormalize(m))
            cached[1].flags.writeable = False
        return cached[1]

    @property
    def axis(self) -> np.ndarray:
        """World direction of the light's local -Z: the hemisphere or cone axis, or the
        direction a sun's light travels."""
        return -self.rotation[:, 2]

    @property
    def is_point(self) -> bool:
        """True for the lights the omnidirectional methods take (omni, hemi)."""
        return self.emission in POINT_EMISSIONS


@dataclass
class SceneSpec:
    """Everything a preset defines."""

    name: str
    meshes: list[MeshSpec]
    light: LightSpec
    camera: CameraSpec
    description: str = ""
    stresses: str = ""

    def world_triangles(self) -> np.ndarray:
        """All triangles in world space as (T, 3, 3) float64."""
        parts = [m.world_triangles() for m in self.meshes]
        if not parts:
            return np.zeros((0, 3, 3), dtype=np.float64)
        return np.concatenate(parts, axis=0)

    def surface(self) -> Surface:
        """The see-through materials of `world_triangles`, in the same order."""
        return Surface.concatenate([m.surface() for m in self.meshes])


def parse_size(text: str) -> tuple[int, int]:
    """'WxH' camera size, each side in [8, 8192]; InputError names a bad one."""
    try:
        w_text, h_text = text.lower().split("x")
        width, height = int(w_text), int(h_text)
    except ValueError:
        raise InputError(f"bad size {text!r}: expected WxH such as 640x480") from None
    if not (8 <= width <= 8192 and 8 <= height <= 8192):
        raise InputError(f"bad size {text!r}: each side must lie in [8, 8192]")
    return width, height


def orthonormalize(m: np.ndarray) -> np.ndarray:
    """Closest rotation to `m` (polar decomposition through SVD)."""
    u, _, vt = np.linalg.svd(np.asarray(m, dtype=np.float64))
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    return r


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """World matrix of a camera (or light) at `eye` whose local -Z points at `target`."""
    eye = np.asarray(eye, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - eye
    norm = np.linalg.norm(forward)
    if norm == 0:
        raise InputError("look_at: eye and target coincide")
    forward /= norm
    up_v = np.asarray(up, dtype=np.float64)
    if abs(float(np.dot(forward, up_v))) > 0.999:
        up_v = np.array([0.0, 1.0, 0.0])
    right = np.cross(forward, up_v)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, -forward, eye
    return m


def translation(offset) -> np.ndarray:
    """4x4 translation matrix."""
    m = np.eye(4)
    m[:3, 3] = np.asarray(offset, dtype=np.float64)
    return m


def rotation_z(degrees: float) -> np.ndarray:
    """4x4 rotation about world Z."""
    a = math.radians(degrees)
    m = np.eye(4)
    m[0, 0], m[0, 1], m[1, 0], m[1, 1] = math.cos(a), -math.sin(a), math.sin(a), math.cos(a)
    return m


_BOX_FACES = np.array(
    [
        [0, 2, 1], [0, 3, 2],  # bottom (z-)
        [4, 5, 6], [4, 6, 7],  # top (z+)
        [0, 1, 5], [0, 5, 4],  # y-
        [2, 3, 7], [2, 7, 6],  # y+
        [1, 2, 6], [1, 6, 5],  # x+
        [3, 0, 4], [3, 4, 7],  # x-
    ],
    dtype=np.int64,
)


class SceneBuilder:
    """What a preset module's `build(builder)` receives. Deterministic, numpy only."""

    def __init__(self, name: str, resolution: tuple[int, int] = (640, 480)) -> None:
        self.name = name
        self.resolution = resolution
        self._meshes: list[MeshSpec] = []
        self._light: LightSpec | None = None
        self._camera: CameraSpec | None = None

    # geometry -------------------------------------------------------------
    def mesh(self, name: str, vertices, triangles, matrix_world=None, *, uvs=None,
             alpha: AlphaMap | None = None) -> MeshSpec:
        """Add an arbitrary triangle mesh, see-through with an `alpha` over per-vertex `uvs`."""
        verts = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
        tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        if len(tris) and (tris.min() < 0 or tris.max() >= len(verts)):
            raise InputError(f"mesh {name!r}: triangle index out of range")
        if (alpha is None) != (uvs is None):
            raise InputError(f"mesh {name!r}: a see-through material needs both its alpha and the UVs")
        if uvs is not None:
            uvs = np.asarray(uvs, dtype=np.float64).reshape(-1, 2)
            if len(uvs) != len(verts):
                raise InputError(f"mesh {name!r}: {len(uvs)} UVs for {len(verts)} vertices")
        spec = MeshSpec(name, verts, tris, np.eye(4) if matrix_world is None else np.asarray(matrix_world, float),
                        alpha, uvs)
        self._meshes.append(spec)
        return spec

    def box(self, name: str, center, size, rotate_z_deg: float = 0.0, inward: bool = False) -> MeshSpec:
        """Axis-aligned box (optionally turned about Z). `inward` flips normals (a room)."""
        sx, sy, sz = (np.asarray(size, dtype=np.float64) / 2.0)
        corners = np.array(
            [[-sx, -sy, -sz], [sx, -sy, -sz], [sx, sy, -sz], [-sx, sy, -sz],
             [-sx, -sy, sz], [sx, -sy, sz], [sx, sy, sz], [-sx, sy, sz]]
        )
        tris = _BOX_FACES[:, ::-1] if inward else _BOX_FACES
        matrix = translation(center) @ rotation_z(rotate_z_deg)
        return self.mesh(name, corners, tris, matrix)

    def plane(self, name: str, center, size_x: float, size_y: float, subdivisions: int = 1) -> MeshSpec:
        """Horizontal grid facing +Z, split into `subdivisions`^2 quads."""
        n = max(1, int(subdivisions))
        xs = np.linspace(-size_x / 2, size_x / 2, n + 1)
        ys = np.linspace(-size_y / 2, size_y / 2, n + 1)
        gx, gy = np.meshgrid(xs, ys, indexing="xy")
        verts = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
        idx = np.arange((n + 1) * (n + 1)).reshape(n + 1, n + 1)
        a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
        c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
        tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
        return self.mesh(name, verts, tris, translation(center))

    def quad(self, name: str, corners, tiles=(1.0, 1.0), alpha: AlphaMap | None = None) -> MeshSpec:
        """A quad of four world corners (counter-clockwise seen from its front), its UVs
        spanning `tiles` repeats of the square: a card, a fence, a curtain."""
        verts = np.asarray(corners, dtype=np.float64).reshape(4, 3)
        uvs = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) * np.asarray(tiles, dtype=np.float64)
        return self.mesh(name, verts, [[0, 1, 2], [0, 2, 3]], uvs=None if alpha is None else uvs, alpha=alpha)

    @staticmethod
    def alpha_image(name: str, image, interpolation: str = "linear", extension: str = "repeat") -> AlphaMap:
        """A see-through material's alpha image ((H, W), row 0 at v = 0), for `quad` and `mesh`."""
        return AlphaMap(name, image, interpolation, extension)

    @staticmethod
    def constant_alpha(name: str, alpha: float) -> AlphaMap:
        """A see-through material of one alpha (a curtain, a pane)."""
        return AlphaMap.constant(name, alpha)

    # light and camera -----------------------------------------------------
    def point_light(self, location, energy: float = 1000.0, radius: float = 0.0) -> None:
        """Omnidirectional point light, a sphere of `radius` (0: hard)."""
        self._light = LightSpec("omni", translation(location), energy, shape=Sphere(radius) if radius else POINT)

    def hemi_light(self, location, target, energy: float = 1000.0, radius: float = 0.0) -> None:
        """Hemispherical light at `location` whose axis points at `target`."""
        self._light = LightSpec("hemi", look_at(location, target), energy, shape=Sphere(radius) if radius else POINT)

    def area_light(self, location, target, size_x: float, size_y: float, outline: str = "rectangle",
                   energy: float = 1000.0) -> None:
        """A one-sided area light at `location` facing `target` (the hemispherical emission)."""
        self._light = LightSpec("hemi", look_at(location, target), energy, shape=Area(outline, size_x, size_y))

    def spot_light(self, location, target, spot_size_deg: float, energy: float = 1000.0, radius: float = 0.0) -> None:
        """Spot light at `location` aimed at `target`, full cone `spot_size_deg`, blend 0."""
        self._light = LightSpec("spot", look_at(location, target), energy, math.radians(spot_size_deg),
                                shape=Sphere(radius) if radius else POINT)

    def sun_light(self, direction, strength: float = 3.0, origin=(0.0, 0.0, 0.0), angle_deg: float = 0.0) -> None:
        """Sun whose light travels along `direction`, `angle_deg` across (0: hard); `origin`
        only places the lamp."""
        d = np.asarray(direction, dtype=np.float64)
        if not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0.0:
            raise InputError(f"sun direction {tuple(d)} must be a finite non-zero vector")
        origin = np.asarray(origin, dtype=np.float64)
        self._light = LightSpec("sun", look_at(origin, origin + d), strength,
                                shape=SunDisk(math.radians(angle_deg)) if angle_deg else POINT)

    def camera(self, location, target, fov_deg: float = 60.0, clip_end: float = 200.0,
               clip_start: float = 0.05, *, shift: tuple[float, float] = (0.0, 0.0),
               ortho_scale: float | None = None) -> None:
        """Camera looking at `target` (clip range in scene units), AUTO sensor fit.

        Perspective with `fov_deg` across the larger image side, or orthographic with
        `ortho_scale` (scene units) across it; `shift` is Blender's lens shift, in units
        of that side.
        """
        if not 0.0 < clip_start < clip_end:
            raise InputError(f"camera clip range must satisfy 0 < start < end, got {clip_start}, {clip_end}")
        matrix = look_at(location, target)
        if ortho_scale is None and tuple(shift) == (0.0, 0.0):
            # The centred form: the same numbers as before windows existed.
            self._camera = CameraSpec(matrix, fov_deg, self.resolution, clip_start, clip_end)
            return
        if ortho_scale is None and not 0.0 < fov_deg < 180.0:
            raise InputError(f"camera field of view {fov_deg} must lie in (0, 180) degrees")
        # A 36 mm sensor with the lens that gives fov_deg: only their ratio matters.
        lens = 18.0 / math.tan(math.radians(fov_deg) / 2.0) if ortho_scale is None else 50.0
        window = blender_camera_window(self.resolution, ortho=ortho_scale is not None, lens=lens,
                                       ortho_scale=1.0 if ortho_scale is None else float(ortho_scale),
                                       sensor_width=36.0, shift=(float(shift[0]), float(shift[1])))
        self._camera = CameraSpec.from_window(matrix, window, self.resolution, clip_start, clip_end,
                                              ortho=ortho_scale is not None)

    def finish(self, description: str = "", stresses: str = "") -> SceneSpec:
        """Return the scene; a preset must have set a light and a camera."""
        if self._light is None:
            raise InputError(f"preset {self.name!r} defines no light")
        if self._camera is None:
            raise InputError(f"preset {self.name!r} defines no camera")
        return SceneSpec(self.name, list(self._meshes), self._light, self._camera, description, stresses)
