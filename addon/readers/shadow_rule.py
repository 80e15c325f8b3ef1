"""One rule for what blocks a light, read from a Blender scene as Cycles reads it.

Every consumer asks this module: the Cycles reference capture (which stores the
occluder triangles of its light), `compare --blend`, `preview`, the viewport
preview and the comparison panel. The rule follows Cycles 5.2:

- **Ray visibility.** An object with `visible_shadow` off casts no shadow; it is
  still seen and still receives. An instance also needs its instancer's flag
  (Cycles ANDs the top-level instancer's ray visibility into the instance's; an
  instancer nested in between is not read).
- **Shadow linking** (Blender 4.0+): the light's `light_linking.blocker_collection`.
  Entries of the collection are INCLUDE or EXCLUDE; an entry that is a collection
  passes its state to everything nested in it, and a later entry overrides an
  earlier one for the same object (children are walked before objects, as the
  depsgraph's light-linking cache walks them). With at least one object included,
  only included objects block; otherwise every object blocks except the excluded.
  An instance takes its instancer's linking when the instancer is named in any
  blocker collection of the scene, else its own.
- **Camera visibility** (`seen`, for a preview's G-buffer): `visible_camera`, the
  instancer's too, and indirect-only view-layer collections, whose objects cast
  shadows but are not seen.
- **Light linking's receivers** (`receiver_collection`), read the same way: pixels
  of objects the light does not light get no light in Cycles, so the reference
  never evaluates them; `lights()` tells the preview the same.
- **The light's own `use_shadow`**: off, nothing blocks it.
- What is rendered at all (`hide_render`, excluded collections, instancers shown
  or not for render, render-level modifiers) comes from the render depsgraph
  (`render_geometry.py`), so it needs no rule here.

What the rule cannot follow is reported in `notes`: shadow catchers and holdout
objects (the capture renders them as plain surfaces) and materials that let shadow
rays through (the capture replaces every material by an opaque white one). What the
methods do not draw (volumes, media not followed, true displacement) is found in the
evaluated geometry itself, by `left_out.py`.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Callable, Hashable, Iterable

import numpy as np

from ..compat import blender as blender_compat
from . import material_nodes

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

log = logging.getLogger(__name__)

INCLUDE = "INCLUDE"
EXCLUDE = "EXCLUDE"
# Object types whose surfaces Cycles renders (the maps get triangles from the first five).
_SURFACE_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"}
# Shader nodes that make a surface (partly) transparent to shadow rays.
_SEE_THROUGH_NODES = {"BSDF_TRANSPARENT", "BSDF_REFRACTION", "BSDF_GLASS", "HOLDOUT"}


def _name(obj: Any) -> str:
    """The original ID's full name (evaluated copies carry the same name)."""
    return (getattr(obj, "original", None) or obj).name_full


def _names(obj: Any, parent: Any) -> tuple[str, str | None]:
    """(object, instancer or None) as original names; strings pass through."""
    name = obj if isinstance(obj, str) else _name(obj)
    if parent is None or isinstance(parent, str):
        return name, parent
    return name, _name(parent)


def collection_states(collection: "bpy.types.Collection | None") -> dict[str, str]:
    """Object name -> INCLUDE or EXCLUDE, as the light-linking cache assigns them.

    Top-level child collections first (each walked depth-first, children before
    objects, all with the top-level entry's state), then the top-level objects;
    a later visit overrides an earlier one.
    """
    states: dict[str, str] = {}
    if collection is None:
        return states

    def nested(child: "bpy.types.Collection", state: str) -> None:
        for grandchild in child.children:
            nested(grandchild, state)
        for obj in child.objects:
            states[obj.name_full] = state

    for child, entry in zip(collection.children, collection.collection_children):
        nested(child, entry.light_linking.link_state)
    for obj, entry in zip(collection.objects, collection.collection_objects):
        states[obj.name_full] = entry.light_linking.link_state
    return states


@dataclass(frozen=True)
class LinkSet:
    """The objects a linking collection admits: included ones, or all but the excluded."""

    states: dict[str, str] = field(default_factory=dict)
    linked: bool = False  # False: the light has no collection, every object is admitted

    @cached_property
    def has_include(self) -> bool:
        # Asked for every owner of every triangle batch: scan the states once.
        return INCLUDE in self.states.values()

    def admits(self, name: str) -> bool:
        if not self.linked:
            return True
        state = self.states.get(name)
        if state is not None:
            return state == INCLUDE
        return not self.has_include

    def key(self) -> tuple:
        return (self.linked, tuple(sorted(self.states.items())))

    @classmethod
    def of(cls, collection: "bpy.types.Collection | None") -> "LinkSet":
        """The set a light's linking collection (None: not linked) admits."""
        return cls(collection_states(collection), collection is not None)


def _linking(obj: Any, attr: str) -> "bpy.types.Collection | None":
    if not blender_compat.has_light_linking():  # Blender 4.0+
        return None
    return getattr(obj.light_linking, attr, None)


def _mentioned(objects: Iterable[Any], attr: str) -> frozenset[str]:
    """Objects named in any emitter's `attr` collection: they have a linking set of their own."""
    names: set[str] = set()
    seen: set[str] = set()
    for obj in objects:
        collection = _linking(obj, attr)
        if collection is not None and collection.name_full not in seen:
            seen.add(collection.name_full)
            names |= set(collection_states(collection))
    return frozenset(names)


def _indirect_only(view_layer: "bpy.types.ViewLayer | None") -> set[str]:
    """Objects in the layer's indirect-only collections: Cycles' camera rays pass through them."""
    names: set[str] = set()
    if view_layer is None or view_layer.layer_collection is None:
        return names

    def walk(layer_collection: "bpy.types.LayerCollection", inherited: bool) -> None:
        indirect = inherited or bool(getattr(layer_collection, "indirect_only", False))
        if indirect:
            names.update(obj.name_full for obj in layer_collection.collection.objects)
        for child in layer_collection.children:
            walk(child, indirect)

    walk(view_layer.layer_collection, False)
    return names


def _see_through_material(material: "bpy.types.Material") -> str | None:
    """Why a material lets shadow rays through in Cycles in a way the reference does not
    keep, or None. Alpha (a Principled BSDF's, Transparent BSDFs in Mix Shaders) is kept
    (reference_materials); transmission, refraction and glass are not."""
    if not blender_compat.uses_nodes(material):
        return None
    tree = material.node_tree
    follows_alpha = material_nodes.see_through(material)
    for node in tree.nodes:
        if node.type in _SEE_THROUGH_NODES and not (node.type == "BSDF_TRANSPARENT" and follows_alpha):
            return f"a {node.type.replace('BSDF_', '').lower()} shader"
        if node.type == "BSDF_PRINCIPLED":
            for socket_name in ("Transmission Weight", "Transmission"):
                socket = node.inputs.get(socket_name)
                if socket is None:
                    continue
                if socket.is_linked or float(socket.default_value) > 0.0:
                    return f"Principled {socket_name.lower()}"
    return None


@dataclass(frozen=True)
class ShadowRule:
    """What blocks one light, and what it lights; build it with `for_light`.

    Objects are named by their original `name_full`, so the rule can be asked
    about evaluated copies, instances and cached parts alike.
    """

    light: str
    casts_shadows: bool = True  # the light's own use_shadow
    blockers: LinkSet = LinkSet()
    receivers: LinkSet = LinkSet()
    blocker_named: frozenset[str] = frozenset()  # in some blocker collection: own shadow set
    receiver_named: frozenset[str] = frozenset()
    no_shadow: frozenset[str] = frozenset()  # visible_shadow off
    no_camera: frozenset[str] = frozenset()  # visible_camera off, or in an indirect-only collection
    notes: tuple[str, ...] = ()

    @classmethod
    def for_light(cls, scene: "bpy.types.Scene", light_obj: "bpy.types.Object", notes: bool = True,
                  view_layer: "bpy.types.ViewLayer | None" = None) -> "ShadowRule":
        """Read the rule of `light_obj` from the file's data.

        `notes=False` skips the scan for what the rule cannot follow (the viewport
        asks every redraw; the capture asks once and logs the notes). `view_layer`
        (default: the first one enabled for rendering) holds the indirect-only
        collections, whose objects cast shadows but are not seen by the camera.
        """
        import bpy

        light_obj = getattr(light_obj, "original", None) or light_obj
        objects = list(bpy.data.objects)  # instanced collections need not be in the scene
        if view_layer is None:
            view_layer = next((layer for layer in scene.view_layers if layer.use), None)
        hidden_from_camera = {o.name_full for o in objects if not getattr(o, "visible_camera", True)}
        return cls(
            light=light_obj.name_full,
            casts_shadows=bool(getattr(light_obj.data, "use_shadow", True)),
            blockers=LinkSet.of(_linking(light_obj, "blocker_collection")),
            receivers=LinkSet.of(_linking(light_obj, "receiver_collection")),
            blocker_named=_mentioned(objects, "blocker_collection"),
            receiver_named=_mentioned(objects, "receiver_collection"),
            no_shadow=frozenset(o.name_full for o in objects if not getattr(o, "visible_shadow", True)),
            no_camera=frozenset(hidden_from_camera | _indirect_only(view_layer)),
            notes=tuple(unfollowed(scene)) if notes else (),
        )

    def blocks(self, obj: Any, parent: Any = None) -> bool:
        """Whether an object (or an instance of it under `parent`) blocks this light."""
        name, parent_name = _names(obj, parent)
        if not self.casts_shadows or name in self.no_shadow:
            return False
        if parent_name is not None and parent_name != name and parent_name in self.no_shadow:
            return False
        owner = parent_name if parent_name is not None and parent_name in self.blocker_named else name
        return self.blockers.admits(owner)

    def lights(self, obj: Any, parent: Any = None) -> bool:
        """Whether this light lights the object at all (light linking's receivers)."""
        name, parent_name = _names(obj, parent)
        owner = parent_name if parent_name is not None and parent_name in self.receiver_named else name
        return self.receivers.admits(owner)

    def seen(self, obj: Any, parent: Any = None) -> bool:
        """Whether camera rays see the object (`visible_camera`, the instancer's too)."""
        name, parent_name = _names(obj, parent)
        return name not in self.no_camera and (parent_name is None or parent_name not in self.no_camera)

    def key(self) -> tuple:
        """Hashable summary: equal keys select the same triangles."""
        return (self.light, self.casts_shadows, self.blockers.key(), self.blocker_named, self.no_shadow)


def rules_for(scene: "bpy.types.Scene", light_names: Iterable[str]) -> dict[str, ShadowRule]:
    """The rule of each named light object (names that are not lights in the file are left out)."""
    import bpy

    rules = {}
    for name in light_names:
        obj = bpy.data.objects.get(name)
        if obj is not None and obj.type == "LIGHT":
            rules[name] = ShadowRule.for_light(scene, obj, notes=False)
    return rules


def _everything(_name: str, _parent: str | None) -> bool:
    return True


def shadow_inputs(select: Callable[[Callable[[str, str | None], bool], Hashable], np.ndarray],
                  rules: dict[str, ShadowRule]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """What the camera sees (a G-buffer's triangles) and, per light, what blocks it.

    `select(keep, key)` returns the triangles whose owners `keep(name, instancer)`
    accepts (a scene cache or a `SceneTriangles`); without rules, all of them.
    """
    if not rules:
        return select(_everything, ("all",)), {}
    first = next(iter(rules.values()))
    seen = select(first.seen, ("seen", first.no_camera))
    return seen, {name: select(rule.blocks, rule.key()) for name, rule in rules.items()}


def unfollowed(scene: "bpy.types.Scene") -> list[str]:
    """One note per thing in the scene that the rule (and the reference capture) cannot follow."""
    notes: list[str] = []
    # Only rendered surfaces: lights carry the flags too (is_shadow_catcher reads True on them).
    surfaces = [o for o in scene.objects if o.type in _SURFACE_TYPES and not o.hide_render]
    catchers = sorted(o.name for o in surfaces if getattr(o, "is_shadow_catcher", False))
    if catchers:
        notes.append(f"shadow catcher rendered as a plain surface: {', '.join(catchers)}")
    # Holdout collections are followed: they cast shadows, and their pixels (alpha 0 in the
    # reference) are not evaluated (docs/comparison.md).
    holdouts = sorted(o.name for o in surfaces if getattr(o, "is_holdout", False))
    if holdouts:
        notes.append(f"holdout rendered as a plain surface: {', '.join(holdouts)}")
    see_through: dict[str, str] = {}
    for obj in scene.objects:
        if obj.hide_render:
            continue
        for slot in getattr(obj, "material_slots", ()):
            material = slot.material
            if material is None or material.name in see_through:
                continue
            why = _see_through_material(material)
            if why is not None:
                see_through[material.name] = why
    if see_through:
        listed = ", ".join(f"{name} ({why})" for name, why in sorted(see_through.items()))
        notes.append(f"materials the reference renders opaque (white diffuse) but Cycles would not: {listed}")
    for note in notes:
        log.warning("scene %r: %s", scene.name, note)
    return notes
