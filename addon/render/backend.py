"""The interface the pipeline draws through: one `ShadowBackend` over a device adapter.

A backend owns the frame's GPU state: the shadow-map atlas (one R32F texture whose tiles
are the layers, plus a depth buffer), the resident geometry, the view samples and the
targets of the passes. Each pass is written once, in render/passes, over the primitives
of device.py; `ModernGLBackend` and `BlenderGPUBackend` only choose the device. The
pipeline hands it numpy arrays and uniform values keyed by the names in
`shaders.ProgramInterface`, so every device runs the same GLSL.
"""
from __future__ import annotations

import functools
import weakref
from typing import Any

import numpy as np

from . import passes
from .device import FULLSCREEN_CORNERS, Device, Rect, Target, UniformValues
from .passes.alpha import AlphaStore, Veil
from .passes.atlas import Atlas, AtlasLayout
from .passes.exact import ExactLists
from .passes.media import NO_MEDIA, GridStore, Haze, MediaFrame, SampleMedia
from .passes.footprints import FootprintDraw, corner_capacity, corner_indices
from .passes.samples import SampleTargets, pack_warp_table
from .passes.segments import SegmentTree
from .pacing import Pacer
from .passes.warp import WarpBuild

# What the pipeline, the parameterizations, the viewport and the tests import from here.
__all__ = ["FULLSCREEN_CORNERS", "AtlasLayout", "FootprintDraw", "Rect", "ShadowBackend", "UniformValues",
           "corner_capacity", "corner_indices", "pack_warp_table"]


def _on_device(method):
    """Run a backend entry point with its device's context current (re-entrant)."""

    @functools.wraps(method)
    def bound(self, *args, **kwargs):
        with self.device.bound():
            return method(self, *args, **kwargs)

    return bound


class ShadowBackend:
    """What a GPU backend provides to the pipeline, over one `device.Device`."""

    name: str = "abstract"

    def __init__(self, device: Device) -> None:
        self.device = device
        # Bytes of scene geometry uploaded since the backend was made (sync_scene): a frame
        # with nothing changed adds none.
        self.geometry_bytes = 0
        # Textures bound by sampler name (samples, atlas, warp tables, ray table, edges).
        self.textures: dict[str, Any] = {}
        self.atlas: Atlas | None = None
        self.samples = SampleTargets()
        self.vertices: dict[str, tuple[int, Any]] = {}  # object key -> (revision, vertex texture)
        self.alpha = AlphaStore()  # see-through materials' maps, shared by the parts that use them
        self.veil = Veil()  # the maps' veil (lib/veil.glsl)
        self.haze = Haze()  # the maps' media (lib/media.glsl)
        self.sample_media = SampleMedia()  # the exact pass's optical depths per sample
        self.media: MediaFrame = NO_MEDIA  # this frame's media units and extinction at the light
        self.grids = GridStore()  # density grids, by digest (lib/grids.glsl)
        self.exact: ExactLists | None = None  # the irregular z-buffer's lists (passes/exact.py)
        self.segments = SegmentTree()  # a sized light's segments' tree (passes/segments.py)
        self.edge_targets: tuple[Target, ...] = ()  # edge-distance passes' targets
        self.ray_target: Target | None = None  # the ray table's, the atlas's size
        self.no_warp = None  # the one zero texel bound as both warp tables without a warp
        self.warp_tables: dict[str, Any] = {}  # each table's own texture, kept between warped frames
        self.warp_build = WarpBuild()  # the GPU's warp construction (passes/warp.py)
        self.pacer = Pacer()  # long passes in slices a signal can end between (pacing.py)
        self._released = False
        self._unread: list[weakref.ref] = []  # frame results whose visibility is still on the GPU
        with device.bound():
            passes.samples.set_warp_tables(self, None, None)
            # Read only by warped footprint draws, after build_ray_table replaced it.
            self.textures["ow_ray_table"] = device.texture((1, 1), "RG32F", np.zeros(2, np.float32))

    # the resident scene -----------------------------------------------------------
    @_on_device
    def sync_scene(self, scene) -> None:
        """Make the GPU hold `scene`'s objects as they are now (a `resident.ResidentScene`).

        Uploads the vertex texture of each object that is new or whose geometry changed
        (by revision) and frees those of the objects removed from it. A moved object
        keeps its texture: its matrix travels as a uniform. A see-through part's alpha
        image and transfer are uploaded once for every part that shares them (by the
        map's digest) and freed with the last of those parts. Objects of other scenes
        stay resident until `release_scene`.
        """
        for key in scene.removed:
            if key in self.vertices:
                self._drop_part(key)
        scene.removed.clear()
        for key, obj in scene.objects.items():
            held = self.vertices.get(key)
            if held is None or held[0] != obj.revision:
                texels = obj.vertex_texels()
                rows, width = texels.shape[:2]
                self.device.free(held[1] if held else None)
                self.vertices[key] = (obj.revision, self.device.texture((width, rows), "RGBA32F", texels))
                self.geometry_bytes += int(texels.nbytes)
                self.geometry_bytes += self.alpha.hold(self.device, key, obj.alpha)
        if scene.removed_grids:  # densities this scene no longer holds (edited or removed grids)
            live = {grid.density_digest for grid in scene.grids.values()}
            self.grids.free(self.device, scene.removed_grids - live)
            scene.removed_grids.clear()
        if scene.grids:
            self.geometry_bytes += self.grids.sync(self.device, scene.grids.values(), self.max_texture_size())

    def _drop_part(self, key: str) -> None:
        held = self.vertices.pop(key, None)
        if held is not None:
            self.device.free(held[1])
        self.alpha.hold(self.device, key, None)

    @_on_device
    def release_scene(self, scene) -> None:
        """Free the vertex textures (and alpha maps no other part uses) of every object of
        `scene`, and its density grids."""
        for key in list(scene.objects) + list(scene.removed):
            if key in self.vertices:
                self._drop_part(key)
        self.grids.free(self.device, {grid.density_digest for grid in scene.grids.values()} | scene.removed_grids)

    def resident_objects(self) -> int:
        """Objects whose vertex textures this backend holds."""
        return len(self.vertices)

    def resident_alpha_maps(self) -> int:
        """Alpha maps (image and transfer) this backend holds."""
        return len(self.alpha.textures)

    def _resident_revisions(self) -> dict[str, int]:
        return {key: revision for key, (revision, _) in self.vertices.items()}

    def alpha_textures(self, key: str) -> dict[str, object]:
        """The alpha map a see-through part's programs sample (ALPHA_SAMPLERS); empty when opaque."""
        return self.alpha.textures_of(key)

    # the passes (render/passes) ---------------------------------------------------
    def renderer(self) -> str:
        """Human-readable renderer string (GL_RENDERER and version)."""
        return self.device.renderer()

    def max_texture_size(self) -> int:
        """Largest 2D texture side the GPU accepts."""
        return self.device.max_texture_size()

    begin_atlas = _on_device(passes.atlas.begin_atlas)
    draw_layer = _on_device(passes.atlas.draw_layer)
    read_atlas = _on_device(passes.atlas.read_atlas)
    build_ray_table = _on_device(passes.footprints.build_ray_table)
    build_ray_table_steps = passes.footprints.build_ray_table_steps  # stepped, like draw_footprints_steps
    draw_footprints = _on_device(passes.footprints.draw_footprints)
    # Stepped (render/pacing.py): the frame that drives it has the device bound.
    draw_footprints_steps = passes.footprints.draw_footprints_steps
    upload_samples = _on_device(passes.samples.upload_samples)
    set_warp_tables = _on_device(passes.samples.set_warp_tables)
    scatter_counts = _on_device(passes.samples.scatter_counts)
    reduce_samples = _on_device(passes.samples.reduce_samples)
    build_warp_crop = _on_device(passes.warp.build_crop)
    build_warp_family = _on_device(passes.warp.build_family)
    link_samples = _on_device(passes.exact.link_samples)
    hold_lists = _on_device(passes.exact.hold_lists)
    read_links = _on_device(passes.exact.read_links)
    read_hits = _on_device(passes.exact.read_hits)
    read_media = _on_device(passes.exact.read_media)
    exact_work = _on_device(passes.exact.exact_work)
    exact_round = _on_device(passes.exact.exact_round)
    finish_lists = _on_device(passes.exact.finish_lists)
    advance_lists = _on_device(passes.exact.advance_lists)
    mark_segments_steps = passes.segments.mark_steps  # stepped: it yields between turns
    edge_distance = _on_device(passes.edges.edge_distance)
    run_shadow_test = _on_device(passes.shadow_test.run_shadow_test)
    read_shadow_test = _on_device(passes.shadow_test.read_shadow_test)
    resolve_visibility = _on_device(passes.shadow_test.resolve_visibility)

    @_on_device
    def read_positions(self) -> np.ndarray:
        """The uploaded samples' light-centred positions and weights, (H, W, 4), row 0 at the
        bottom (a frame's media around the light weigh each sample's distance)."""
        return self.device.read(self.textures["ow_positions"], "RGBA32F")

    def samples_from_gbuffer(self, textures: dict, light_position: np.ndarray) -> None:
        """Make a Blender G-buffer's textures the view samples (frame.GBufferSamples); only
        the backend on Blender's own GL can read them."""
        from ..core.errors import BackendError

        raise BackendError(f"the {self.name} backend cannot read a Blender G-buffer")

    def finish(self) -> None:
        """Block until the GPU has finished all submitted work (for timing)."""
        self.device.finish(self.atlas.target if self.atlas is not None else None)

    def hold_unread(self, result) -> None:
        """Keep track of a frame result (frame.FrameResult) whose visibility is still on the GPU."""
        self._unread.append(weakref.ref(result))

    def settle(self) -> None:
        """Read every frame result still held and unread: call before work that overwrites
        what they read (the next frame, `release`)."""
        unread, self._unread = self._unread, []
        for ref in unread:
            result = ref()
            if result is not None and result.pending:
                result.resolve()

    @property
    def released(self) -> bool:
        """Whether `release` ran: the backend holds nothing any more."""
        return self._released

    def release(self) -> None:
        """Free every GPU object; the backend is unusable afterwards."""
        if self._released:
            return
        self.settle()
        device = self.device
        with device.bound():
            # Drain the queue first: a release that an interrupt brings in the middle of a
            # frame must not free what the GPU is still drawing with.
            device.finish()
            passes.atlas.free_atlas(self)
            device.free(*self.samples.held(), *self.edge_targets, self.ray_target)
            self.samples = SampleTargets()
            passes.exact.free_lists(self)
            self.segments.release(device)
            device.free(*self.warp_build.held())
            self.warp_build = WarpBuild()
            self.edge_targets, self.ray_target = (), None
            device.free(*(texture for _, texture in self.vertices.values()))
            self.vertices.clear()
            self.alpha.release(device)
            self.veil.release(device)
            self.haze.release(device)
            self.grids.release(device)
            self.sample_media.release(device)
            held = (*self.textures.values(), *self.warp_tables.values(), self.no_warp)
            device.free(*{id(t): t for t in held if t is not None}.values())
            self.textures.clear()
            self.warp_tables.clear()
            self.no_warp = None
        device.release()  # outside the binding: it may end the context itself
        self._released = True

    def __enter__(self) -> "ShadowBackend":
        return self

    def __exit__(self, *exc) -> None:
        self.release()
