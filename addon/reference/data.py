"""The Cycles reference as plain numpy arrays, saved as one compressed .npz file.

Conventions (verified in tests/blender/test_reference.py):
- Every image array is indexed [row, column] with row 0 the TOP row of the image,
  as the camera sees it (the EXR data window is read top-down, INCREASING_Y).
- `normal` is Cycles' geometric "True Normal" as the shader sees it: Cycles flips it
  towards the incoming camera ray on backfaces, so it always faces the camera
  (dot(normal, camera_position - position) > 0), whatever the winding.
- `position` and `normal` are zero where `hit` is False.
- Pixels are point samples at the pixel centre (with the default single sample the
  position projects to (col + 0.5, row + 0.5) within 1e-4 px).
- `meta` holds: preset ("custom" for a user scene), scene/light/camera names,
  blender_version, samples, mixed_pixels, capture_version, render_seconds
  {"shadowed", "unshadowed"} and, from the cache, cache_key and key_fields.
- `spot_size` is the full cone angle (radians) of a "spot" light; pi for every other
  emission. Files written before the field existed load with pi (or, for a spot, the
  cone recorded in meta["spot_size_deg"]), so the field needs no format bump.
- The camera (`camera()`, a `core.camera.CameraSpec`): `camera_matrix`, `resolution`,
  `camera_clip` (clip start and end) and, for a camera that `camera_fov_deg` alone
  cannot describe (lens shift, non-square pixels, orthographic), `camera_window` and
  `camera_ortho`. A centred perspective camera with square pixels stores no window,
  exactly as before these fields existed; older files load without them (a centred
  camera, clip 0.05 to 200 as then), so they need no format bump either.
- `surface` (core/alpha.Surface): the see-through materials of `triangles` as the
  capture read them (readers/material_alpha.py), stored as `uvs`, `material` and one
  `alpha{i}_image` / `alpha{i}_transfer` pair a map (their names, interpolations and
  extensions in meta["alpha_maps"]); a file without them is all opaque. The homogeneous
  media (core/media.py) the triangles bound are `medium` (T,) int32 (-1: none) and
  `media_sigma` (M, 3) float64, their names in meta["media"]; a file without
  them has no media (its `uvs` and `material` are then written for media alone too).
- The light's size as rendered (`light_shape()`, core/light_shape.py) is meta["light_shape"],
  as the file has it meta["light_shape_file"]; files without them are hard. A sized light's
  reference also stores `visibility_noise` (H, W): half the difference of the two halves'
  visibility (capture.py), the reference's own noise per pixel; a hard one has none.
- `spheres` and `strands` (core/blockers.py): the point clouds and hair curves that block
  the light, world space, as `sphere_centres`/`sphere_radii` and `strand_points`/
  `strand_radii`/`strand_offsets`/`strand_linear`; a file without them has none.
- `grids` (core/media.GridMedium): the heterogeneous media of the Volume geometry that
  blocks the light (readers/volume_grids.py), as `grid{i}_density` (nz, ny, nx) float32,
  `grid{i}_to_index` (4, 4) and `grid{i}_sigma` (3,), their names in meta["grids"]; a
  file without them has none.
"""
from __future__ import annotations

import json
import logging
import math
import os
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core import interrupt
from ..core.alpha import AlphaMap, Surface
from ..core.blockers import Spheres, Strands
from ..core.camera import CameraSpec, Window
from ..core.errors import ReferenceCaptureError
from ..core.light_shape import LightShape, shape_from_dict
from ..core.media import GridMedium, Medium
from ..core.scene import LightSpec

log = logging.getLogger(__name__)

# Bumped when the file layout changes; older files are then treated as stale.
FORMAT_VERSION = 1

# What numpy raises for a damaged .npz: a bad or truncated zip (BadZipFile, EOFError),
# damaged deflate data (zlib.error), a truncated member or bad JSON (ValueError).
_UNREADABLE = (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile, zlib.error)


@dataclass
class ReferenceData:
    """Per-pixel ground truth of one camera view plus the scene's world triangles."""

    position: np.ndarray  # (H, W, 3) float32, world space
    normal: np.ndarray  # (H, W, 3) float32, unit geometric normal facing the camera
    hit: np.ndarray  # (H, W) bool, the camera ray hit geometry
    shadowed: np.ndarray  # (H, W) float32, Diffuse Direct (mean of RGB) with shadows
    unshadowed: np.ndarray  # (H, W) float32, the same with shadow casting disabled
    triangles: np.ndarray  # (T, 3, 3) float32, world space: what blocks the light (shadow_rule.py)
    light_matrix: np.ndarray  # (4, 4) float64, light to world, rotation orthonormal (scale dropped)
    emission: str  # "omni" | "hemi" | "spot" | "sun"
    camera_matrix: np.ndarray  # (4, 4) float64, camera to world (looks along local -Z), no scale
    camera_fov_deg: float  # field of view along the larger image side; with a camera_window only a description
    resolution: tuple[int, int]  # (W, H)
    meta: dict[str, Any] = field(default_factory=dict)
    # Full cone angle in radians; only a "spot" narrows the domain below pi. Kept last so
    # positional construction of the older fields is unchanged.
    spot_size: float = math.pi
    # The camera's image window (CameraSpec.window) when fov alone cannot describe it.
    camera_window: Window | None = None
    camera_ortho: bool = False
    camera_clip: tuple[float, float] | None = None  # (start, end); None: CameraSpec's defaults
    surface: Surface | None = None  # see-through materials and media of `triangles`; None: opaque, none
    visibility_noise: np.ndarray | None = None  # (H, W) float32, a sized light's or a medium's; None: noise-free
    spheres: Spheres | None = None  # point clouds that block the light; None: none
    strands: Strands | None = None  # hair curves that block the light; None: none
    grids: tuple[GridMedium, ...] = ()  # Volume geometry's density grids that block the light

    def __post_init__(self) -> None:
        self.position = np.asarray(self.position, dtype=np.float32)
        self.normal = np.asarray(self.normal, dtype=np.float32)
        self.hit = np.asarray(self.hit, dtype=bool)
        self.shadowed = np.asarray(self.shadowed, dtype=np.float32)
        self.unshadowed = np.asarray(self.unshadowed, dtype=np.float32)
        self.triangles = np.asarray(self.triangles, dtype=np.float32).reshape(-1, 3, 3)
        self.light_matrix = np.asarray(self.light_matrix, dtype=np.float64)
        self.camera_matrix = np.asarray(self.camera_matrix, dtype=np.float64)
        self.camera_fov_deg = float(self.camera_fov_deg)
        self.resolution = (int(self.resolution[0]), int(self.resolution[1]))
        self.emission = str(self.emission)
        self.spot_size = float(self.spot_size)
        if not (0.0 < self.spot_size <= math.pi):
            raise ReferenceCaptureError(f"reference spot_size {self.spot_size!r} rad is outside (0, pi]")
        if self.camera_window is not None:
            self.camera_window = tuple(float(v) for v in self.camera_window)  # type: ignore[assignment]
        self.camera_ortho = bool(self.camera_ortho)
        self.grids = tuple(self.grids)
        if self.camera_clip is not None:
            self.camera_clip = (float(self.camera_clip[0]), float(self.camera_clip[1]))
        if self.camera_ortho and self.camera_window is None:
            raise ReferenceCaptureError("an orthographic reference camera needs its camera_window")
        if self.visibility_noise is not None:
            self.visibility_noise = np.asarray(self.visibility_noise, dtype=np.float32)
        if self.surface is not None and len(self.surface) != len(self.triangles):
            raise ReferenceCaptureError(f"reference surface has {len(self.surface)} triangles, "
                                        f"the triangles {len(self.triangles)}")
        self._check_shapes()

    def _check_shapes(self) -> None:
        width, height = self.resolution
        expected = {
            "position": (height, width, 3),
            "normal": (height, width, 3),
            "hit": (height, width),
            "shadowed": (height, width),
            "unshadowed": (height, width),
        }
        if self.visibility_noise is not None:
            expected["visibility_noise"] = (height, width)
        for name, shape in expected.items():
            actual = getattr(self, name).shape
            if actual != shape:
                raise ReferenceCaptureError(
                    f"reference field {name!r} has shape {actual}, expected {shape} for resolution {width}x{height}"
                )
        for name in ("light_matrix", "camera_matrix"):
            if getattr(self, name).shape != (4, 4):
                raise ReferenceCaptureError(f"reference field {name!r} must be 4x4")

    # derived ---------------------------------------------------------------
    @property
    def light_position(self) -> np.ndarray:
        """World position of the light."""
        return self.light_matrix[:3, 3].copy()

    @property
    def camera_position(self) -> np.ndarray:
        """World position of the camera."""
        return self.camera_matrix[:3, 3].copy()

    def camera(self) -> CameraSpec:
        """The camera the reference was rendered from: the one function that turns the
        stored fields into a CameraSpec (compare and the headless preview use it)."""
        clip = () if self.camera_clip is None else self.camera_clip
        if self.camera_window is None:
            return CameraSpec(self.camera_matrix, self.camera_fov_deg, self.resolution, *clip)
        return CameraSpec.from_window(self.camera_matrix, self.camera_window, self.resolution, *clip,
                                      ortho=self.camera_ortho)

    def visibility(self, eps: float = 1e-6) -> np.ndarray:
        """Reference visibility (H, W) bool: lit where shadowed/unshadowed >= 0.5.

        Pixels with unshadowed <= eps (missed, facing away, outside the emission
        domain) are False; use `lit_domain(eps)` to tell them apart from shadow.
        """
        lit = self.lit_domain(eps)
        ratio = np.zeros_like(self.unshadowed)
        np.divide(self.shadowed, self.unshadowed, out=ratio, where=lit)
        return lit & (ratio >= 0.5)

    def light_shape(self) -> LightShape:
        """The light's size as the reference rendered it (a point for older files)."""
        return shape_from_dict(self.meta.get("light_shape"))

    def light_spec(self) -> LightSpec:
        """The light as the reference rendered it: emission, matrix, cone and its blend, size."""
        return LightSpec(self.emission, self.light_matrix, spot_size=self.spot_size,  # type: ignore[arg-type]
                         shape=self.light_shape(), spot_blend=float(self.meta.get("spot_blend", 0.0)))

    def scene_surface(self) -> Surface:
        """The triangles' see-through materials and homogeneous media (`Surface.medium`,
        `Surface.media`); all opaque, without media, for a file without them."""
        return self.surface if self.surface is not None else Surface.opaque(len(self.triangles))

    def lit_domain(self, eps: float = 1e-6) -> np.ndarray:
        """(H, W) bool: hit pixels that receive light when no shadows are cast."""
        return self.hit & (self.unshadowed > eps)

    # persistence -------------------------------------------------------------
    def _camera_arrays(self) -> dict[str, np.ndarray]:
        """The optional camera fields as arrays; a centred camera writes no window."""
        arrays: dict[str, np.ndarray] = {}
        if self.camera_window is not None:
            arrays["camera_window"] = np.array(self.camera_window, dtype=np.float64)
            arrays["camera_ortho"] = np.array(self.camera_ortho)
        if self.camera_clip is not None:
            arrays["camera_clip"] = np.array(self.camera_clip, dtype=np.float64)
        return arrays

    def _surface_arrays(self, meta: dict[str, Any]) -> dict[str, np.ndarray]:
        """The see-through materials and media as arrays (none for an all-opaque scene
        without media); their descriptions go to `meta`."""
        if self.surface is None or not (self.surface.see_through or self.surface.has_media):
            return {}
        arrays = {"uvs": self.surface.uvs, "material": self.surface.material}
        if self.surface.has_media:
            arrays["medium"] = self.surface.medium
            arrays["media_sigma"] = np.array([m.sigma for m in self.surface.media], dtype=np.float64).reshape(-1, 3)
            meta["media"] = [m.name for m in self.surface.media]
        for index, amap in enumerate(self.surface.maps):
            arrays[f"alpha{index}_image"] = amap.image
            if amap.transfer is not None:
                arrays[f"alpha{index}_transfer"] = amap.transfer
        meta["alpha_maps"] = [{"name": m.name, "interpolation": m.interpolation, "extension": m.extension}
                              for m in self.surface.maps]
        return arrays

    def _blocker_arrays(self) -> dict[str, np.ndarray]:
        """The point clouds and hair curves as arrays (none when the scene has none)."""
        arrays = {}
        if self.spheres is not None and len(self.spheres):
            arrays.update(sphere_centres=self.spheres.centres, sphere_radii=self.spheres.radii)
        if self.strands is not None and len(self.strands):
            arrays.update(strand_points=self.strands.points, strand_radii=self.strands.radii,
                          strand_offsets=self.strands.offsets, strand_linear=self.strands.linear,
                          strand_flat=self.strands.flat)
        return arrays

    def _grid_arrays(self, meta: dict[str, Any]) -> dict[str, np.ndarray]:
        """The grid media as arrays (none without them); their names go to `meta`."""
        arrays: dict[str, np.ndarray] = {}
        for index, grid in enumerate(self.grids):
            arrays.update({f"grid{index}_density": grid.density, f"grid{index}_to_index": grid.to_index,
                           f"grid{index}_sigma": grid.sigma})
        if self.grids:
            meta["grids"] = [grid.name for grid in self.grids]
        return arrays

    def save(self, path: str | os.PathLike) -> Path:
        """Write a compressed .npz atomically (a temp file renamed into place)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = dict(self.meta)
        meta["format_version"] = FORMAT_VERSION
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        interrupt.register_temporary(tmp)
        # Not cut by a signal: an interrupt raised inside numpy's zip writer left a half-closed
        # ZipFile whose finaliser printed a traceback at exit (seen on Python 3.11).
        with interrupt.deferred():
            self._write(tmp, path, meta)
        log.debug("saved reference %s", path)
        return path

    def _write(self, tmp: Path, path: Path, meta: dict) -> None:
        try:
            # A file object keeps numpy from appending ".npz" to the temp name.
            with open(tmp, "wb") as fh:
                np.savez_compressed(
                    fh,
                    position=self.position,
                    normal=self.normal,
                    hit=self.hit,
                    shadowed=self.shadowed,
                    unshadowed=self.unshadowed,
                    triangles=self.triangles,
                    light_matrix=self.light_matrix,
                    emission=np.array(self.emission),
                    camera_matrix=self.camera_matrix,
                    camera_fov_deg=np.array(self.camera_fov_deg, dtype=np.float64),
                    resolution=np.array(self.resolution, dtype=np.int64),
                    spot_size=np.array(self.spot_size, dtype=np.float64),
                    **self._camera_arrays(),
                    **self._surface_arrays(meta),
                    **({} if self.visibility_noise is None else {"visibility_noise": self.visibility_noise}),
                    **self._blocker_arrays(),
                    **self._grid_arrays(meta),
                    meta=np.array(json.dumps(meta, sort_keys=True)),
                )
            os.replace(tmp, path)
        finally:
            if tmp.exists():
                tmp.unlink()

    @classmethod
    def load(cls, path: str | os.PathLike) -> "ReferenceData":
        """Read a file written by `save`."""
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as npz:
                meta = json.loads(str(npz["meta"]))
                if meta.get("format_version") != FORMAT_VERSION:
                    raise ReferenceCaptureError(
                        f"reference file {path} has format {meta.get('format_version')}, "
                        f"expected {FORMAT_VERSION}; refresh it"
                    )
                return cls(
                    position=npz["position"],
                    normal=npz["normal"],
                    hit=npz["hit"],
                    shadowed=npz["shadowed"],
                    unshadowed=npz["unshadowed"],
                    triangles=npz["triangles"],
                    light_matrix=npz["light_matrix"],
                    emission=str(npz["emission"]),
                    camera_matrix=npz["camera_matrix"],
                    camera_fov_deg=float(npz["camera_fov_deg"]),
                    resolution=tuple(int(v) for v in npz["resolution"]),
                    meta=meta,
                    spot_size=_stored_spot_size(npz, meta),
                    surface=_stored_surface(npz, meta),
                    visibility_noise=npz["visibility_noise"] if "visibility_noise" in npz.files else None,
                    **_stored_camera(npz),
                    **_stored_blockers(npz),
                    grids=_stored_grids(npz, meta),
                )
        except _UNREADABLE as exc:
            raise ReferenceCaptureError(f"cannot read reference file {path}: {_reason(exc)}") from exc


def _stored_blockers(npz) -> dict[str, Any]:
    """The point clouds and hair curves of a loaded file (older files have none)."""
    fields: dict[str, Any] = {}
    if "sphere_centres" in npz.files:
        fields["spheres"] = Spheres(npz["sphere_centres"], npz["sphere_radii"])
    if "strand_points" in npz.files:
        fields["strands"] = Strands(npz["strand_points"], npz["strand_radii"], npz["strand_offsets"],
                                    npz["strand_linear"] if "strand_linear" in npz.files else None,
                                    npz["strand_flat"] if "strand_flat" in npz.files else None)
    return fields


def _stored_grids(npz, meta: dict[str, Any]) -> tuple[GridMedium, ...]:
    """The grid media of a loaded file (older files have none)."""
    return tuple(GridMedium(name, npz[f"grid{i}_sigma"], npz[f"grid{i}_density"], npz[f"grid{i}_to_index"])
                 for i, name in enumerate(meta.get("grids", ())))


def _stored_camera(npz) -> dict[str, Any]:
    """The optional camera fields of a loaded file (older files have none of them)."""
    fields: dict[str, Any] = {}
    if "camera_window" in npz.files:
        fields["camera_window"] = tuple(float(v) for v in npz["camera_window"])
        fields["camera_ortho"] = bool(npz["camera_ortho"]) if "camera_ortho" in npz.files else False
    if "camera_clip" in npz.files:
        fields["camera_clip"] = tuple(float(v) for v in npz["camera_clip"])
    return fields


def _stored_surface(npz, meta: dict[str, Any]) -> Surface | None:
    """The see-through materials of a loaded file; None when it has none."""
    if "material" not in npz.files:
        return None
    maps = tuple(AlphaMap(d["name"], npz[f"alpha{i}_image"], d["interpolation"], d["extension"],
                          npz[f"alpha{i}_transfer"] if f"alpha{i}_transfer" in npz.files else None)
                 for i, d in enumerate(meta.get("alpha_maps", ())))
    if "medium" not in npz.files:  # written before media, or without any
        return Surface(npz["uvs"], npz["material"], maps)
    media = tuple(Medium(name, sigma) for name, sigma in zip(meta.get("media", ()), npz["media_sigma"]))
    return Surface(npz["uvs"], npz["material"], maps, npz["medium"], media)


def _stored_spot_size(npz, meta: dict[str, Any]) -> float:
    """The spot cone of a loaded file; older files lack the field (still format 1)."""
    if "spot_size" in npz.files:
        return float(npz["spot_size"])
    # A spot captured before the field existed still recorded its cone in meta.
    if str(npz["emission"]) == "spot" and "spot_size_deg" in meta:
        return math.radians(float(meta["spot_size_deg"]))
    return math.pi


def read_meta(path: str | os.PathLike) -> dict[str, Any]:
    """Only the meta dict of a saved reference (cheap: one small zip member)."""
    try:
        with np.load(Path(path), allow_pickle=False) as npz:
            return json.loads(str(npz["meta"]))
    except _UNREADABLE as exc:
        raise ReferenceCaptureError(f"cannot read reference file {path}: {_reason(exc)}") from exc


def _reason(exc: BaseException) -> str:
    """One line for why a file could not be read (some numpy errors say nothing)."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
