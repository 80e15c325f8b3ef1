"""The edge-distance map of the atlas (EDGE_PROGRAM, two passes), read by the shadow test's
antialiasing (unfold+aa)."""
from __future__ import annotations

from ...core.errors import BackendError
from ..device import UniformValues
from ..shaders import EDGE_PASSES, EDGE_PROGRAM

TARGETS = ("ow_edge_x", "ow_edges")  # the along-x pass writes the first, the along-y pass the second


def edge_uniforms(edge_pass: int, radius: int, eps: float, resolution: int) -> UniformValues:
    """EDGE_PROGRAM's uniforms for one of its two passes."""
    return {"ow_edge_pass": edge_pass, "ow_edge_radius": int(radius), "ow_edge_eps": float(eps),
            "ow_edge_tile_size": float(resolution)}


def edge_distance(backend, radius: int, eps: float) -> None:
    """Edge-distance map of the atlas bound as `ow_edges` for the next shadow test: per
    texel, the Manhattan distance (in texels, up to radius + 1) to the nearest texel of its
    tile whose depth is at least `eps` nearer."""
    if backend.atlas is None:
        raise BackendError("edge_distance needs a drawn atlas")
    device = backend.device
    layout = backend.atlas.layout
    size = layout.size
    if not backend.edge_targets or backend.edge_targets[0].size != size:
        # Both passes write a fresh target; each keeps its framebuffer with its texture.
        device.free(*backend.edge_targets, *(backend.textures.pop(name, None) for name in TARGETS))
        for name in TARGETS:
            backend.textures[name] = device.texture(size, "R32F")
        backend.edge_targets = tuple(device.target((backend.textures[name],)) for name in TARGETS)
    for edge_pass, target in zip((EDGE_PASSES["along_x"], EDGE_PASSES["along_y"]), backend.edge_targets):
        textures = dict(backend.textures)
        if edge_pass == EDGE_PASSES["along_x"]:
            # Pass 0 writes ow_edge_x: it samples the other target there, so no texture is
            # both read and written (a GL feedback loop), even statically.
            textures["ow_edge_x"] = backend.textures["ow_edges"]
        with device.drawing(target, (0, 0) + size):
            device.draw(EDGE_PROGRAM, edge_uniforms(edge_pass, radius, eps, layout.resolution), textures)
