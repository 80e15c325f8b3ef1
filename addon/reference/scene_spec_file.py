"""A `SceneSpec` as a plain .npz (no pickles): how a test or a caller hands any scene to the
EEVEE child process (`python -m addon.reference.eevee --scene-spec FILE`)."""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from ..core import interrupt
from ..core.alpha import AlphaMap
from ..core.errors import InputError
from ..core.light_shape import shape_from_dict
from ..core.scene import CameraSpec, LightSpec, MeshSpec, SceneSpec

SPEC_FORMAT = 1


def save_scene_spec(spec: SceneSpec, path: str | os.PathLike) -> Path:
    """Write a SceneSpec as a plain .npz (no pickles)."""
    path = Path(path)
    arrays: dict[str, np.ndarray] = {}
    for i, mesh in enumerate(spec.meshes):
        arrays[f"mesh{i}_vertices"] = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
        arrays[f"mesh{i}_triangles"] = np.asarray(mesh.triangles, dtype=np.int64).reshape(-1, 3)
        arrays[f"mesh{i}_matrix"] = np.asarray(mesh.matrix_world, dtype=np.float64).reshape(4, 4)
        if mesh.alpha is not None and mesh.uvs is not None:
            arrays[f"mesh{i}_uvs"] = np.asarray(mesh.uvs, dtype=np.float64)
            arrays[f"mesh{i}_alpha_image"] = mesh.alpha.image
            if mesh.alpha.transfer is not None:
                arrays[f"mesh{i}_alpha_transfer"] = mesh.alpha.transfer
    arrays["light_matrix"] = np.asarray(spec.light.matrix_world, dtype=np.float64).reshape(4, 4)
    arrays["camera_matrix"] = np.asarray(spec.camera.matrix_world, dtype=np.float64).reshape(4, 4)
    header = {
        "format": SPEC_FORMAT,
        "name": spec.name,
        "description": spec.description,
        "stresses": spec.stresses,
        "mesh_names": [mesh.name for mesh in spec.meshes],
        "alpha_maps": {str(i): {"name": m.alpha.name, "interpolation": m.alpha.interpolation,
                                "extension": m.alpha.extension}
                       for i, m in enumerate(spec.meshes) if m.alpha is not None},
        "light": {"emission": spec.light.emission, "energy": float(spec.light.energy),
                  "spot_size": float(spec.light.spot_size), "spot_blend": float(spec.light.spot_blend),
                  "shape": spec.light.shape.as_dict()},
        "camera": {"fov_deg": float(spec.camera.fov_deg), "resolution": [int(v) for v in spec.camera.resolution],
                   "clip_start": float(spec.camera.clip_start), "clip_end": float(spec.camera.clip_end),
                   # None for the centred camera; else its window (shift, pixel aspect, ortho).
                   "window": None if spec.camera.window is None else list(spec.camera.window),
                   "ortho": bool(spec.camera.ortho)},
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    # Not cut by a signal: numpy's zip writer, cut, leaves a ZipFile that complains at exit.
    with interrupt.deferred(), open(path, "wb") as fh:  # a file object keeps numpy from appending ".npz"
        np.savez_compressed(fh, header=np.array(json.dumps(header)), **arrays)
    return path


def load_scene_spec(path: str | os.PathLike) -> SceneSpec:
    """Read a file written by `save_scene_spec`."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            header = json.loads(str(npz["header"]))
            if header.get("format") != SPEC_FORMAT:
                raise InputError(f"scene spec {path} has format {header.get('format')}, expected {SPEC_FORMAT}")
            meshes = [MeshSpec(name, npz[f"mesh{i}_vertices"], npz[f"mesh{i}_triangles"], npz[f"mesh{i}_matrix"],
                               *_stored_alpha(npz, header, i))
                      for i, name in enumerate(header["mesh_names"])]
            stored = header["light"]  # its cone and shape are absent from files written before them
            light = LightSpec(stored["emission"], npz["light_matrix"], stored["energy"],
                              spot_size=float(stored.get("spot_size", math.pi)),
                              shape=shape_from_dict(stored.get("shape")),
                              spot_blend=float(stored.get("spot_blend", 0.0)))
            cam = header["camera"]
            window = cam.get("window")  # absent in files written before windows existed
            camera = CameraSpec(npz["camera_matrix"], cam["fov_deg"], tuple(cam["resolution"]),
                                cam["clip_start"], cam["clip_end"], None if window is None else tuple(window),
                                bool(cam.get("ortho", False)))
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"cannot read scene spec {path}: {exc}") from exc
    return SceneSpec(header["name"], meshes, light, camera, header.get("description", ""),
                     header.get("stresses", ""))


def _stored_alpha(npz, header: dict, index: int) -> tuple[AlphaMap | None, np.ndarray | None]:
    """A stored mesh's see-through material and UVs, (None, None) when it is opaque."""
    described = header.get("alpha_maps", {}).get(str(index))
    if described is None:
        return None, None
    transfer = npz[f"mesh{index}_alpha_transfer"] if f"mesh{index}_alpha_transfer" in npz.files else None
    amap = AlphaMap(described["name"], npz[f"mesh{index}_alpha_image"], described["interpolation"],
                    described["extension"], transfer)
    return amap, npz[f"mesh{index}_uvs"]
