"""Volumes on the GPU (core/media.py): for homogeneous media (lib/media.glsl)
the frame's fixed-point units and the extinction at the light, the exact pass's optical
depths per view sample and the maps' haze per texel; and the density grids (GridStore,
lib/grids.glsl) that the shadow test marches.

A frame with media draws each medium's part with the medium variant of the footprint pass
(shaders.medium_of): the exact pass adds every listed sample's signed crossings to its
three words of `ow_media` (one a channel), the maps add each texel ray's crossings to the
texel's haze, which the shadow test's haze variant reads. Both sums are integers in the
frame's units (`MediaFrame.scale`), and both leave the media around the light to the
reader: sigma_light times the sample's distance.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core import media as core_media
from ...core.light_shape import stratified_points
from .alpha import AtlasWords
from ..shaders import GRID_LIGHT_POINTS, GRID_MAX, GRID_SAMPLERS, HAZE_IMAGES, LIGHT_KINDS, MEDIA_POINTS

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MediaFrame:
    """One frame's media: units per optical depth in the GPU's sums (0: no media), the
    extinction at the light per metre, (3,), and for a sun's map what puts every point's
    place along the axis past 0 (the haze's nearest and farthest words order as positive
    floats; footprint_medium.frag)."""

    scale: float
    light: np.ndarray
    offset: float = 0.0
    # The light points a sample of the exact pass keeps optical depths for: 1 for a hard
    # light, a stratified share of a sized light's (MEDIA_POINTS at most), by their index in
    # the exact pass's pattern (soft.py's `share_points`).
    points: int = 1
    indices: tuple[int, ...] = (0,)
    across: int = 1  # points a row of blocks in SampleMedia's image

    @property
    def on(self) -> bool:
        return self.scale > 0.0

    def uniforms(self) -> dict[str, Any]:
        """What the readers of the sums take (the shadow test's haze variant, the resolve)."""
        return {"ow_media_light": self.light, "ow_media_scale": self.scale if self.on else 1.0,
                "ow_media_offset": self.offset, **self.share_uniforms()}

    def share_uniforms(self) -> dict[str, Any]:
        """ow_media_points and ow_media_index: the light points followed, by pattern index."""
        index = np.zeros(MEDIA_POINTS)
        index[:len(self.indices)] = self.indices
        return {"ow_media_points": self.points, "ow_media_across": self.across, "ow_media_index": index.reshape(-1, 4)}

    def sigma_uniform(self, medium: core_media.Medium) -> np.ndarray:
        """A medium part's ow_medium_sigma: its extinction in the frame's units a metre."""
        return medium.sigma * self.scale

    def kept(self, words: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """The light kept per sample, from the exact pass's words (SampleMedia's layout)
        and each sample's distance from the light (H, W): lib/media.glsl's
        ow_media_light_kept, averaged over the sample's light points."""
        height, width = np.shape(distance)
        down = words.shape[0] // (3 * height)
        blocks = words.view(np.int32).astype(np.float64).reshape(down, 3, height, self.across, width)
        per_point = blocks.transpose(0, 3, 1, 2, 4).reshape(down * self.across, 3, height, width)[:self.points]
        depth = np.moveaxis(per_point, 1, -1) / (self.scale if self.on else 1.0)  # (points, H, W, 3)
        depth += np.asarray(distance, dtype=np.float64)[None, ..., None] * self.light
        return core_media.visibility(np.maximum(depth, 0.0)).mean(axis=0)


NO_MEDIA = MediaFrame(0.0, np.zeros(3))
# A sized light's exact pass follows MEDIA_POINTS of its points (shaders' constant) through
# media, each keeping three words a view sample (lib/exact_soft_medium.glsl); MEDIA_WORDS
# bounds the words (128 MB), so a large view follows fewer.
MEDIA_WORDS = 1 << 25


def media_points(exact_samples: int, size: tuple[int, int], max_texture: int) -> tuple[int, int]:
    """(the light points a sized light's exact pass follows through media, how many a row
    of blocks in SampleMedia's image) for view samples of `size` (H, W): MEDIA_POINTS, or
    fewer for a light of fewer points, a large view (MEDIA_WORDS) or one whose blocks do
    not fit the device's `max_texture`; a square number (144, 121, ... 1) below the light's
    own count, so that soft.py's `share_points` covers the light evenly."""
    height, width = (max(int(v), 1) for v in size)
    across = max(int(max_texture) // width, 1)
    capacity = across * max(int(max_texture) // (3 * height), 1)
    bound = max(1, min(MEDIA_POINTS, MEDIA_WORDS // (3 * height * width), capacity))
    points = max(1, int(exact_samples)) if int(exact_samples) <= bound else int(math.isqrt(bound)) ** 2
    return points, min(points, across)




class MediaMemo:
    """A scene's MediaFrame for a light, kept while the light, the media parts and their
    matrices are the same (the light's winding numbers are numpy over the media's triangles)."""

    def __init__(self) -> None:
        self._held: tuple[tuple, MediaFrame] | None = None

    def frame(self, scene, light) -> MediaFrame:
        parts = [obj for obj in scene.objects.values() if obj.medium is not None and obj.triangles]
        if not parts:
            return NO_MEDIA
        key = (light.position.tobytes(), light.emission,
               tuple((obj.key, obj.revision, obj.matrix.tobytes()) for obj in parts))
        if self._held is None or self._held[0] != key:
            self._held = (key, media_frame(scene, light, parts))
        return self._held[1]


def media_frame(scene, light, parts: list) -> MediaFrame:
    """The units and the light's extinction of a frame over `parts` (resident media parts):
    the largest optical depth a sample can have, every medium's largest sigma times the
    farthest point of the scene from the light (a sun: across the scene), is
    core_media.FIXED_RANGE units."""
    lo, hi = scene.bounds()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    offset = 0.0
    if light.emission == "sun":
        reach = float(np.linalg.norm(hi - lo))
        offset = reach - float(((corners - light.position) @ light.axis).min())
    else:
        reach = float(np.linalg.norm(corners - light.position, axis=1).max())
    media = tuple(obj.medium for obj in parts)
    scale = core_media.fixed_scale(media, reach)
    sigma = np.zeros(3)
    if light.emission != "sun":  # a sun lies inside nothing
        by_medium: dict[str, list[np.ndarray]] = {}
        held: dict[str, core_media.Medium] = {}
        for obj in parts:
            by_medium.setdefault(obj.medium.digest, []).append(obj.world_triangles())
            held[obj.medium.digest] = obj.medium
        for digest, tris in by_medium.items():
            inside = round(core_media.winding_numbers(light.position, np.concatenate(tris)))
            sigma += max(inside, 0) * held[digest].sigma
    log.debug("media frame: %d parts, reach %.4g, scale %.4g, sigma at the light %s", len(parts), reach, scale, sigma)
    return MediaFrame(scale, sigma, offset)


def read_haze(backend) -> np.ndarray | None:
    """The maps' transmittance past each atlas texel's media, (H, W) float32, row 0 at the
    bottom (1 where its ray meets none): the mean over RGB of exp(-optical depth) of the
    haze's whole sum, what the overlay shows; None when this atlas drew no media."""
    if not backend.haze.live:
        return None
    device = backend.device
    device.barrier()
    held = backend.haze.by_name()
    near = device.read(held["ow_haze_near"], "R32UI")
    depth = np.stack([device.read(held[f"ow_haze_{c}"], "R32UI").view(np.int32) for c in "rgb"], axis=-1)
    kept = core_media.visibility(np.maximum(depth / backend.media.scale, 0.0)) if backend.media.on else 1.0
    return np.where(near != 0, kept, 1.0).astype(np.float32)


class SampleMedia:
    """The exact pass's optical depths: one R32UI image of blocks of the samples' size (W, H),
    `across` light points a row of blocks, three rows of blocks (one a channel) a row of
    points: channel c of point j of the sample at (x, y) at
    (x + (j % across) W, y + (3 (j // across) + c) H) (lib/media.glsl's ow_media_word).
    Cleared at each link_samples of a frame with media (`live` until the next)."""

    def __init__(self) -> None:
        self.image: Any = None
        self.size: tuple[int, int] | None = None
        self.live = False
        # A sized light's shadow test weighed them per light point with the surfaces'
        # weights and marks (shadow_test.frag): the readers and the resolve leave them.
        self.weighed = False

    def ready(self, device, size: tuple[int, int], points: int = 1, across: int = 1) -> Any:
        width, height = size
        across = max(1, min(int(across), int(points)))
        wanted = (width * across, 3 * height * (-(-int(points) // across)))
        if self.image is None or self.size != wanted:
            self.release(device)
            self.size = wanted
            self.image = device.texture(self.size, "R32UI")
        device.clear_image(self.image)
        self.live = True
        self.weighed = False
        return self.image

    @property
    def unweighed(self) -> bool:
        """Whether this frame's sums wait for a reader or the resolve to weigh them in."""
        return self.live and not self.weighed

    def release(self, device) -> None:
        device.free(*((self.image,) if self.image is not None else ()))
        self.image = self.size = None
        self.live = self.weighed = False


def Haze() -> AtlasWords:  # noqa: N802 - the haze's words, named as the backend holds them
    """The maps' haze (HAZE_IMAGES, lib/media.glsl): media crossings per atlas texel, made at
    the first medium draw and cleared once per atlas, as the veil is (passes/alpha.py)."""
    return AtlasWords(HAZE_IMAGES)


def grid_texels(density: np.ndarray, max_width: int) -> tuple[np.ndarray, int]:
    """A density grid (nz, ny, nx) as the 2D texture lib/grids.glsl reads: its z slices
    side by side, `cols` to a row (as many as fit `max_width`), row 0 first; and cols."""
    nz, ny, nx = density.shape
    cols = max(1, min(nz, max_width // max(nx, 1)))
    rows = -(-nz // cols)
    out = np.zeros((rows * ny, cols * nx), dtype=np.float32)
    for k in range(nz):
        r, c = divmod(k, cols)
        out[r * ny:(r + 1) * ny, c * nx:(c + 1) * nx] = density[k]
    return out, cols


def grid_light(light) -> dict[str, Any]:
    """The grids march's light: a sized light's kind (shaders.LIGHT_KINDS) and its
    GRID_LIGHT_POINTS points (core/light_shape.stratified_points, in its frame), and the
    frame; kind 0 for a hard one."""
    points = np.zeros((GRID_LIGHT_POINTS, 4))
    kind = LIGHT_KINDS.get(light.shape.kind, 0) if light.sized else 0
    if kind:
        points[:, :3] = stratified_points(light.shape, GRID_LIGHT_POINTS)
    return {"ow_grid_light_kind": kind, "ow_grid_light_count": GRID_LIGHT_POINTS if kind else 1,
            "ow_grid_light_points": points, "ow_grid_light_frame": light.rotation}


class GridStore:
    """Density grids on the GPU (R32F textures of their slices, grid_texels), by the
    density's digest (a moved grid keeps its texture): uploaded once, freed when their
    scene drops them (ResidentScene.removed_grids) or is released."""

    def __init__(self) -> None:
        self.textures: dict[str, tuple[Any, int]] = {}  # digest -> (texture, slices a row)
        self.dummy: Any = None

    def sync(self, device, grids, max_width: int) -> int:
        """Upload the grids not yet held; returns the bytes uploaded."""
        uploaded = 0
        for grid in grids:
            if grid.density_digest not in self.textures:
                texels, cols = grid_texels(grid.density, max_width)
                rows, width = texels.shape
                self.textures[grid.density_digest] = (device.texture((width, rows), "R32F", texels), cols)
                uploaded += int(texels.nbytes)
        return uploaded

    def free(self, device, digests: set[str]) -> None:
        """Free the grids of these density digests (those not held are passed over)."""
        for digest in [d for d in self.textures if d in digests]:
            device.free(self.textures.pop(digest)[0])

    def bind(self, device, grids, light) -> tuple[dict[str, Any], dict[str, Any]]:
        """The shadow test's grid uniforms and samplers for up to GRID_MAX held grids:
        index-space matrices from light-centred points, sizes, extinctions, and how far
        upstream a sun's march starts."""
        if self.dummy is None:
            self.dummy = device.texture((1, 1), "R32F", np.zeros((1, 1), np.float32))
        grids = list(grids)[:GRID_MAX]
        to_index = np.tile(np.eye(4), (GRID_MAX, 1, 1))
        size = np.ones((GRID_MAX, 4))
        sigma = np.zeros((GRID_MAX, 4))
        samplers = {name: self.dummy for name in GRID_SAMPLERS}
        reach = 0.0
        centre = np.eye(4)
        centre[:3, 3] = light.position  # light-centred -> world
        for g, grid in enumerate(grids):
            texture, cols = self.textures[grid.density_digest]
            to_index[g] = grid.to_index @ centre
            nz, ny, nx = grid.density.shape
            size[g] = (nx, ny, nz, cols)
            sigma[g, :3] = grid.sigma
            samplers[GRID_SAMPLERS[g]] = texture
            lo, hi = grid.world_bounds()
            reach = max(reach, float(np.linalg.norm(hi - lo)) + float(np.linalg.norm(0.5 * (lo + hi) - light.position)))
        uniforms = {"ow_grid_count": len(grids), "ow_grid_to_index": to_index, "ow_grid_size": size,
                    "ow_grid_sigma": sigma, "ow_grid_reach": 2.0 * reach, **grid_light(light)}
        return uniforms, samplers

    def release(self, device) -> None:
        self.free(device, set(self.textures))
        device.free(self.dummy)
        self.dummy = None
