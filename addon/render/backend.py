"""The small interface the pipeline draws through.

A backend owns GPU objects: the shadow-map atlas (one R32F texture whose tiles are
the layers, plus a depth buffer), the compiled programs, and the sample
textures of the shadow test. The pipeline hands it numpy arrays and uniform
values keyed by the names in `shaders.ProgramInterface`, so every backend runs
the same GLSL.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from ..core.errors import BackendError
from .shaders import (
    ALPHA_SAMPLERS,
    EXACT_SOFT_KEY,
    FOOTPRINT_PROGRAM,
    FOOTPRINT_VERTICES,
    SHADOW_TEST_PROGRAM,
    VEIL_IMAGES,
    WORK_BOX,
    WORK_CUT,
    WORK_ENTRIES,
    WORK_FRAGMENTS,
    ProgramInterface,
    alpha_of,
    exact_soft_of,
    exact_variant,
    program_variant,
    soft_of,
    veil_of,
)


@dataclass(frozen=True)
class AtlasLayout:
    """Tiles of `resolution`^2 texels, `columns` x `rows`, tile i at (i % columns, i // columns)."""

    resolution: int
    tiles: int
    columns: int

    @property
    def rows(self) -> int:
        return max(1, -(-self.tiles // self.columns))

    @property
    def size(self) -> tuple[int, int]:
        return self.columns * self.resolution, self.rows * self.resolution

    def origin(self, tile: int) -> tuple[int, int]:
        return (tile % self.columns) * self.resolution, (tile // self.columns) * self.resolution

    def span_viewport(self, tile: int, span: int) -> tuple[int, int, int, int]:
        """Viewport (x, y, w, h) over `span` tiles side by side from `tile`, which must share a row."""
        if span < 1 or tile % self.columns + span > self.columns or tile + span > self.tiles:
            raise ValueError(f"tiles {tile}..{tile + span - 1} do not lie side by side in a "
                             f"{self.columns}-column atlas")
        x, y = self.origin(tile)
        return x, y, self.resolution * span, self.resolution

    def scissor_rect(self, tile: int, box: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
        """Atlas rectangle (x, y, w, h) of a tile-local texel box (x0, y0, x1, y1), clipped to the tile."""
        res = self.resolution
        x0, y0, x1, y1 = (min(max(int(v), 0), res) for v in box)
        x, y = self.origin(tile)
        return x + x0, y + y0, max(x1 - x0, 0), max(y1 - y0, 0)

    @staticmethod
    def for_tiles(resolution: int, tiles: int, max_texture: int) -> "AtlasLayout":
        """Widest layout (at most 3 columns) that fits the GPU's texture size limit."""
        tiles = max(1, tiles)
        for columns in (min(tiles, 3), 2, 1):
            layout = AtlasLayout(resolution, tiles, columns)
            if max(layout.size) <= max_texture:
                return layout
        raise ValueError(f"{tiles} tiles of {resolution}^2 exceed the GPU texture limit {max_texture}")


UniformValues = dict[str, object]
Rect = tuple[int, int, int, int]  # (x, y, width, height) in atlas or target pixels

# The one triangle that covers a target (fullscreen.vert): every screen pass draws it.
FULLSCREEN_CORNERS: tuple[tuple[float, float], ...] = ((-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0))


@dataclass(frozen=True)
class FootprintDraw:
    """One object's triangles [first, first + count) drawn by the footprint pass, with the
    object's own uniforms (ow_object_linear, ow_light_hi, ow_light_lo); as point sprites when
    `points` (each triangle's box is known to fit MAX_POINT_SIZE), else as quads."""

    key: str
    first: int
    count: int
    uniforms: UniformValues
    points: bool = False


class ShadowBackend(ABC):
    """What a GPU backend provides to the pipeline."""

    name: str = "abstract"
    # Bytes of scene geometry uploaded since the backend was made (sync_scene): a frame
    # with nothing changed adds none.
    geometry_bytes: int = 0

    def __init__(self) -> None:
        # See-through materials' textures, shared by the parts that use them (issue 25):
        # digest -> (channel image, transfer table), and part key -> digest.
        self._alpha_textures: dict[str, tuple[object, object]] = {}
        self._alpha_users: dict[str, str] = {}
        self._alpha_counts: dict[str, int] = {}  # digest -> parts using it (thousands of instances)
        # The maps' veil (lib/veil.glsl): R32UI images the atlas's size, made at the first
        # see-through draw and cleared once per atlas (`_veil_live` until the next begin_atlas).
        self._veil_images: tuple[object, ...] | None = None
        self._veil_size: tuple[int, int] | None = None
        self._veil_live = False
        self._exact_work: dict[str, int] = {}
        self._reset_work()

    def sync_scene(self, scene) -> None:
        """Make the GPU hold `scene`'s objects as they are now (a `resident.ResidentScene`).

        Uploads the vertex texture of each object that is new or whose geometry changed
        (by revision) and frees those of the objects removed from it. A moved object
        keeps its texture: its matrix travels as a uniform. A see-through part's alpha
        image and transfer are uploaded once for every part that shares them (by the
        map's digest) and freed with the last of those parts. Objects of other scenes
        stay resident until `release_scene`.
        """
        held = self._resident_revisions()
        for key in scene.removed:
            if key in held:
                self._drop_part(key)
        scene.removed.clear()
        for key, obj in scene.objects.items():
            if held.get(key) != obj.revision:
                texels = obj.vertex_texels()
                self._upload_vertices(key, obj.revision, texels)
                self.geometry_bytes += int(texels.nbytes)
                self._hold_alpha(key, obj.alpha)

    def _hold_alpha(self, key: str, amap) -> None:
        """Record which alpha map a part uses, uploading the map the first time."""
        previous = self._alpha_users.pop(key, None)
        if amap is not None:
            if amap.digest not in self._alpha_textures:
                image, transfer = amap.image, amap.transfer_table()
                self._alpha_textures[amap.digest] = (self._upload_channel(image),
                                                     self._upload_channel(transfer[None, :]))
                self.geometry_bytes += int(image.nbytes + transfer.nbytes)
            self._alpha_users[key] = amap.digest
            self._alpha_counts[amap.digest] = self._alpha_counts.get(amap.digest, 0) + 1
        if previous is not None:
            self._alpha_counts[previous] -= 1
            if not self._alpha_counts[previous]:
                del self._alpha_counts[previous]
                for texture in self._alpha_textures.pop(previous):
                    self._free_channel(texture)

    def _drop_part(self, key: str) -> None:
        self._drop_vertices(key)
        self._hold_alpha(key, None)

    def release_scene(self, scene) -> None:
        """Free the vertex textures (and alpha maps no other part uses) of every object of `scene`."""
        held = self._resident_revisions()
        for key in list(scene.objects) + list(scene.removed):
            if key in held:
                self._drop_part(key)

    def _release_alpha(self) -> None:
        """Free every alpha texture (a backend's release)."""
        for textures in self._alpha_textures.values():
            for texture in textures:
                self._free_channel(texture)
        self._alpha_textures.clear()
        self._alpha_users.clear()
        self._alpha_counts.clear()

    def resident_objects(self) -> int:
        """Objects whose vertex textures this backend holds."""
        return len(self._resident_revisions())

    def resident_alpha_maps(self) -> int:
        """Alpha maps (image and transfer) this backend holds."""
        return len(self._alpha_textures)

    @staticmethod
    def _layer_viewport(layout: AtlasLayout | None, tile: int, span: int = 1, caller: str = "draw_layer") -> Rect:
        """The atlas viewport of `span` tiles from `tile`; a BackendError before begin_atlas
        or for tiles that do not lie side by side."""
        if layout is None:
            raise BackendError(f"{caller} called before begin_atlas")
        try:
            return layout.span_viewport(tile, span)
        except ValueError as exc:
            raise BackendError(str(exc)) from None

    def _footprint_program(self, draw: FootprintDraw, uniforms: UniformValues, exact: bool, points: bool,
                           layout: AtlasLayout) -> tuple[ProgramInterface, dict[str, object], dict[str, object]]:
        """The program one footprint draw runs (the exact pass's variant with `exact`, after
        `link_samples`; the alpha variant for a see-through part), the textures it reads
        from the object (its vertex texture and alpha map) and the images it writes, by
        name: the exact pass's lists and marks, or the atlas's veil. A BackendError for an
        object not resident."""
        if exact and self._links is None:
            raise BackendError("the exact footprint pass needs link_samples first")
        held = self._vertices.get(draw.key)
        if held is None:
            raise BackendError(f"object {draw.key!r} is not resident; call sync_scene first")
        see_through = draw.key in self._alpha_users
        if exact:
            iface = exact_variant(uniforms, points, see_through=see_through)
            images = dict(zip((name for _, name in iface.images), self._links))
        else:
            iface = program_variant(FOOTPRINT_PROGRAM, uniforms, points)
            iface = alpha_of(iface) if see_through else iface
            images = self._veil(layout) if see_through else {}
        return iface, {"ow_vertices": held[1], **self.alpha_textures(draw.key)}, images

    def _ready_veil(self, draws: list[FootprintDraw], exact: bool, layout: AtlasLayout) -> None:
        """Clear the veil before a depth pass with see-through parts binds its target
        (a backend may clear through a framebuffer of its own)."""
        if not exact and any(draw.key in self._alpha_users for draw in draws):
            self._veil(layout)

    def _veil(self, layout: AtlasLayout) -> dict[str, object]:
        """The veil's images by name, made for the atlas's size and cleared at the first
        see-through draw into this atlas."""
        if self._veil_images is None or self._veil_size != layout.size:
            self._release_veil()
            self._veil_images = self._new_veil(layout.size)
            self._veil_size = layout.size
        if not self._veil_live:
            self._clear_veil(self._veil_images)
            self._veil_live = True
        return self._veil_by_name()

    def _veil_by_name(self) -> dict[str, object]:
        return dict(zip((name for _, name in VEIL_IMAGES), self._veil_images))

    def _release_veil(self) -> None:
        """Free the veil's images (a new atlas size, or the backend's release)."""
        for image in self._veil_images or ():
            self._free_veil(image)
        self._veil_images = self._veil_size = None
        self._veil_live = False

    def _shadow_test_program(self, uniforms: UniformValues) -> tuple[ProgramInterface, dict[str, object]]:
        """The shadow test's variant for `uniforms` and the images it reads: the veil's when
        this atlas drew see-through parts, none otherwise (the plain test, unchanged); the
        soft variant when the uniforms carry a sized light's points."""
        iface = program_variant(SHADOW_TEST_PROGRAM, uniforms)
        images = {}
        if self._veil_live:
            iface, images = veil_of(iface), self._veil_by_name()
        if int(uniforms.get("ow_soft_count", 0)) > 0:
            iface = soft_of(iface)  # a sized light (lib/soft.glsl)
        if int(uniforms.get(EXACT_SOFT_KEY, 0)) > 0:
            if self._links is None:
                raise BackendError("the exact soft shadow test needs the exact pass's marks (link_samples)")
            # A sized light's exact pass: the test weighs the light points it left unmarked.
            iface, images = exact_soft_of(iface), {"ow_hits": self._links[2]}
        return iface, images

    def alpha_textures(self, key: str) -> dict[str, object]:
        """The alpha map a see-through part's programs sample (ALPHA_SAMPLERS); empty for
        an opaque part."""
        digest = self._alpha_users.get(key)
        return {} if digest is None else dict(zip(ALPHA_SAMPLERS, self._alpha_textures[digest]))

    @staticmethod
    def _clear_rects(layout: AtlasLayout, boxes: dict[int, tuple[int, int, int, int]] | None) -> list[Rect] | None:
        """What `begin_atlas` clears: None for the whole atlas, else each tile's readable box
        (the whole tile where it has none), empty boxes left out."""
        if not boxes:
            return None
        rects = []
        for tile in range(layout.tiles):
            box = boxes.get(tile)
            rect = layout.scissor_rect(tile, box) if box is not None else layout.span_viewport(tile, 1)
            if rect[2] > 0 and rect[3] > 0:
                rects.append(rect)
        return rects

    @staticmethod
    def _edge_uniforms(edge_pass: int, radius: int, eps: float, resolution: int) -> UniformValues:
        """EDGE_PROGRAM's uniforms for one of its two passes."""
        return {"ow_edge_pass": edge_pass, "ow_edge_radius": int(radius), "ow_edge_eps": float(eps),
                "ow_edge_tile_size": float(resolution)}

    @abstractmethod
    def _resident_revisions(self) -> dict[str, int]:
        """Object key -> revision of the vertex texture this backend holds."""

    @abstractmethod
    def _upload_vertices(self, key: str, revision: int, texels: np.ndarray) -> None:
        """Hold `texels` ((rows, VERTEX_TEXTURE_WIDTH, 4) float32) as the object's vertex texture."""

    @abstractmethod
    def _drop_vertices(self, key: str) -> None:
        """Free the object's vertex texture."""

    @abstractmethod
    def _upload_channel(self, data: np.ndarray) -> object:
        """A one-channel float texture (R32F) of `data` (rows, columns), row 0 first."""

    @abstractmethod
    def _free_channel(self, texture: object) -> None:
        """Free a texture `_upload_channel` made."""

    @abstractmethod
    def _new_veil(self, size: tuple[int, int]) -> tuple[object, ...]:
        """One R32UI texture of `size` (width, height) per veil word (shaders.VEIL_IMAGES)."""

    @abstractmethod
    def _clear_veil(self, images: tuple[object, ...]) -> None:
        """Zero the veil's textures (no crossing)."""

    @abstractmethod
    def _free_veil(self, image: object) -> None:
        """Free one veil texture."""

    @abstractmethod
    def build_ray_table(self, tile: int, uniforms: UniformValues) -> None:
        """Fill one tile of the ray table (RAY_TABLE_PROGRAM, RG32F, the atlas's size), bound
        as `ow_ray_table` for the footprint pass: the projection point of every texel of a
        warped layer. Call after begin_atlas and set_warp_tables."""

    @abstractmethod
    def draw_footprints(self, tile: int, draws: list[FootprintDraw], uniforms: UniformValues,
                        scissor: tuple[int, int, int, int] | None = None, exact: bool = False) -> None:
        """Draw resident objects into one tile with the footprint program (FOOTPRINT_PROGRAM).

        FOOTPRINT_VERTICES vertices per triangle (corner_indices); `uniforms` are the
        layer's, each draw adds its object's. `scissor` is as for `draw_layer`. With `exact`
        the irregular z-buffer's variant (shaders.exact_variant) marks the linked samples
        instead (uniforms ow_exact_tile, ow_exact_eps; after `link_samples`).
        """

    @abstractmethod
    def renderer(self) -> str:
        """Human-readable renderer string (GL_RENDERER and version)."""

    @abstractmethod
    def max_texture_size(self) -> int:
        """Largest 2D texture side the GPU accepts."""

    @abstractmethod
    def begin_atlas(self, layout: AtlasLayout, boxes: dict[int, tuple[int, int, int, int]] | None = None) -> None:
        """Make the atlas exist at this layout and clear it to depth 1 (empty).

        `boxes` maps a tile to the texel box (x0, y0, x1, y1) the shadow test can read
        (plan.layer_scissor); such a tile is cleared only inside its box, the others
        whole. Outside a box the atlas keeps stale values: the shadow test never reads
        there (ow_layer_box), and the pipeline masks it in read-backs.
        """

    @abstractmethod
    def draw_layer(self, tile: int, vertices: np.ndarray, uniforms: UniformValues, span: int = 1,
                   scissor: tuple[int, int, int, int] | None = None) -> None:
        """Draw triangles into one tile (or `span` tiles side by side) with the depth program.

        `scissor` (x0, y0, x1, y1), in texels of the tile, limits the fragments drawn to
        the part of the map the shadow test can read (plan.layer_scissor).

        `vertices` is (n, 7) float32, three rows per triangle: light-centred
        position (3) and plane (4), matching DEPTH_PROGRAM.
        """

    @abstractmethod
    def upload_samples(self, positions: np.ndarray, normals: np.ndarray) -> None:
        """View samples for the scatter and test passes: (H, W, 4) float32, row 0 at the bottom.

        positions: light-centred xyz; w = the sample's importance weight (an integer
        >= 1, 1 unless ViewSamples.importance is given) where the pixel hit geometry,
        0 where it missed.
        """

    def samples_from_gbuffer(self, textures: dict, light_position: np.ndarray) -> None:
        """Make a Blender G-buffer's textures the view samples (frame.GBufferSamples); only
        the backend on Blender's own GL can read them."""
        raise BackendError(f"the {self.name} backend cannot read a Blender G-buffer")

    @abstractmethod
    def set_warp_tables(self, rows: np.ndarray | None, cols: np.ndarray | None) -> None:
        """Warp offset tables, (6 * A, A + 1) float32 each (slot-major), or None for no warp.

        Backends upload them as `pack_warp_table` lays them out (RGBA32F, A x 6A).
        """

    @abstractmethod
    def scatter_counts(self, size: int, tiles: int, uniforms: UniformValues) -> np.ndarray:
        """Count maps of the uploaded samples, all layers in one dispatch (SCATTER_PROGRAM).

        Returns (size, size * tiles) float32, row 0 at the bottom (v = 0); the layer in
        slot s fills the columns of tile `uniforms["ow_slot_tile"][s]`.
        """

    @abstractmethod
    def link_samples(self, size: int, tiles: int, uniforms: UniformValues, hit_words: int = 1) -> None:
        """Link every uploaded sample into the list of the map texel it falls in, through the
        full warp (shaders.link_variant, the scatter's uniforms with ow_count_size = the map
        resolution): the irregular z-buffer's lists, kept on the GPU. A heads strip like
        scatter_counts' (0: empty, else sample index + 1) and one next-link per sample; the
        marks get `hit_words` words a sample (a sized light's bits, soft.hit_words), word w
        of the sample at (x, y) at (x, y + w * H)."""

    def read_hits(self) -> tuple[np.ndarray, dict[str, int]]:
        """The exact pass's marks since the last `link_samples`: (words * H, W) uint32, non-zero
        where a triangle crossed the sample's segment to the light (row 0 at the bottom; a
        sized light's bit k of word k // 32 for its point k);
        and its work as `exact_round` folded it, round by round: `cut`, the walks that
        stopped at their round's bound and went on in the next; `rounds`, the rounds after
        the first; and on a measurement frame (shaders.EXACT_COUNT_KEY) `entries` and
        `fragments` walked, and `moved`, the entries the later rounds walked."""
        if self._links is None:
            raise BackendError("read_hits called before link_samples")
        return self._read_hit_words(), self.exact_work()

    def exact_work(self) -> dict[str, int]:
        """The exact pass's work since the last `link_samples`, as `read_hits` gives it."""
        if self._links is None:
            raise BackendError("exact_work called before link_samples")
        return dict(self._exact_work)

    def exact_round(self) -> int:
        """Fold the exact pass's counters since the last call into the frame's work, zero
        them, and return the walks of that round which stopped short of their list's end."""
        words = self._take_work()
        cut = int(words[WORK_CUT])
        self._exact_work["cut"] += cut
        entries = int(words[WORK_ENTRIES])
        self._exact_work["entries"] += entries
        self._exact_work["fragments"] += int(words[WORK_FRAGMENTS])
        if self._exact_work["rounds"] > 0:  # a later round's counters (advance_lists came first)
            self._exact_work["moved"] += entries
        return cut

    def advance_lists(self, steps: int, layout: AtlasLayout) -> dict[int, tuple[int, int, int, int]]:
        """Move every list's head past `steps` entries (ADVANCE_PROGRAM), after a round of
        the exact pass; returns, per tile, the box (x0, y0, x1, y1) of the texels whose
        lists go on, the next round's scissor (tiles without any left out)."""
        if self._links is None:
            raise BackendError("advance_lists called before link_samples")
        self._dispatch_advance(int(steps), layout.resolution)
        words = self._take_work()
        self._exact_work["rounds"] += 1
        boxes = {}
        for tile in range(layout.tiles):
            nx0, ny0, x1, y1 = (int(w) for w in words[WORK_BOX + 4 * tile:WORK_BOX + 4 * tile + 4])
            if x1 > 0:
                boxes[tile] = (~nx0 & 0xFFFFFFFF, ~ny0 & 0xFFFFFFFF, x1, y1)
        return boxes

    def _advance_images(self) -> dict[str, object]:
        """ADVANCE_PROGRAM's images by name: the lists' heads and links, and the work."""
        heads, links, _, work = self._links
        return {"ow_counts": heads, "ow_next": links, "ow_work": work}

    def _reset_work(self) -> None:
        """A new frame's lists: no work counted yet (link_samples)."""
        self._exact_work = dict.fromkeys(("cut", "entries", "fragments", "moved", "rounds"), 0)

    @abstractmethod
    def _read_hit_words(self) -> np.ndarray:
        """The hits image as (H, W) uint32, row 0 at the bottom."""

    @abstractmethod
    def _take_work(self) -> np.ndarray:
        """The work image as (WORK_TEXELS,) uint32, then zeroed."""

    @abstractmethod
    def _dispatch_advance(self, steps: int, tile_size: int) -> None:
        """Run ADVANCE_PROGRAM over the heads strip (ow_advance_steps, ow_tile_size)."""

    @abstractmethod
    def read_links(self) -> tuple[np.ndarray, np.ndarray]:
        """The last `link_samples` as (heads (size, size * tiles), links (H, W)) uint32, row 0
        at the bottom; sample index i is texel (i % W, i // W) of the sample texture."""

    @abstractmethod
    def reduce_samples(self, uniforms: UniformValues, clear: bool) -> np.ndarray:
        """One pass of the planning statistics over the uploaded samples (SAMPLE_STATS_PROGRAM).

        The reduction image (core.samples.STAT_TEXELS R32UI texels) is zeroed first when
        `clear`; pass 1 adds its histogram beside pass 0's fields. Returns the image as
        (STAT_TEXELS,) uint32.
        """

    @abstractmethod
    def shadow_test(self, uniforms: UniformValues) -> np.ndarray:
        """Run the shadow test on the uploaded samples.

        Returns (H, W, 2) float32, row 0 at the bottom: visibility and flag per sample.
        """

    @abstractmethod
    def edge_distance(self, radius: int, eps: float) -> None:
        """Edge-distance map of the atlas (EDGE_PROGRAM, two passes) bound as `ow_edges` for
        the next shadow test: per texel, the Manhattan distance (in texels, up to radius + 1)
        to the nearest texel of its tile whose depth is at least `eps` nearer."""

    @abstractmethod
    def read_atlas(self) -> np.ndarray:
        """The atlas as (rows*res, columns*res) float32, row 0 at the bottom."""

    @abstractmethod
    def finish(self) -> None:
        """Block until the GPU has finished all submitted work (for timing)."""

    @abstractmethod
    def release(self) -> None:
        """Free every GPU object; the backend is unusable afterwards."""

    def __enter__(self) -> "ShadowBackend":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def corner_indices(triangles: int) -> np.ndarray:
    """The footprint pass's corner buffer for `triangles` triangles: vertex i holds i % 6.

    Backends keep one, grown by doubling, and draw a range of it per object.
    """
    return np.tile(np.arange(FOOTPRINT_VERTICES, dtype=np.float32), max(int(triangles), 1))


def corner_capacity(triangles: int, held: int) -> int:
    """Triangles a corner buffer must hold for a draw of `triangles`: `held` while it is
    enough, else the next power of two (so a growing scene reallocates rarely)."""
    if triangles <= held:
        return held
    return 1 << max(int(triangles) - 1, 1).bit_length()


def pack_warp_table(table: np.ndarray | None) -> np.ndarray:
    """The GPU layout of a (6 * A, A + 1) warp table: (6 * A, A, 4) float32.

    Texel (k, row) holds the four offsets one evaluation needs: nodes k and k + 1 of
    function i = row and of its neighbour i + 1 (the same function at the last one of a
    slot's A). One fetch instead of four: on a software rasteriser the fetches of the
    warp dominate the warped depth pass, which evaluates it twice per texel (see
    lib/warp.glsl). None packs to one zero texel.
    """
    if table is None:
        return np.zeros((1, 1, 4), dtype=np.float32)
    t = np.asarray(table, dtype=np.float32)
    size = t.shape[1] - 1
    if size < 1 or t.shape[0] % size:
        raise BackendError(f"warp table of shape {t.shape} is not (6 * A, A + 1)")
    following = np.arange(t.shape[0]) + 1
    following[size - 1::size] -= 1  # the last function of each slot has no next one: itself
    nxt = t[following]
    return np.ascontiguousarray(np.stack([t[:, :-1], t[:, 1:], nxt[:, :-1], nxt[:, 1:]], axis=-1))
