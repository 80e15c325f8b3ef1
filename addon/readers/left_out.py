"""What Cycles renders but OmniWarp's methods do not draw, found in the evaluated geometry.

The render depsgraph (`render_geometry.collect`) hands over every instance Cycles
renders. Most become triangles. These do not, or not as Cycles renders them, and the
rows, the report, the comparison panel and the log must say so:

- **volumes**: Volume geometry (OpenVDB grids, geometry nodes' volumes) whose density
  grid `volume_grids` could not read, each with why (a grid read is a grid medium,
  `render_geometry.SceneTriangles.grids`, and is not named);
- a **volume material** on a mesh without a surface shader (a smoke or fog box) whose
  medium `material_media.material_medium` cannot follow (a density that varies in space,
  a light-path trick, an unknown node): Cycles and the reference (reference_materials)
  render the medium, the maps an opaque surface; the note says why for each material. A
  homogeneous medium is drawn (its triangles carry it, `Surface.medium`), so
  it is not named;
- **true displacement**: a material that displaces its surface at render time (the
  maps draw the undisplaced triangles, and so does the reference, whose white
  materials displace nothing).

Hair curves, particle hair and point clouds are drawn: `render_geometry`
keeps them as strands and spheres, every method but unfold draws them, and unfold's rows
say so (compare._row_note). The type of an instance is what geometry nodes made it, not
the type of the object that carries it: a volume made by a mesh object's modifier is
named here by that object. Shadow catchers and holdouts, and see-through
materials, are the shadow rule's notes (`shadow_rule.unfollowed`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from collections.abc import Iterator
from typing import Any, Callable

from ..compat import blender as blender_compat
from .material_media import material_medium
from .smoke_domains import is_gas_domain

log = logging.getLogger(__name__)

# Each kind's note, in the order notes are given; the owners' names follow it.
KINDS = {
    "volume": "volumes that Cycles shadows with, not drawn by OmniWarp's methods",
    "volume_material": ("volume materials without a surface shader whose medium OmniWarp does not follow, "
                        "a medium in Cycles (and in the reference), drawn as opaque surfaces by OmniWarp's methods"),
    "displacement": ("true displacement, which OmniWarp's methods and the reference (its white materials "
                     "displace nothing) leave out"),
    "elliptic_hair": ("hair under a non-uniform scale, elliptic tubes in Cycles, drawn by OmniWarp's methods "
                      "as round tubes of the same cross-section"),
}
# Instance types (`Object.type` of a depsgraph instance) that give no triangles and that
# no method draws; hair curves and point clouds (CURVES, POINTCLOUD) are drawn as pieces.
_INSTANCE_KINDS = {"VOLUME": "volume"}


@dataclass
class LeftOut:
    """The owners (object, instancer or None) of each kind of geometry the methods leave out."""

    found: dict[str, set[tuple[str, str | None]]] = field(default_factory=dict)
    # Per kind and owner, why (as "material: reason"), where a kind has reasons.
    why: dict[str, dict[tuple[str, str | None], set[str]]] = field(default_factory=dict)

    def add(self, kind: str, name: str, parent: str | None = None, why: str | None = None) -> None:
        self.found.setdefault(kind, set()).add((name, parent))
        if why is not None:
            self.why.setdefault(kind, {}).setdefault((name, parent), set()).add(why)

    def discard(self, kind: str, name: str, parent: str | None = None) -> None:
        """Forget an owner of a kind (a volume whose grid was read: the methods draw it)."""
        self.found.get(kind, set()).discard((name, parent))
        self.why.get(kind, {}).pop((name, parent), None)

    def forget(self, kind: str, name: str, parent: str | None, why: str) -> None:
        """Forget one reason an owner was named for (a medium read after all); the owner
        goes when no reason is left."""
        whys = self.why.get(kind, {}).get((name, parent))
        if whys is None:
            return
        whys.discard(why)
        if not whys:
            self.discard(kind, name, parent)

    def notes(self, keep: Callable[[str, str | None], bool] | None = None) -> list[str]:
        """One note per kind, naming the objects whose geometry `keep(name, parent)` (a
        light's `ShadowRule.blocks`) accepts (every owner without `keep`), after the
        reasons of their materials in parentheses; the object names come last."""
        out = []
        for kind, note in KINDS.items():
            owners = [o for o in self.found.get(kind, set()) if keep is None or keep(*o)]
            names = sorted({parent or name for name, parent in owners})
            if not names:
                continue
            reasons = sorted({r for owner in owners for r in self.why.get(kind, {}).get(owner, ())})
            why = f" ({', '.join(reasons)})" if reasons else ""
            out.append(f"{note}{why}: {', '.join(names)}")
        return out


def scan_instance(left: LeftOut, inst: Any, materials: dict[str, tuple[tuple[str, str | None], ...]]) -> None:
    """Record what of one depsgraph instance the methods leave out. `materials` caches
    each material's kinds (and why) by name."""
    obj = inst.object
    parent = inst.parent if inst.is_instance else None
    name = obj.original.name_full
    parent_name = None if parent is None else parent.original.name_full
    kind = _INSTANCE_KINDS.get(obj.type)
    if kind is not None:
        left.add(kind, name, parent_name)
        return
    if obj.type != "MESH" or is_gas_domain(obj):  # a smoke domain is Volume geometry (render_geometry)
        return
    if parent is None and obj.is_instancer and not obj.original.show_instancer_for_render:
        return  # an emitter Cycles does not draw: its surface, materials and all
    for slot in getattr(obj, "material_slots", ()):
        material = slot.material
        if material is None:
            continue
        kinds = materials.get(material.name_full)
        if kinds is None:
            kinds = materials[material.name_full] = material_kinds(material)
        for found, why in kinds:
            left.add(found, name, parent_name, why)


def path_hair_systems(obj: Any) -> Iterator[Any]:
    """An evaluated mesh's hair particle systems that render draws as strands (Cycles'
    curves): hair, drawn as paths, its modifier shown in renders."""
    for modifier in obj.modifiers:
        if modifier.type != "PARTICLE_SYSTEM" or not modifier.show_render:
            continue
        settings = modifier.particle_system.settings
        if settings.type == "HAIR" and settings.render_type == "PATH":
            yield modifier.particle_system


def _output(material: Any) -> Any | None:
    """The material output Cycles renders, or None."""
    tree = getattr(material, "node_tree", None)
    if tree is None or not blender_compat.uses_nodes(material):
        return None
    if hasattr(tree, "get_output_node"):
        return tree.get_output_node("CYCLES")
    return next((n for n in tree.nodes if n.type == "OUTPUT_MATERIAL" and n.is_active_output), None)


def material_kinds(material: Any) -> tuple[tuple[str, str | None], ...]:
    """The kinds a material makes of its surface that no method draws, each with why
    ("material: reason") or None: a volume without a surface shader whose medium is not
    followed (Cycles renders the surface transparent, the medium inside), true displacement."""
    output = _output(material)
    if output is None:
        return ()
    kinds: list[tuple[str, str | None]] = []
    medium, why = material_medium(material)
    if medium is None and why is not None:
        kinds.append(("volume_material", f"{material.name}: {why}"))
    displacement = output.inputs.get("Displacement")
    if (getattr(material, "displacement_method", "BUMP") in ("DISPLACEMENT", "BOTH")
            and displacement is not None and displacement.is_linked):
        kinds.append(("displacement", None))
    return tuple(kinds)
