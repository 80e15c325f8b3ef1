"""A material's alpha for shadow rays, read from its node tree as Cycles reads it.

From the Cycles material output the reader follows the shader on Surface: a Principled
BSDF's Alpha, a Transparent BSDF (its colour's luminance is what passes), and Mix / Add
Shaders of those and opaque shaders. Its transparency is the sum of the transparent
closures' weights; alpha is 1 minus that. Every scalar on the way is a function of one
source, an Image Texture's Alpha, colour luminance or colour channel (or a constant),
through Math, Invert, Map Range, Clamp, Mix (float, or colour mix), Color Ramp, Separate
Color (RGB) and Reroute nodes, and muted nodes' pass-throughs; the chain is baked into
the AlphaMap's transfer table over the source's [0, 1].

The texture's vector may come from the default UV map, a UV Map node, Texture
Coordinate UV, and Mapping nodes (point, texture, vector) in between, which become an
affine `uv_matrix`. Cubic and Smart interpolation read as linear. Cycles decodes a byte
sRGB image after interpolating: a grey one (a mask) is kept encoded and the decode is
composed into the transfer, so a threshold on its filtered edge falls where Cycles' does
(measured: `exact` 0.168 % -> 0.000 % on a chain-link mask); a coloured one is decoded
per texel before the lookup, which differs between texels only. Colour is premultiplied by alpha where Cycles does (the Alpha
output unused), unpremultiplied where it is used.

What the reader cannot follow (a procedural texture, a node group, an attribute, two
textures, a light-path trick, a UDIM image, ...) gives alpha None and a `note` naming it;
the caller then treats the material as opaque.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.alpha import LUMINANCE, TRANSFER_SIZE, AlphaMap, Surface, luminance, srgb_to_linear
from ..compat import blender as blender_compat

log = logging.getLogger(__name__)

IDENTITY_UV = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
# The source's values the chain is evaluated at: the transfer table's abscissae.
_X = np.linspace(0.0, 1.0, TRANSFER_SIZE)
_INTERPOLATIONS = {"Closest": "closest", "Linear": "linear", "Cubic": "linear", "Smart": "linear"}
_EXTENSIONS = {"REPEAT": "repeat", "EXTEND": "extend", "CLIP": "clip", "MIRROR": "mirror"}
# Shaders without a transparent closure: Cycles stops shadow rays at them (glass and
# refraction included: shadow rays do not refract).
_OPAQUE_SHADERS = {
    "BSDF_DIFFUSE", "BSDF_GLOSSY", "BSDF_ANISOTROPIC", "BSDF_GLASS", "BSDF_REFRACTION", "BSDF_TRANSLUCENT",
    "BSDF_SHEEN", "BSDF_VELVET", "BSDF_TOON", "BSDF_HAIR", "BSDF_HAIR_PRINCIPLED", "BSDF_METALLIC",
    "SUBSURFACE_SCATTERING", "EMISSION", "BACKGROUND", "HOLDOUT", "EEVEE_SPECULAR",
}
UNARY = {"ROUND", "ABSOLUTE", "FLOOR", "CEIL", "FRACT", "SIGN", "SQRT"}
TERNARY = {"MULTIPLY_ADD", "COMPARE"}


def _power(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cycles' safe_powf: 0 for a negative base with a fractional exponent, 0^b = 0 (b != 0)."""
    with np.errstate(all="ignore"):
        odd = np.mod(b, 2.0) == 1.0
        value = np.abs(a) ** b * np.where((a < 0) & odd, -1.0, 1.0)
        value = np.where((a < 0) & (b != np.round(b)), 0.0, np.where(a == 0, 0.0, value))
    return np.where(b == 0, 1.0, value)


def _divide(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.divide(a, b, out=np.zeros(np.broadcast(a, b).shape), where=b != 0)  # Cycles' safe_divide


MATH = {
    "ADD": lambda a, b, c: a + b, "SUBTRACT": lambda a, b, c: a - b, "MULTIPLY": lambda a, b, c: a * b,
    "DIVIDE": lambda a, b, c: _divide(a, b), "POWER": lambda a, b, c: _power(a, b),
    "MINIMUM": lambda a, b, c: np.minimum(a, b), "MAXIMUM": lambda a, b, c: np.maximum(a, b),
    "GREATER_THAN": lambda a, b, c: (a > b) * 1.0, "LESS_THAN": lambda a, b, c: (a < b) * 1.0,
    "ROUND": lambda a, b, c: np.floor(a + 0.5), "ABSOLUTE": lambda a, b, c: np.abs(a),
    "FLOOR": lambda a, b, c: np.floor(a), "CEIL": lambda a, b, c: np.ceil(a),
    "FRACT": lambda a, b, c: a - np.floor(a), "SIGN": lambda a, b, c: np.sign(a),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0.0)), "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "COMPARE": lambda a, b, c: (np.abs(a - b) <= np.maximum(c, 1e-5)) * 1.0,
}


@dataclass(frozen=True, eq=False)
class MaterialAlpha:
    """A material's alpha for shadow rays: None is opaque (or not followed: `note` says why).

    `uv_map` names the UV map the texture reads ("" = the active render one); `uv_matrix`
    (2, 3) maps (u, v, 1) to the texture's coordinates."""

    alpha: AlphaMap | None
    uv_map: str = ""
    uv_matrix: np.ndarray = field(default_factory=IDENTITY_UV.copy)
    note: str | None = None


class _Unfollowed(Exception):
    """Raised inside the reader only; its message becomes the material's note."""


@dataclass(frozen=True, eq=False)
class _Value:
    """A scalar as a function of its source: `values` at the source values _X (all equal
    for a constant, `source` None), `source` an image node's (name, channel)."""

    values: np.ndarray
    source: tuple[str, str] | None = None


def _constant(value: float) -> _Value:
    return _Value(np.full(TRANSFER_SIZE, float(value)))


def _label(node: Any) -> str:
    if node.type == "GROUP":
        return f"node group ({node.node_tree.name if node.node_tree else 'empty'})"
    return node.bl_label.lower()


def _input(node: Any, identifier: str) -> Any:
    return next(s for s in node.inputs if s.identifier == identifier)


def _grey(pixels: np.ndarray) -> bool:
    """Whether an image's colour channels are equal at every texel."""
    return bool(np.array_equal(pixels[..., 0], pixels[..., 1]) and np.array_equal(pixels[..., 0], pixels[..., 2]))


def _euler(rotation: np.ndarray) -> np.ndarray:
    """Blender's XYZ Euler rotation matrix (Rz @ Ry @ Rx)."""
    (cx, cy, cz), (sx, sy, sz) = np.cos(rotation), np.sin(rotation)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


class _Reader:
    """Follows one material's node tree; `sources` maps source keys to image nodes."""

    def __init__(self) -> None:
        self.sources: dict[tuple[str, str], Any] = {}

    def linked(self, socket: Any) -> Any | None:
        """The output socket that feeds `socket`, through reroutes and muted nodes."""
        for _ in range(256):  # Blender keeps trees acyclic; this only bounds a broken one
            links = [link for link in socket.links if link.is_valid and not link.is_muted]
            if not links:
                return None
            out = links[0].from_socket
            if out.node.type == "REROUTE":
                socket = out.node.inputs[0]
            elif out.node.mute:
                through = [link.from_socket for link in out.node.internal_links if link.to_socket == out]
                if not through:
                    raise _Unfollowed(f"alpha through a muted {_label(out.node)}")
                socket = through[0]
            else:
                return out
        raise _Unfollowed("a reroute loop")

    @staticmethod
    def join(*values: _Value) -> tuple[str, str] | None:
        sources = {v.source for v in values} - {None}
        if len(sources) > 1:
            raise _Unfollowed("alpha from more than one texture")
        return next(iter(sources), None)

    def shader(self, socket: Any) -> _Value:
        """Transparency (the transparent closures' total weight) of the shader into `socket`."""
        out = self.linked(socket)
        if out is None:
            return _constant(0.0)  # no closure: Cycles stops the ray
        node = out.node
        if node.type == "BSDF_PRINCIPLED":
            alpha = self.scalar(node.inputs["Alpha"])
            return _Value(1.0 - np.clip(alpha.values, 0.0, 1.0), alpha.source)
        if node.type == "BSDF_TRANSPARENT":
            return self.scalar(node.inputs["Color"])  # the colour's luminance passes
        if node.type in ("MIX_SHADER", "ADD_SHADER"):
            first, second = (self.shader(s) for s in node.inputs if s.type == "SHADER")
            if node.type == "ADD_SHADER":
                return _Value(first.values + second.values, self.join(first, second))
            fac = self.scalar(node.inputs[0])
            f = np.clip(fac.values, 0.0, 1.0)  # Cycles clamps the mix weight
            return _Value((1.0 - f) * first.values + f * second.values, self.join(fac, first, second))
        if node.type in _OPAQUE_SHADERS:
            return _constant(0.0)
        raise _Unfollowed(f"shader from a {_label(node)}")

    def scalar(self, socket: Any) -> _Value:
        """The value at a float or colour socket (colour as its luminance, as Cycles converts)."""
        out = self.linked(socket)
        if out is None:
            return _constant(self.default(socket))
        node, kind = out.node, out.node.type
        if kind == "TEX_IMAGE":
            if node.image is None:
                raise _Unfollowed("an image texture without an image")
            if out.identifier == "Alpha" and node.image.alpha_mode == "NONE":
                return _constant(1.0)
            return self.texture(node, "A" if out.identifier == "Alpha" else "L")
        if kind in ("VALUE", "RGB"):
            return _constant(self.default(out))
        if kind == "MATH" and node.operation in MATH:
            arity = 1 if node.operation in UNARY else 3 if node.operation in TERNARY else 2
            args = [self.scalar(s) for s in list(node.inputs)[:arity]]
            args += [_constant(0.0)] * (3 - arity)
            value = MATH[node.operation](*(a.values for a in args))
            return _Value(np.clip(value, 0.0, 1.0) if node.use_clamp else value, self.join(*args))
        if kind == "INVERT":
            fac, color = self.scalar(node.inputs[0]), self.scalar(node.inputs[1])
            return _Value(color.values + fac.values * (1.0 - 2.0 * color.values), self.join(fac, color))
        if kind == "CLAMP":
            value, lo, hi = (self.scalar(s) for s in node.inputs[:3])
            if node.clamp_type == "RANGE":
                lo, hi = _Value(np.minimum(lo.values, hi.values)), _Value(np.maximum(lo.values, hi.values))
            return _Value(np.minimum(np.maximum(value.values, lo.values), hi.values), self.join(value, lo, hi))
        if kind == "MAP_RANGE" and node.data_type == "FLOAT" and node.interpolation_type in ("LINEAR", "STEPPED"):
            return self.map_range(node)
        if kind == "MIX" and (node.data_type == "FLOAT" or (node.data_type == "RGBA" and node.blend_type == "MIX")):
            suffix = "Float" if node.data_type == "FLOAT" else "Color"  # a colour mix commutes with luminance
            fac = self.scalar(_input(node, "Factor_Float"))
            a, b = (self.scalar(_input(node, f"{side}_{suffix}")) for side in "AB")
            f = np.clip(fac.values, 0.0, 1.0) if node.clamp_factor else fac.values
            value = a.values + f * (b.values - a.values)
            if node.data_type == "RGBA" and node.clamp_result:
                value = np.clip(value, 0.0, 1.0)
            return _Value(value, self.join(fac, a, b))
        if kind == "VALTORGB":
            fac = self.scalar(node.inputs[0])
            unique, back = np.unique(fac.values, return_inverse=True)
            colors = np.array([node.color_ramp.evaluate(float(x)) for x in unique])[back.ravel()]
            return _Value(colors[:, 3] if out.identifier == "Alpha" else luminance(colors), fac.source)
        if kind == "SEPARATE_COLOR" and node.mode == "RGB":
            channel = list(node.outputs).index(out)
            src = self.linked(node.inputs[0])
            if src is None:
                return _constant(node.inputs[0].default_value[channel])
            if src.node.type == "TEX_IMAGE" and src.identifier == "Color" and src.node.image is not None:
                return self.texture(src.node, "RGB"[channel])
            raise _Unfollowed(f"a colour channel of a {_label(src.node)}")
        raise _Unfollowed(f"alpha from a {_label(node)}")

    @staticmethod
    def default(socket: Any) -> float:
        value = socket.default_value
        return float(luminance(np.array(value[:3]))) if hasattr(value, "__len__") else float(value)

    def map_range(self, node: Any) -> _Value:
        """Cycles' float Map Range (linear or stepped), with its clamp to the target range."""
        # By name: the float sockets come first; the vector ones share their names.
        names = ("Value", "From Min", "From Max", "To Min", "To Max")
        stepped = node.interpolation_type == "STEPPED"
        args = [self.scalar(node.inputs[name]) for name in names + (("Steps",) if stepped else ())]
        value, from_min, from_max, to_min, to_max = (a.values for a in args[:5])
        factor = _divide(value - from_min, from_max - from_min)
        if stepped:
            steps = args[5].values
            factor = np.where(steps > 0, _divide(np.floor(factor * (steps + 1.0)), steps), 0.0)
        result = to_min + factor * (to_max - to_min)
        if node.clamp:
            result = np.clip(result, np.minimum(to_min, to_max), np.maximum(to_min, to_max))
        return _Value(result, self.join(*args))

    def texture(self, node: Any, channel: str) -> _Value:
        self.sources[(node.name, channel)] = node
        return _Value(_X.copy(), (node.name, channel))

    def channel(self, node: Any, channel: str) -> tuple[np.ndarray, bool]:
        """The texture's (H, W) channel as Cycles looks it up: "A", "L" (luminance), "R", "G",
        "B"; and whether it is still sRGB-encoded. Cycles decodes a byte sRGB image after
        the lookup: a grey one (R = G = B, the usual mask) is kept encoded, and the decode
        goes into the transfer (`build`), so its filtered edges fall where Cycles' do."""
        image = node.image
        if image.source in ("SEQUENCE", "MOVIE", "TILED", "VIEWER"):
            raise _Unfollowed(f"an image {'with UDIM tiles' if image.source == 'TILED' else image.source.lower()}")
        (width, height), channels = image.size[:], image.channels
        if width * height == 0 or channels not in (1, 3, 4):
            raise _Unfollowed(f"image {image.name!r} without pixels (a missing file?)")
        flat = np.empty(width * height * channels, dtype=np.float32)
        image.pixels.foreach_get(flat)  # row 0 is the bottom row: v = 0, as AlphaMap wants
        pixels = flat.reshape(height, width, channels)
        alpha = pixels[..., 3] if channels == 4 and image.alpha_mode != "NONE" else np.ones((height, width))
        if channel == "A":
            return alpha, False
        space = image.colorspace_settings
        decode = not image.is_float and not space.is_data and not space.name.startswith("Linear")
        if decode and space.name != "sRGB":
            raise _Unfollowed(f"image {image.name!r} in colour space {space.name!r}")
        # Cycles stores colour associated with alpha (not for data or channel-packed images),
        # and unassociates it at the lookup only where the node's Alpha output is used.
        scale = None
        if channels == 4 and image.alpha_mode in ("STRAIGHT", "PREMUL") and not space.is_data:
            straight = node.outputs["Alpha"].is_linked
            if image.alpha_mode == "STRAIGHT" and not straight:
                scale = alpha
            elif image.alpha_mode == "PREMUL" and straight:
                scale = np.where((alpha == 0) | (alpha == 1), 1.0, _divide(np.ones(alpha.shape), alpha))

        def one(index: int) -> np.ndarray:
            # One colour channel at a time: a 4K image's RGB in float64 would be 400 MB.
            value = pixels[..., min(index, channels - 1)]
            value = value if scale is None else value * scale
            return srgb_to_linear(value) if decode else value  # a byte image's bytes, decoded

        if scale is not None and np.all(scale == 1.0):
            scale = None  # an opaque image: associating changes nothing
        if decode and scale is None and channels >= 3 and _grey(pixels):
            return pixels[..., 0].astype(np.float64), True
        if channel != "L":
            return one("RGB".index(channel)), False
        return sum(weight * one(index) for index, weight in enumerate(LUMINANCE)), False

    def coordinates(self, socket: Any) -> tuple[str, np.ndarray]:
        """(UV map, 3 x 3 affine of (u, v, 1)) of an image texture's Vector input."""
        out = self.linked(socket)
        if out is None:
            return "", np.eye(3)
        node = out.node
        if getattr(node, "from_instancer", False):
            raise _Unfollowed("UVs from the instancer")
        if node.type == "UVMAP":
            return node.uv_map, np.eye(3)
        if node.type == "TEX_COORD" and out.identifier == "UV":
            return "", np.eye(3)
        if node.type == "MAPPING" and node.vector_type in ("POINT", "TEXTURE", "VECTOR"):
            uv_map, inner = self.coordinates(node.inputs["Vector"])
            return uv_map, self.mapping(node) @ inner
        raise _Unfollowed(f"texture coordinates from a {_label(node)} ({out.name})")

    def mapping(self, node: Any) -> np.ndarray:
        """Cycles' Mapping node on (u, v, 0) as an affine of (u, v, 1)."""
        names = ("Location", "Rotation", "Scale")
        if any(self.linked(node.inputs[name]) is not None for name in names):
            raise _Unfollowed("a mapping node with linked inputs")
        location, rotation, scale = (np.array(node.inputs[name].default_value[:3], dtype=np.float64)
                                     for name in names)
        turn = _euler(rotation)
        if node.vector_type == "TEXTURE":  # the inverse: (R^T (p - L)) / S
            linear = np.diag(_divide(np.ones(3), scale)) @ turn.T
            shift = -linear @ location
        else:  # POINT: R (p S) + L; VECTOR drops the location
            linear = turn @ np.diag(scale)
            shift = location if node.vector_type == "POINT" else np.zeros(3)
        affine = np.eye(3)
        affine[:2, :2], affine[:2, 2] = linear[:2, :2], shift[:2]
        return affine

    def build(self, name: str, transparency: _Value) -> MaterialAlpha:
        alpha = np.clip(1.0 - transparency.values, 0.0, 1.0)
        if transparency.source is None:
            amap = AlphaMap.constant(name, float(alpha[0]))
            return MaterialAlpha(None if amap.opaque else amap)
        node = self.sources[transparency.source]
        if node.projection != "FLAT":
            raise _Unfollowed(f"an image texture with {node.projection.lower()} projection")
        interpolation = _INTERPOLATIONS.get(node.interpolation)
        extension = _EXTENSIONS.get(node.extension)
        if interpolation is None or extension is None:
            raise _Unfollowed(f"an image texture with {node.interpolation} interpolation, {node.extension} extension")
        image, encoded = self.channel(node, transparency.source[1])
        if encoded:  # the chain was evaluated on decoded values: compose the decode into it
            alpha = np.interp(srgb_to_linear(_X), _X, alpha)
        if not np.all(np.isfinite(image)):
            raise _Unfollowed(f"image {node.image.name!r} with NaN or infinite texels")
        transfer = None if np.allclose(alpha, _X, atol=1e-7) else alpha
        amap = AlphaMap(name, image, interpolation, extension, transfer)
        if amap.opaque:
            return MaterialAlpha(None)
        uv_map, affine = self.coordinates(node.inputs["Vector"])
        return MaterialAlpha(amap, uv_map, affine[:2].copy())


def material_alpha(material: Any) -> MaterialAlpha:
    """The alpha Cycles' shadow rays see on `material` (None, or a note, when opaque or unfollowed)."""
    if material is None or not blender_compat.uses_nodes(material):
        return MaterialAlpha(None)
    tree = material.node_tree
    output = tree.get_output_node("CYCLES") or next(
        (n for n in tree.nodes if n.type == "OUTPUT_MATERIAL" and n.is_active_output), None)
    if output is None:
        return MaterialAlpha(None)
    reader = _Reader()
    try:
        return reader.build(material.name, reader.shader(output.inputs["Surface"]))
    except _Unfollowed as why:
        log.debug("material %r: alpha not followed: %s", material.name, why)
        return MaterialAlpha(None, note=str(why))


def _triangle_count(mesh: Any) -> int:
    if len(mesh.loop_triangles) == 0 and len(mesh.polygons):
        mesh.calc_loop_triangles()  # a mesh made in this process may not have them yet
    return len(mesh.loop_triangles)


def _uv_layer(mesh: Any, uv_map: str) -> Any | None:
    layers = mesh.uv_layers
    layer = layers.get(uv_map) if uv_map else None
    if layer is None and uv_map:
        log.debug("mesh %r has no UV map %r: reading the active render one", mesh.name, uv_map)
    return layer or next((la for la in layers if la.active_render), None) or layers.active


def triangle_uvs(mesh: Any, uv_map: str) -> np.ndarray:
    """(T, 3, 2) float32 UVs of the mesh's loop triangles from the named UV map
    ("" or missing: the active render one; no UV map: zeros)."""
    count = _triangle_count(mesh)
    layer = _uv_layer(mesh, uv_map)
    if layer is None or count == 0:
        return np.zeros((count, 3, 2), dtype=np.float32)
    loops = np.empty(count * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    uv = np.empty(len(mesh.loops) * 2, dtype=np.float32)
    layer.uv.foreach_get("vector", uv)
    return uv.reshape(-1, 2)[loops].reshape(count, 3, 2)


def triangle_slots(obj: Any, mesh: Any) -> tuple[list[Any], np.ndarray]:
    """An (evaluated) object's slot materials (None for an empty slot) and each loop
    triangle's slot index, clamped as Cycles clamps an index past the last slot."""
    count = _triangle_count(mesh)
    slots = [slot.material for slot in obj.material_slots] if len(obj.material_slots) else list(mesh.materials)
    index = np.zeros(count, dtype=np.int32)
    if count and slots:
        mesh.loop_triangles.foreach_get("material_index", index)
        index = np.clip(index, 0, len(slots) - 1)
    return slots, index


def mesh_surface(obj: Any, mesh: Any, cache: dict[str, MaterialAlpha] | None = None
                 ) -> tuple[Surface, dict[str, str]]:
    """The see-through surface of an (evaluated) object's mesh, and material name -> note for
    the materials not followed. `cache` (material name -> MaterialAlpha) may be shared
    between objects of one scene."""
    count = _triangle_count(mesh)
    slots, index = triangle_slots(obj, mesh)
    if count == 0 or not slots:
        return Surface.opaque(count), {}
    cache = {} if cache is None else cache
    uvs = np.zeros((count, 3, 2), dtype=np.float32)
    material = np.full(count, -1, dtype=np.int32)
    maps: list[AlphaMap] = []
    notes: dict[str, str] = {}
    layers: dict[str, np.ndarray] = {}
    for slot in np.unique(index):
        mat = slots[slot]
        if mat is None:
            continue
        found = cache.get(mat.name_full)
        if found is None:
            found = cache[mat.name_full] = material_alpha(mat)
        if found.note is not None:
            notes[mat.name] = found.note
        if found.alpha is None:
            continue
        if found.uv_map not in layers:
            layers[found.uv_map] = triangle_uvs(mesh, found.uv_map)
        chosen = index == slot
        corners = layers[found.uv_map][chosen].astype(np.float64)
        uvs[chosen] = corners @ found.uv_matrix[:, :2].T + found.uv_matrix[:, 2]
        material[chosen] = len(maps)
        maps.append(found.alpha)
    return Surface(uvs, material, tuple(maps)), notes
