"""See-through surfaces: a material's alpha at a point of its surface.

Cycles lets a shadow ray through a surface of alpha a with weight 1 - a (a Transparent
BSDF mixed in front of the opaque part), so the light a receiver gets through surfaces
a_1, ..., a_n is the product of (1 - a_i): cut-outs (a 0 or 1) block or pass, a curtain
of a = 0.5 halves the light.

An `AlphaMap` is one material's alpha as a function of the surface's UV: one scalar
image channel (an image texture's alpha, or its colour's luminance), sampled with
Cycles' interpolation and extension, then a transfer curve (the math and colour-ramp
nodes between the texture and the material's alpha, baked into a table). A constant
alpha is a 1 x 1 image. Nothing here knows Blender: `readers/material_alpha.py`
reads the node graph into this form, and the GPU's `lib/alpha.glsl` samples it as
`sample` does (its numpy oracle).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError
from .media import Medium

# The interpolations and extensions the rule follows, with the codes the GPU takes
# (lib/alpha.glsl's ow_alpha_mode: interpolation + 2 * extension).
INTERPOLATIONS = ("closest", "linear")
EXTENSIONS = ("repeat", "extend", "clip", "mirror")
# Entries of a baked transfer curve over [0, 1]: a step (a Math "Greater Than", a
# constant colour ramp) lands within 1 / 4095 of its place.
TRANSFER_SIZE = 4096
# Luminance weights of Cycles' colour-to-float conversion (linear Rec. 709, Blender's
# default OCIO configuration).
LUMINANCE = (0.2126729, 0.7151522, 0.0721750)
# Alpha at or above which a surface is opaque and at or below which it lets everything
# through: the same bounds on the GPU (shaders.SHARED_DEFINES).
OPAQUE_ALPHA = 1.0 - 1.0 / 65536.0
CLEAR_ALPHA = 1.0 / 65536.0
# The exact pass's per-sample word (lib/exact_walk.glsl): an opaque crossing sets HIT_OPAQUE; a
# see-through one adds its optical depth -ln(1 - alpha) in units of 1 / OPTICAL_SCALE, so
# the sum over any order of crossings is the product of their (1 - alpha). A crossing adds
# at most OPTICAL_SCALE * ln(1 / (1 - OPAQUE_ALPHA)) (about 2^19.5), so 1,400 of them stay
# below HIT_TWIN; a sum past it is a depth past 16,384, whose light is 0 either way. HIT_TWIN
# is set by the first opaque triangle found to hold the sample in its plane (its own): a
# second one is a face laid over it, which shadows it as Cycles' shadow ray does (it
# skips only the primitive it leaves from), and sets HIT_OPAQUE.
HIT_OPAQUE = 1 << 31
HIT_TWIN = 1 << 30
# A face holds the sample in its plane within this share of the sample's distance from the
# light: float32's rounding of a point on two copies of one face (about 1e-7), well under
# the gap to a neighbouring face's plane (a rug's 1 cm rim 0.2 mm from its edge's samples).
TWIN_SHARE = 1e-6
# ... and the sample's own normal is parallel to the face's within this cosine: a neighbour
# that meets the sample's face at an edge (a fold) is not a copy laid over it.
TWIN_COS = 1.0 - 1e-4
OPTICAL_SCALE = 65536.0


@dataclass(frozen=True, eq=False)
class AlphaMap:
    """One material's alpha over its UV square.

    `image` is (H, W) float32 with row 0 at v = 0 (Blender's pixel order), texel centres
    at ((i + 0.5) / W, (j + 0.5) / H). `transfer` maps the sampled value, clamped to
    [0, 1], to alpha through linear interpolation of its entries (None: the value itself).
    """

    name: str
    image: np.ndarray
    interpolation: str = "linear"
    extension: str = "repeat"
    transfer: np.ndarray | None = None
    digest: str = field(init=False, default="")

    def __post_init__(self) -> None:
        image = np.ascontiguousarray(np.asarray(self.image, dtype=np.float32))
        if image.ndim != 2 or image.size == 0:
            raise InputError(f"alpha of {self.name!r}: the image must be a non-empty 2D array, got {image.shape}")
        if not np.all(np.isfinite(image)):
            raise InputError(f"alpha of {self.name!r}: the image holds NaN or infinite values")
        if self.interpolation not in INTERPOLATIONS:
            raise InputError(f"alpha of {self.name!r}: interpolation {self.interpolation!r} is not one of "
                             f"{', '.join(INTERPOLATIONS)}")
        if self.extension not in EXTENSIONS:
            raise InputError(f"alpha of {self.name!r}: extension {self.extension!r} is not one of "
                             f"{', '.join(EXTENSIONS)}")
        transfer = self.transfer
        if transfer is not None:
            transfer = np.ascontiguousarray(np.clip(np.asarray(transfer, dtype=np.float32), 0.0, 1.0))
            if transfer.ndim != 1 or len(transfer) < 2 or not np.all(np.isfinite(transfer)):
                raise InputError(f"alpha of {self.name!r}: the transfer must be 1D with at least 2 finite entries")
        object.__setattr__(self, "image", image)
        object.__setattr__(self, "transfer", transfer)
        object.__setattr__(self, "digest", self._digest())

    @classmethod
    def constant(cls, name: str, alpha: float) -> "AlphaMap":
        """A material whose alpha is the same everywhere (a pane, a curtain)."""
        return cls(name, np.full((1, 1), float(np.clip(alpha, 0.0, 1.0)), dtype=np.float32), "closest", "extend")

    def _digest(self) -> str:
        """What the GPU upload is keyed on: equal maps share one texture."""
        h = hashlib.sha1()
        h.update(f"{self.image.shape}|{self.interpolation}|{self.extension}|".encode())
        h.update(self.image.tobytes())
        if self.transfer is not None:
            h.update(self.transfer.tobytes())
        return h.hexdigest()[:16]

    @property
    def mode(self) -> int:
        """The GPU's code for interpolation and extension."""
        return INTERPOLATIONS.index(self.interpolation) + 2 * EXTENSIONS.index(self.extension)

    def transfer_table(self) -> np.ndarray:
        """The transfer the GPU samples: the identity as two entries when there is none."""
        return np.array([0.0, 1.0], dtype=np.float32) if self.transfer is None else self.transfer

    def values(self) -> np.ndarray:
        """Every alpha the map can give at a texel centre (the image through the transfer)."""
        return apply_transfer(self.transfer_table(), self.image.ravel())

    @property
    def opaque(self) -> bool:
        """True when every texel is opaque: such a material draws as plain geometry."""
        return bool(np.all(self.values() >= OPAQUE_ALPHA)) and self.extension != "clip"

    def sample(self, uv: np.ndarray) -> np.ndarray:
        """Alpha at each (u, v) of `uv` (..., 2): Cycles' texture lookup, then the transfer."""
        uv = np.asarray(uv, dtype=np.float64)
        value = _lookup(self.image, uv[..., 0], uv[..., 1], self.interpolation, self.extension)
        return apply_transfer(self.transfer_table(), value)


def apply_transfer(table: np.ndarray, value: np.ndarray) -> np.ndarray:
    """The transfer at `value` clamped to [0, 1], linearly between its entries."""
    table = np.asarray(table, dtype=np.float64)
    x = np.clip(np.asarray(value, dtype=np.float64), 0.0, 1.0) * (len(table) - 1)
    i = np.minimum(np.floor(x).astype(np.int64), len(table) - 2)
    f = x - i
    return (1.0 - f) * table[i] + f * table[i + 1]


def _wrap(index: np.ndarray, size: int, extension: str) -> tuple[np.ndarray, np.ndarray]:
    """Texel indices inside [0, size) for an extension, and whether each texel exists."""
    if extension == "repeat":
        return np.mod(index, size), np.ones(index.shape, dtype=bool)
    if extension == "mirror":
        m = np.mod(index, 2 * size)
        return np.where(m < size, m, 2 * size - 1 - m), np.ones(index.shape, dtype=bool)
    valid = (index >= 0) & (index < size)
    if extension == "clip":
        return np.clip(index, 0, size - 1), valid
    return np.clip(index, 0, size - 1), np.ones(index.shape, dtype=bool)  # extend


def _texel(image: np.ndarray, i: np.ndarray, j: np.ndarray, extension: str) -> np.ndarray:
    height, width = image.shape
    col, col_ok = _wrap(i, width, extension)
    row, row_ok = _wrap(j, height, extension)
    return np.where(col_ok & row_ok, image[row, col].astype(np.float64), 0.0)


def _lookup(image: np.ndarray, u: np.ndarray, v: np.ndarray, interpolation: str, extension: str) -> np.ndarray:
    """Cycles' image lookup: closest takes the texel under (u, v); linear blends the four
    texels around it, centres at half-texel offsets. Clip is 0 outside the image."""
    height, width = image.shape
    x = np.asarray(u, dtype=np.float64) * width
    y = np.asarray(v, dtype=np.float64) * height
    if interpolation == "closest":
        return _texel(image, np.floor(x).astype(np.int64), np.floor(y).astype(np.int64), extension)
    x -= 0.5
    y -= 0.5
    i, j = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = x - i, y - j
    return ((1 - fy) * ((1 - fx) * _texel(image, i, j, extension) + fx * _texel(image, i + 1, j, extension))
            + fy * ((1 - fx) * _texel(image, i, j + 1, extension) + fx * _texel(image, i + 1, j + 1, extension)))


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Cycles' colour-to-float conversion of linear RGB (..., 3)."""
    return np.asarray(rgb, dtype=np.float64)[..., :3] @ np.asarray(LUMINANCE)


def srgb_to_linear(value: np.ndarray) -> np.ndarray:
    """The sRGB transfer function's inverse (an 8-bit sRGB image's colour, as Cycles reads it)."""
    c = np.asarray(value, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


@dataclass(frozen=True)
class Surface:
    """What a set of triangles carries beyond its shape: per-corner UVs and, per triangle,
    the index of its material's alpha in `maps` (-1: opaque), and of the homogeneous medium
    it bounds in `media` (core/media.py; -1: none). A medium's triangles are no surface:
    they cast no shadow of their own, the medium between them does."""

    uvs: np.ndarray  # (T, 3, 2) float32
    material: np.ndarray  # (T,) int32
    maps: tuple[AlphaMap, ...] = ()
    medium: np.ndarray | None = None  # (T,) int32; None: all -1
    media: tuple[Medium, ...] = ()

    def __post_init__(self) -> None:
        uvs = np.asarray(self.uvs, dtype=np.float32).reshape(-1, 3, 2)
        material = np.asarray(self.material, dtype=np.int32).reshape(-1)
        if len(uvs) != len(material):
            raise InputError(f"surface: {len(uvs)} triangles of UVs but {len(material)} material indices")
        if len(material) and (material.min() < -1 or material.max() >= len(self.maps)):
            raise InputError(f"surface: a material index lies outside [-1, {len(self.maps)})")
        medium = (np.full(len(material), -1, np.int32) if self.medium is None
                  else np.asarray(self.medium, dtype=np.int32).reshape(-1))
        if len(medium) != len(material):
            raise InputError(f"surface: {len(material)} triangles but {len(medium)} medium indices")
        if len(medium) and (medium.min() < -1 or medium.max() >= len(self.media)):
            raise InputError(f"surface: a medium index lies outside [-1, {len(self.media)})")
        object.__setattr__(self, "uvs", uvs)
        object.__setattr__(self, "material", material)
        object.__setattr__(self, "maps", tuple(self.maps))
        object.__setattr__(self, "medium", medium)
        object.__setattr__(self, "media", tuple(self.media))

    @classmethod
    def opaque(cls, triangles: int) -> "Surface":
        return cls(np.zeros((triangles, 3, 2), np.float32), np.full(triangles, -1, np.int32))

    def __len__(self) -> int:
        return len(self.material)

    @property
    def see_through(self) -> bool:
        """Whether any triangle has a material that is not opaque."""
        return bool(np.any(self.material >= 0))

    @property
    def has_media(self) -> bool:
        """Whether any triangle bounds a medium."""
        return bool(np.any(self.medium >= 0))

    def take(self, index: np.ndarray) -> "Surface":
        """The surface of a selection (or reordering) of the triangles."""
        return Surface(self.uvs[index], self.material[index], self.maps, self.medium[index], self.media)

    def with_media(self, medium: np.ndarray, media: tuple[Medium, ...]) -> "Surface":
        """This surface with the triangles' media set."""
        return Surface(self.uvs, self.material, self.maps, medium, media)

    @staticmethod
    def concatenate(parts: "list[Surface]") -> "Surface":
        """One surface of several, their maps and media merged (equal digests kept once)."""
        if not parts:
            return Surface.opaque(0)
        maps, material = _merged([(p.maps, p.material) for p in parts])
        media, medium = _merged([(p.media, p.medium) for p in parts])
        return Surface(np.concatenate([p.uvs for p in parts]), material, tuple(maps), medium, tuple(media))


def _merged(parts: list[tuple[tuple, np.ndarray]]) -> tuple[list, np.ndarray]:
    """Items with a `digest` and per-triangle indices into them (-1: none), of several
    parts: the items kept once each, and the indices into that one list."""
    items: list = []
    where: dict[str, int] = {}
    indices = []
    for own, index in parts:
        remap = np.full(len(own) + 1, -1, dtype=np.int32)
        for i, item in enumerate(own):
            if item.digest not in where:
                where[item.digest] = len(items)
                items.append(item)
            remap[i] = where[item.digest]
        indices.append(remap[index])  # -1 indexes the last entry: -1
    return items, np.concatenate(indices)


def transmittance(alphas: np.ndarray, axis: int = -1) -> np.ndarray:
    """The light that passes surfaces of the given alphas: the product of (1 - alpha)."""
    return np.prod(1.0 - np.clip(np.asarray(alphas, dtype=np.float64), 0.0, 1.0), axis=axis)


def hits_visibility(hits: np.ndarray) -> np.ndarray:
    """The light a sample gets from the exact pass's word: 0 past an opaque crossing,
    else exp(-optical depth)."""
    words = np.asarray(hits, dtype=np.uint32)
    depth = (words & np.uint32(HIT_TWIN - 1)).astype(np.float64) / OPTICAL_SCALE
    return np.where(words & np.uint32(HIT_OPAQUE), 0.0, np.exp(-depth))
