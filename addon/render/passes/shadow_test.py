"""The shadow test: the visibility of every view sample, from the atlas (and the veil,
the edge map, a sized light's points or the exact pass's marks)."""
from __future__ import annotations

import numpy as np

from ...core.errors import BackendError
from ..device import Target, UniformValues
from .exact import held_lists
from ..shaders import (EXACT_SOFT_KEY, RESOLVE_PROGRAM, SHADOW_TEST_PROGRAM, ProgramInterface, exact_soft_of,
                       program_variant)
from ..shaders import GRID_SAMPLERS_KEY, exact_soft_media_of, grids_of, haze_of, soft_of, veil_of


def test_program(backend, uniforms: UniformValues) -> tuple[ProgramInterface, dict[str, object]]:
    """The shadow test's variant for `uniforms` and the images it reads: the veil's when this
    atlas drew see-through parts, none otherwise (the plain test, unchanged); the soft
    variant when the uniforms carry a sized light's points; the exact soft variant, which
    weighs the light points the exact pass left unmarked, with its marks (and the media it
    summed per light point, which it weighs the same way)."""
    iface = program_variant(SHADOW_TEST_PROGRAM, uniforms)
    images = {}
    if backend.veil.live:
        iface, images = veil_of(iface), backend.veil.by_name()
    if int(uniforms.get("ow_soft_count", 0)) > 0:
        iface = soft_of(iface)  # a sized light (lib/soft.glsl)
    if int(uniforms.get(EXACT_SOFT_KEY, 0)) > 0:
        if backend.exact is None:
            raise BackendError("the exact soft shadow test needs the exact pass's marks (link_samples)")
        iface, images = exact_soft_of(iface), {"ow_hits": backend.exact.hits}
        if backend.sample_media.live:
            # The media its exact pass summed per light point, weighed with the surfaces' marks.
            iface, images = exact_soft_media_of(iface), {**images, "ow_media": backend.sample_media.image}
            backend.sample_media.weighed = True
    if backend.haze.live:
        iface, images = haze_of(iface), {**images, **backend.haze.by_name()}
    if int(uniforms.get("ow_grid_count", 0)) > 0:
        iface = grids_of(iface)  # density grids (lib/grids.glsl); their samplers come with the uniforms
    return iface, images


def run_shadow_test(backend, uniforms: UniformValues) -> None:
    """Run the shadow test on the uploaded samples into the samples' test target; nothing
    is read back (`read_shadow_test`)."""
    held = backend.samples
    if backend.atlas is None or held.size is None:
        raise BackendError("shadow_test needs an atlas and uploaded samples")
    device = backend.device
    if "ow_edges" not in backend.textures:
        # Bound even when no antialiasing runs (ow_edge_radius = 0 never reads it).
        backend.textures["ow_edges"] = device.texture((1, 1), "R32F", np.zeros(1, np.float32))
    iface, images = test_program(backend, uniforms)
    if backend.haze.live or backend.sample_media.weighed:
        uniforms = {**uniforms, **backend.media.uniforms()}
    textures = backend.textures
    if int(uniforms.get("ow_grid_count", 0)) > 0:
        textures = {**textures, **uniforms[GRID_SAMPLERS_KEY]}
    if images:
        device.barrier()  # the depth pass's image atomics, before the test's loads
    target = held.test[1]
    with device.drawing(target, (0, 0) + held.size):
        device.draw(iface, uniforms, textures, images=images)


def read_shadow_test(backend) -> np.ndarray:
    """The last shadow test's output: (H, W, 2) float32, row 0 at the bottom, visibility and
    flag per sample (waits for the GPU)."""
    if backend.samples.test is None:
        raise BackendError("read_shadow_test called before a shadow test")
    return backend.device.read(backend.samples.test[0], "RG32F")


def resolve_visibility(backend, target: Target, marks: bool) -> None:
    """The last shadow test's visibility and flags drawn into `target` (RG32F, the samples'
    size, row 0 at the bottom), times the exact pass's marks where `marks`: the
    visibility a compositor samples, with nothing read back (RESOLVE_PROGRAM)."""
    held = backend.samples
    if held.test is None:
        raise BackendError("resolve_visibility called before a shadow test")
    device = backend.device
    if "ow_no_hits" not in backend.textures:
        backend.textures["ow_no_hits"] = device.texture((1, 1), "R32UI", np.zeros(1, np.uint32))
    hits = media = backend.textures["ow_no_hits"]
    if marks:
        device.barrier()  # the exact pass's atomics, before the loads
        hits = held_lists(backend, "resolve_visibility").hits
    media_on = backend.sample_media.unweighed
    if media_on:
        media = backend.sample_media.image
    uniforms = {"ow_marks": int(marks), "ow_media_on": int(media_on), **backend.media.uniforms()}
    with device.drawing(target, (0, 0) + held.size):
        device.draw(RESOLVE_PROGRAM, uniforms, {"ow_test": held.test[0], "ow_positions": backend.textures["ow_positions"]},
                    images={"ow_hits": hits, "ow_media": media})

