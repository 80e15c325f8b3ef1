"""A material's homogeneous medium, read from its volume graph as Cycles evaluates it.

A medium is a material whose Volume output is linked and whose Surface output is not
(`material_nodes.is_medium`): Cycles renders its mesh's faces as the medium's
boundary and nothing else. Shadow rays through it keep exp(-sigma_t L) per channel
(core/media.py), sigma_t the volume closures' summed extinction, which Cycles' SVM
(kernel/svm/closure.h) sets per node, per RGB channel:

- Principled Volume: density * (color + max(1 - color, 0) * max(1 - sqrt(absorption color), 0)),
  the Color input being the scatter colour (density <= 1e-5 gives none);
- Volume Absorption: density * (1 - color); Volume Scatter: density * color;
- Volume Coefficients (5.x): absorption + scatter coefficients;
- Add Shader: the sum; Mix Shader: (1 - f) a + f b, f clamped to [0, 1];
- density = max(density, 0); reroutes pass through; node groups are followed inside.

Each formula was checked against Cycles 5.2 renders (docs/notebook/2026-12-volumes.md,
tests/blender/test_volume_reference.py). Inputs must be constants: a value, an RGB node,
or Math nodes of constants. An input linked to anything else (a texture, an attribute,
a light-path trick) is not followed, and the material's note says why; the methods then
draw its mesh opaque (left_out.py). bpy is only touched through the material passed in.
"""
from __future__ import annotations

import logging
from typing import Any

import numpy as np

from ..core.alpha import luminance
from ..core.media import Medium
from . import material_nodes
from .material_alpha import MATH, TERNARY, UNARY, triangle_slots

log = logging.getLogger(__name__)

# Cycles leaves a closure out below this weight (CLOSURE_WEIGHT_CUTOFF).
WEIGHT_CUTOFF = 1e-5
# Node types whose outputs vary over space: a volume fed by one is heterogeneous.
_SPATIAL = {"ATTRIBUTE", "NEW_GEOMETRY", "TEX_COORD", "VOLUME_INFO", "OBJECT_INFO", "VERTEX_COLOR",
            "UVMAP", "POINT_INFO", "PARTICLE_INFO", "HAIR_INFO", "WIREFRAME", "AMBIENT_OCCLUSION",
            "BEVEL", "LAYER_WEIGHT", "FRESNEL", "TANGENT", "NORMAL_MAP", "BUMP"}
_DEPTH = 32  # nesting guard for graphs (and group nesting)
# What `material_medium` finds: the medium, or None and why (None: no medium at all).
MediumFound = tuple[Medium | None, str | None]


class Unfollowed(Exception):
    """Raised inside the reader only; its message becomes the material's note."""


def material_medium(material: Any) -> MediumFound:
    """The homogeneous medium of a material that is a medium, or (None, why it was not
    followed, one short line); (None, None) for a material that is no medium at all."""
    if material is None or not material_nodes.is_medium(material):
        return None, None
    sigma, why = _extinction(material, Reader())
    return (None, why) if sigma is None else (Medium(material.name, sigma), None)


def _extinction(material: Any, reader: "Reader") -> tuple[np.ndarray | None, str | None]:
    """The summed extinction (3,) of a material's volume graph as `reader` follows it, or
    (None, why): a node it does not follow, or a negative or infinite sum."""
    volume = material_nodes.surface_output(material.node_tree).inputs["Volume"]
    try:
        source, _, groups = reader.linked(volume, ())
        sigma = np.zeros(3) if source is None else reader.extinction(source, groups)
    except Unfollowed as why:
        log.debug("material %r: volume not followed: %s", material.name, why)
        return None, str(why)
    if np.any(sigma < 0.0) or not np.all(np.isfinite(sigma)):
        return None, f"a negative or infinite extinction {tuple(round(float(s), 4) for s in sigma)}: not followed"
    return sigma, None


def _label(node: Any) -> str:
    return node.bl_label.lower() if hasattr(node, "bl_label") else node.type.lower()


# The group nodes a socket lies inside, innermost last: how a Group Input is followed back.
_Groups = tuple[Any, ...]


class Reader:
    """Follows one volume graph with constant inputs."""

    def linked(self, socket: Any, groups: _Groups) -> tuple[Any | None, Any, _Groups]:
        """(the output socket feeding `socket` through reroutes and node groups (entered at
        their Group Output, left at their Group Input), or None where the chain ends at an
        unlinked input; that last input socket, whose default then holds; the group stack)."""
        for _ in range(4 * _DEPTH):
            source = material_nodes.linked_from(socket)
            if source is None:
                return None, socket, groups
            node = source.node
            if getattr(node, "mute", False):
                raise Unfollowed(f"a muted {_label(node)}: not followed")
            if node.type == "GROUP":
                tree = node.node_tree
                out = None if tree is None else next(
                    (n for n in tree.nodes if n.type == "GROUP_OUTPUT" and n.is_active_output), None)
                if out is None or len(groups) >= _DEPTH:
                    raise Unfollowed(f"an empty or too deep node group ({node.name}): not followed")
                socket = next(s for s in out.inputs if s.identifier == source.identifier)
                groups = (*groups, node)
                continue
            if node.type == "GROUP_INPUT":
                if not groups:
                    raise Unfollowed("a group input outside a group: not followed")
                socket = next(s for s in groups[-1].inputs if s.identifier == source.identifier)
                groups = groups[:-1]
                continue
            return source, socket, groups
        raise Unfollowed("a cycle of links: not followed")

    def extinction(self, shader: Any, groups: _Groups, depth: int = 0) -> np.ndarray:
        """(3,) the extinction of the shader behind an output socket."""
        if depth > _DEPTH:
            raise Unfollowed("a volume graph too deep: not followed")
        node, kind = shader.node, shader.node.type
        if kind == "PRINCIPLED_VOLUME":
            density = self.density(node, groups)
            if density <= WEIGHT_CUTOFF:
                return np.zeros(3)
            color = self.color(node.inputs["Color"], groups, "color")
            absorption = np.sqrt(np.maximum(self.color(node.inputs["Absorption Color"], groups,
                                                       "absorption color"), 0.0))
            return density * (color + np.maximum(1.0 - color, 0.0) * np.maximum(1.0 - absorption, 0.0))
        if kind == "VOLUME_ABSORPTION":
            return self.density(node, groups) * (1.0 - self.color(node.inputs["Color"], groups, "color"))
        if kind == "VOLUME_SCATTER":
            return self.density(node, groups) * self.color(node.inputs["Color"], groups, "color")
        if kind == "VOLUME_COEFFICIENTS":
            return (self.color(node.inputs["Absorption Coefficients"], groups, "absorption coefficients")
                    + self.color(node.inputs["Scatter Coefficients"], groups, "scatter coefficients"))
        if kind in ("ADD_SHADER", "MIX_SHADER"):
            parts = []
            for socket in node.inputs[-2:]:
                source, _, inner = self.linked(socket, groups)
                parts.append(np.zeros(3) if source is None else self.extinction(source, inner, depth + 1))
            if kind == "ADD_SHADER":
                return parts[0] + parts[1]
            f = min(max(self.scalar(node.inputs[0], groups, "mix factor"), 0.0), 1.0)
            return (1.0 - f) * parts[0] + f * parts[1]
        raise Unfollowed(f"an unknown volume shader ({_label(node)}): not followed")

    def density(self, node: Any, groups: _Groups) -> float:
        return max(self.scalar(node.inputs["Density"], groups, "density"), 0.0)

    def scalar(self, socket: Any, groups: _Groups, what: str) -> float:
        """A float input's constant value (a colour linked to it as Cycles converts it: its luminance)."""
        value = self.constant(socket, groups, what)
        return float(value if np.ndim(value) == 0 else luminance(np.asarray(value)))

    def color(self, socket: Any, groups: _Groups, what: str) -> np.ndarray:
        """A colour or vector input's constant (3,) value."""
        value = np.asarray(self.constant(socket, groups, what), dtype=np.float64)
        return np.repeat(value, 3) if value.ndim == 0 else value[:3]

    def constant(self, socket: Any, groups: _Groups, what: str) -> float | np.ndarray:
        """The value at an input socket: its default, a Value or RGB node's, or Math nodes of
        constants; anything else raises, naming whether it varies in space."""
        out, end, inner = self.linked(socket, groups)
        if out is None:
            value = end.default_value
            return np.array(value[:3], dtype=np.float64) if hasattr(value, "__len__") else float(value)
        node = out.node
        if node.type in ("VALUE", "RGB"):
            value = out.default_value
            return np.array(value[:3], dtype=np.float64) if hasattr(value, "__len__") else float(value)
        if node.type == "MATH" and node.operation in MATH:
            arity = 1 if node.operation in UNARY else 3 if node.operation in TERNARY else 2
            args = [np.atleast_1d(self.scalar(s, inner, what)) for s in list(node.inputs)[:arity]]
            args += [np.zeros(1)] * (3 - arity)
            value = float(MATH[node.operation](*args)[0])
            return min(max(value, 0.0), 1.0) if node.use_clamp else value
        if self.varies(node, inner, 0):
            raise Unfollowed(f"{what} varies in space (heterogeneous): not followed")
        raise Unfollowed(f"{what} from a {_label(node)}: not followed")

    def varies(self, node: Any, groups: _Groups, depth: int) -> bool:
        """Whether a node or any node upstream of it reads a position (a texture, an attribute)."""
        if node.type.startswith("TEX_") or node.type in _SPATIAL:
            return True
        if depth > _DEPTH:
            return False
        for socket in node.inputs:
            try:
                source, _, inner = self.linked(socket, groups)
            except Unfollowed:
                continue
            if source is not None and self.varies(source.node, inner, depth + 1):
                return True
        return False


def mesh_media(obj: Any, mesh: Any, cache: dict[str, MediumFound] | None = None
               ) -> tuple[np.ndarray, tuple[Medium, ...]]:
    """(T,) int32 the medium of each loop triangle of an (evaluated) object's mesh (-1:
    none, or a medium not followed), and the media it indexes. `cache` (material
    name_full -> `material_medium`) may be shared between objects of one scene."""
    slots, index = triangle_slots(obj, mesh)
    medium = np.full(len(index), -1, dtype=np.int32)
    media: list[Medium] = []
    cache = {} if cache is None else cache
    for slot in np.unique(index) if slots else ():
        material = slots[slot]
        if material is None:
            continue
        found = cache.get(material.name_full)
        if found is None:
            found = cache[material.name_full] = material_medium(material)
        if found[0] is not None:
            medium[index == slot] = len(media)
            media.append(found[0])
    return medium, tuple(media)


# Cycles renders a Volume object without a material with its default volume shader, a
# Principled Volume of default inputs (scene/shader.cpp, `default_volume`): density 1 times
# the "density" grid, colour 0.5, no absorption colour, so an extinction of
# 0.5 + 0.5 (1 - sqrt(0)) = 1 per unit density (measured: make_cloud_blend.py --variant inside).
DEFAULT_GRID_SIGMA = np.ones(3)
DEFAULT_DENSITY_GRID = "density"
# What `grid_sigma` finds: (extinction per unit density, the grid's name), or (None, why).
GridSigma = tuple[np.ndarray | None, str]


def grid_sigma(material: Any) -> GridSigma:
    """The extinction per unit density of a Volume object's material and the name of the
    grid it multiplies (a Principled Volume's Density Attribute, or an Attribute node on a
    volume node's Density, times constants): (sigma (3,), name), or (None, why it was not
    followed). No material: Cycles' default volume shader (`DEFAULT_GRID_SIGMA`)."""
    if material is None:
        return DEFAULT_GRID_SIGMA.copy(), DEFAULT_DENSITY_GRID
    if material_nodes.volume_source(material) is None:
        return None, f"{material.name}: no volume shader: not followed"
    # A Volume object renders its material's volume alone (a surface shader draws nothing).
    reader = _GridReader()
    sigma, why = _extinction(material, reader)
    if sigma is None:
        return None, f"{material.name}: {why}"
    if reader.grid is None:
        return None, f"{material.name}: no density grid read: not followed"
    return sigma, reader.grid


class _GridReader(Reader):
    """Follows a Volume object's volume graph: each volume node's density is constants times
    one grid, the same grid for every node (`grid`), read by name."""

    grid: str | None = None

    def _use(self, name: str) -> None:
        if not name:
            raise Unfollowed("a density without a grid (homogeneous over the grids' bounds): not followed")
        if self.grid is not None and self.grid != name:
            raise Unfollowed(f"densities of two grids ({self.grid}, {name}): not followed")
        self.grid = name

    def density(self, node: Any, groups: _Groups) -> float:
        if node.type == "PRINCIPLED_VOLUME":
            # Cycles multiplies the Density input by the Density Attribute's grid.
            attribute = node.inputs.get("Density Attribute")
            if attribute is None or material_nodes.linked_from(attribute) is not None:
                raise Unfollowed("a linked density attribute: not followed")
            self._use(str(attribute.default_value))
            return max(self.scalar(node.inputs["Density"], groups, "density"), 0.0)
        return max(self.grid_scalar(node.inputs["Density"], groups), 0.0)

    def grid_scalar(self, socket: Any, groups: _Groups) -> float:
        """A Density input that is a grid's Attribute node times constants (Math Multiply)."""
        out, _, inner = self.linked(socket, groups)
        node = None if out is None else out.node
        if node is not None and node.type == "ATTRIBUTE" and out.name == "Fac" \
                and getattr(node, "attribute_type", "GEOMETRY") == "GEOMETRY":
            self._use(str(node.attribute_name))
            return 1.0
        if node is not None and node.type == "MATH" and node.operation == "MULTIPLY" and not node.use_clamp:
            a, b = list(node.inputs)[:2]
            for grid, constant in ((a, b), (b, a)):
                try:
                    scale = self.scalar(constant, inner, "density")
                except Unfollowed:
                    continue
                return scale * self.grid_scalar(grid, inner)
        raise Unfollowed("a density that is not a grid times constants: not followed")
