"""A material's node graph read as Cycles reads it: its output, what feeds a socket, and
whether it is a medium or lets shadow rays through by its alpha (read-only checks, used by
the scene readers, the viewport's scene cache and the reference's materials)."""
from __future__ import annotations

from typing import Any

from ..compat import blender as blender_compat


def surface_output(tree) -> Any:
    """The Material Output Cycles renders (its own target first, then any active one)."""
    if hasattr(tree, "get_output_node"):
        node = tree.get_output_node("CYCLES")
        if node is not None:
            return node
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"]
    return next((n for n in outputs if getattr(n, "is_active_output", False)), outputs[0] if outputs else None)


def linked_from(socket) -> Any:
    """The output socket feeding `socket` (through reroutes), or None."""
    while socket.is_linked:
        link = socket.links[0]
        if not getattr(link, "is_valid", True) or getattr(link, "is_muted", False):
            return None
        node = link.from_node
        if node.type == "REROUTE":
            socket = node.inputs[0]
            continue
        return link.from_socket
    return None


def volume_source(material) -> Any:
    """The socket feeding a material's Volume output, or None (read-only check)."""
    if material is None or not blender_compat.uses_nodes(material):
        return None
    output = surface_output(material.node_tree)
    socket = output.inputs.get("Volume") if output is not None else None
    return linked_from(socket) if socket is not None else None


def is_medium(material) -> bool:
    """Whether a material is a medium only: a volume and no surface shader."""
    if volume_source(material) is None:
        return False
    surface = surface_output(material.node_tree).inputs.get("Surface")
    return surface is None or linked_from(surface) is None


def see_through(material) -> bool:
    """Whether a material's shader lets shadow rays through by its alpha (read-only check)."""
    if material is None or not blender_compat.uses_nodes(material):
        return False
    output = surface_output(material.node_tree)
    source = linked_from(output.inputs["Surface"]) if output is not None else None
    return source is not None and _has_alpha(source, 0)


def _has_alpha(shader_output, depth: int) -> bool:
    node = shader_output.node
    if depth > 16:
        return False
    if node.type == "BSDF_PRINCIPLED":
        socket = node.inputs["Alpha"]
        return linked_from(socket) is not None or float(socket.default_value) < 1.0
    if node.type == "BSDF_TRANSPARENT":
        return True
    if node.type == "MIX_SHADER":
        return any(_has_alpha(s, depth + 1) for s in map(linked_from, node.inputs[1:3]) if s is not None)
    return False
