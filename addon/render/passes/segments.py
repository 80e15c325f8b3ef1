"""The exact pass of a sized light by segments: per view sample, one segment to each of the
light's points walked through a box tree over the light-centred triangles
(core/ray_tree.py, lib/ray_tree.glsl, exact_segments.comp), its marks written into the
lists' hits image, which the shadow test weighs as it weighs the lists' marks.

The lists' walk costs every triangle against every sample within the light's angle of it,
which under a large light is most of both; a segment costs the boxes it passes, about the
log of the triangles. It takes scenes of opaque triangles only (`fits`): hair, points,
see-through faces and media still go to the lists. A walk spends at most RAY_TREE_BUDGET
boxes and triangles a sample a turn and is resumed in the next (llvmpipe ends any loop of
one invocation after 65,535 iterations); each turn reads one counter back.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core import ray_tree
from ...core.errors import BackendError
from ..device import UniformValues
from ..pacing import Steps
from ..shaders import RAY_TREE_BUDGET, RAY_TREE_WIDTH, SEGMENTS_PROGRAM
from .exact import EXACT_EPS

log = logging.getLogger(__name__)

# Turns after which a frame gives up: each spends RAY_TREE_BUDGET units a sample, and the
# furnished interior's frame of 256 points (about 195 units a segment) took 12.
MAX_TURNS = 4096


def fits(scene) -> bool:
    """Whether a resident scene is all the segments' tree holds: opaque triangles, no
    pieces, no media, no density grids."""
    return not scene.grids and all(obj.piece_data is None and obj.alpha is None and obj.medium is None
                                   for obj in scene.objects.values())


@dataclass
class SegmentTree:
    """The tree's two tables on the GPU, for one scene state and light position, and each
    sample's place between turns (R32UI, the samples' width by twice their height)."""

    key: tuple | None = None
    boxes: Any = None
    corners: Any = None
    leaves: int = 0
    reach: float = 0.0  # the farthest triangle corner from the light
    walk: Any = None
    turns: int = 0  # the last frame's

    def held(self) -> list[Any]:
        return [t for t in (self.boxes, self.corners, self.walk) if t is not None]

    def release(self, device) -> None:
        device.free(*self.held())
        self.key, self.boxes, self.corners, self.walk = None, None, None, None

    def ready(self, device, scene, light_position: np.ndarray) -> None:
        """Build and upload the tree unless this scene state and light already have it."""
        key = (scene.state(), np.asarray(light_position, dtype=np.float64).tobytes())
        if key == self.key:
            return
        parts = [obj.light_centred(light_position) for obj in scene.objects.values() if obj.triangles]
        triangles = np.concatenate(parts) if parts else np.zeros((0, 3, 3))
        tree = ray_tree.build(triangles)
        boxes, corners = ray_tree.texels(tree, RAY_TREE_WIDTH)
        device.free(*(t for t in (self.boxes, self.corners) if t is not None))
        self.boxes = device.texture((boxes.shape[1], boxes.shape[0]), "RGBA32F", boxes)
        self.corners = device.texture((corners.shape[1], corners.shape[0]), "RGBA32F", corners)
        self.leaves = tree.leaves
        self.reach = float(np.linalg.norm(triangles.reshape(-1, 3), axis=1).max()) if len(triangles) else 0.0
        self.key = key
        log.debug("segments' tree: %d triangles, %d leaves", len(triangles), tree.leaves)


def mark_steps(backend, scene, light_position: np.ndarray, soft: UniformValues, sample_far: float) -> Steps[int]:
    """Mark, in the lists' hits image (passes/exact.hold_lists first), every light point
    of some weight whose segment from a sample some triangle crosses; returns the turns
    taken, and yields between turns while the backend's pacer is stepping (the viewport).
    `soft` are the exact soft uniforms (render/soft.exact_soft_uniforms), `sample_far`
    the farthest a sample lies from the light (0: not known)."""
    lists = backend.exact
    if lists is None:
        raise BackendError("segments.mark_steps called before hold_lists")
    device = backend.device
    held: SegmentTree = backend.segments
    held.ready(device, scene, light_position)
    width, height = backend.samples.size
    if held.walk is None or device.texture_size(held.walk) != (width, 2 * height):
        device.free(*(t for t in (held.walk,) if t is not None))
        held.walk = device.texture((width, 2 * height), "R32UI")
    device.clear_image(held.walk)
    uniforms = {**soft, "ow_tree_leaves": held.leaves, "ow_exact_eps": EXACT_EPS,
                "ow_budget": RAY_TREE_BUDGET,
                # A sun's segment reaches past every triangle from the farthest sample.
                "ow_sun_reach": 2.0 * (held.reach + max(sample_far, held.reach)) + 1.0}
    textures = {"ow_positions": backend.textures["ow_positions"], "ow_normals": backend.textures["ow_normals"],
                "ow_tree_boxes": held.boxes,
                "ow_tree_tris": held.corners}
    images = {"ow_hits": lists.hits, "ow_walk": held.walk, "ow_work": lists.work}
    groups = SEGMENTS_PROGRAM.groups(width * height)
    for turn in range(1, MAX_TURNS + 1):
        if turn > 1:
            yield from backend.pacer.pause()
        device.clear_image(lists.work)
        device.dispatch(SEGMENTS_PROGRAM, uniforms, textures, images, groups)
        left = int(device.read(lists.work, "R32UI").ravel()[0])
        if not left:
            device.clear_image(lists.work)
            held.turns = turn
            return turn
    device.clear_image(lists.work)
    log.warning("exact pass by segments: %d samples still unfinished after %d turns", left, MAX_TURNS)
    held.turns = MAX_TURNS
    return MAX_TURNS
