"""The exact method's irregular z-buffer on the GPU: its lists, its rounds and its work.

`link_samples` links every view sample into the list of the map texel it falls in; the
exact footprint pass (footprints.draw_footprints with `exact`) walks those lists and
marks the samples whose segment to the light a triangle crosses; a walk stops at its
round's bound, and `advance_lists` moves the heads on for the next round. The marks
(`read_hits`) and the work counters (`exact_work`) are read after the last round. Whether
there is a later round is known only from the GPU's counters: `hold_rounds` keeps the
first round's passes and `finish_lists` checks, at the end of a measuring frame or at the
first read of a frame that does not wait (pipeline.FrameResult.complete).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...core.errors import BackendError
from ..device import UniformValues
from ..shaders import (ADVANCE_PROGRAM, EXACT_COUNT_KEY, EXACT_MAX_WALK, WORK_BOX, WORK_CUT, WORK_ENTRIES,
                       WORK_FRAGMENTS, WORK_TEXELS, ProgramInterface, link_variant)
from .atlas import AtlasLayout

log = logging.getLogger(__name__)

# The exact pass leaves out an occluder within this share of the segment's length from the
# sample: the receiver's own surface, and its coplanar neighbours, in float32 rounding.
EXACT_EPS = 1e-4
# The exact pass over a spot's or sun's map lifts each sample off its own surface, towards
# the light, by this share of its distance from the light-centred origin (lib/exact_walk.glsl's
# ow_exact_lift): about three times float32's rounding of the sample (6e-8), far below a
# pixel. On sun_field 5e-8 still left 333 samples of a face parallel to the sun shadowed by
# their own box, 1e-7 to 2e-7 none; from 5e-7 on, the lift moves shadow edges on the
# ground past Cycles' samples (1 pixel at 5e-7, 5 at 1e-6, 59 at 1e-5).
EXACT_LIFT = 2e-7
# Rounds of the exact pass after the first (_finish_lists): the bound doubles each round, so
# 16 of them walk lists of up to 4096 * 2^17 entries, far more than any frame's samples.
EXACT_MAX_ROUNDS = 16

WORK_KEYS = ("cut", "entries", "fragments", "moved", "rounds")


@dataclass
class ExactLists:
    """The lists' state, all R32UI images on the GPU (shaders.EXACT_IMAGES):

    heads: the strip of the count-map size and its tiles (0: empty, else sample index + 1);
    links: one next-link per sample; hits: the marks, `words` words a sample (word w of the
    sample at (x, y) at (x, y + w * H)); work: the counters (WORK_TEXELS words). `work_done`
    is what `exact_round` folded since the last `link_samples`."""

    heads: Any
    links: Any
    hits: Any
    work: Any
    work_done: dict[str, int] = field(default_factory=lambda: dict.fromkeys(WORK_KEYS, 0))
    # The first round's passes, (layout, [(tile, draws, uniforms, scissor)]), until
    # finish_lists has seen whether later rounds are needed (hold_rounds).
    rounds: tuple | None = None

    def images(self, iface: ProgramInterface) -> dict[str, Any]:
        """The images a program of the exact pass binds, by the names it declares."""
        held = {"ow_counts": self.heads, "ow_next": self.links, "ow_hits": self.hits, "ow_work": self.work}
        return {name: held[name] for _, name in iface.images if name in held}

    def all(self) -> tuple[Any, ...]:
        return self.heads, self.links, self.hits, self.work


def held_lists(backend, caller: str) -> ExactLists:
    if backend.exact is None:
        raise BackendError(f"{caller} called before link_samples")
    return backend.exact


def hold_lists(backend, size: int, tiles: int, hit_words: int = 1, media: int = 0,
               media_across: int = 1) -> ExactLists:
    """The lists' images for this frame, cleared: heads of `size` texels a side for `tiles`
    tiles, `hit_words` words of marks a sample (a sized light's bits), and the samples'
    optical depths of `media` light points each, `media_across` of them a row of blocks
    (passes/media.py's SampleMedia; 0: none). The segments' pass (passes/segments.py) marks
    these words without linking the samples."""
    if backend.samples.size is None:
        raise BackendError("the exact pass's lists held before upload_samples")
    device = backend.device
    width, height = backend.samples.size
    sizes = ((size * tiles, size), (width, height), (width, height * hit_words), (WORK_TEXELS, 1))
    held = backend.exact
    if held is None or tuple(device.texture_size(t) for t in held.all()) != sizes:
        free_lists(backend)
        held = backend.exact = ExactLists(*(device.texture(s, "R32UI") for s in sizes))
    for image in held.all():
        device.clear_image(image)
    if media:
        backend.sample_media.ready(device, (width, height), media, media_across)
    else:
        backend.sample_media.live = False
    held.work_done = dict.fromkeys(WORK_KEYS, 0)  # a new dict: an earlier frame keeps its own
    held.rounds = None
    return held


def link_samples(backend, size: int, tiles: int, uniforms: UniformValues, hit_words: int = 1,
                 media: int = 0, media_across: int = 1) -> None:
    """Link every uploaded sample into the list of the map texel it falls in, through the
    full warp (shaders.link_variant, the scatter's uniforms with ow_count_size = the map
    resolution), into the lists `hold_lists` makes ready (its arguments)."""
    held = hold_lists(backend, size, tiles, hit_words, media, media_across)
    width, height = backend.samples.size
    iface = link_variant(uniforms)
    backend.device.dispatch(iface, uniforms, backend.textures, held.images(iface), iface.groups(width * height))


def read_links(backend) -> tuple[np.ndarray, np.ndarray]:
    """The last `link_samples` as (heads (size, size * tiles), links (H, W)) uint32, row 0 at
    the bottom; sample index i is texel (i % W, i // W) of the sample texture."""
    held = held_lists(backend, "read_links")
    return backend.device.read(held.heads, "R32UI"), backend.device.read(held.links, "R32UI")


def read_media(backend) -> np.ndarray | None:
    """The exact pass's optical depths since the last `link_samples`, uint32 in
    SampleMedia's layout (passes/media.py), or None for a frame without media."""
    if not backend.sample_media.live:
        return None
    backend.device.barrier()
    return backend.device.read(backend.sample_media.image, "R32UI")


def read_hits(backend) -> tuple[np.ndarray, dict[str, int]]:
    """The exact pass's marks since the last `link_samples`: (words * H, W) uint32, non-zero
    where a triangle crossed the sample's segment to the light (row 0 at the bottom; a sized
    light's bit k of word k // 32 for its point k); and its work as `exact_work` gives it."""
    held = held_lists(backend, "read_hits")
    backend.device.barrier()  # the exact pass's fragment atomics, before the read
    return backend.device.read(held.hits, "R32UI"), dict(held.work_done)


def exact_work(backend) -> dict[str, int]:
    """The exact pass's work since the last `link_samples`, as `exact_round` folds it round by
    round (the dict itself: `finish_lists` goes on filling it): `cut`, the walks that stopped
    at their round's bound and went on in the next; `rounds`, the rounds after the first; and
    on a measurement frame (shaders.EXACT_COUNT_KEY) `entries` and `fragments` walked, and
    `moved`, the entries the later rounds walked."""
    return held_lists(backend, "exact_work").work_done


def _take_work(backend) -> np.ndarray:
    """The work image as (WORK_TEXELS,) uint32, then zeroed."""
    device = backend.device
    device.barrier()
    words = device.read(backend.exact.work, "R32UI").ravel()
    device.clear_image(backend.exact.work)
    return words


def exact_round(backend) -> int:
    """Fold the exact pass's counters since the last call into the frame's work, zero them,
    and return the walks of that round which stopped short of their list's end."""
    done = held_lists(backend, "exact_round").work_done
    words = _take_work(backend)
    cut = int(words[WORK_CUT])
    done["cut"] += cut
    entries = int(words[WORK_ENTRIES])
    done["entries"] += entries
    done["fragments"] += int(words[WORK_FRAGMENTS])
    if done["rounds"] > 0:  # a later round's counters (advance_lists came first)
        done["moved"] += entries
    return cut


def advance_lists(backend, steps: int, layout: AtlasLayout) -> dict[int, tuple[int, int, int, int]]:
    """Move every list's head past `steps` entries (ADVANCE_PROGRAM), after a round of the
    exact pass; returns, per tile, the box (x0, y0, x1, y1) of the texels whose lists go on,
    the next round's scissor (tiles without any left out)."""
    held = held_lists(backend, "advance_lists")
    width, height = backend.device.texture_size(held.heads)
    backend.device.dispatch(ADVANCE_PROGRAM, {"ow_advance_steps": int(steps), "ow_tile_size": layout.resolution},
                            backend.textures, held.images(ADVANCE_PROGRAM), ADVANCE_PROGRAM.groups(width * height))
    words = _take_work(backend)
    held.work_done["rounds"] += 1
    boxes = {}
    for tile in range(layout.tiles):
        nx0, ny0, x1, y1 = (int(w) for w in words[WORK_BOX + 4 * tile:WORK_BOX + 4 * tile + 4])
        if x1 > 0:
            boxes[tile] = (~nx0 & 0xFFFFFFFF, ~ny0 & 0xFFFFFFFF, x1, y1)
    return boxes


def map_uniforms(tile: int, count_work: bool) -> UniformValues:
    """The exact footprint pass's own uniforms over one tile: its lists are strip `tile`
    (link_samples), its walks start at the first round's bound, and a measurement frame
    (`count_work`) counts the entries and fragments walked."""
    return {"ow_exact_tile": tile, "ow_exact_eps": EXACT_EPS, "ow_exact_bound": EXACT_MAX_WALK,
            EXACT_COUNT_KEY: int(count_work)}


def free_lists(backend) -> None:
    """Free the lists (a new size, or the backend's release)."""
    if backend.exact is not None:
        backend.device.free(*backend.exact.all())
        backend.exact = None


def hold_rounds(backend, layout: AtlasLayout, passes: list) -> None:
    """Keep the first round's passes, [(tile, draws, uniforms, scissor)], for
    `finish_lists`: whether later rounds are needed is known only from the GPU's counters,
    so a frame that does not wait leaves the check to the first read of its result."""
    held_lists(backend, "hold_rounds").rounds = (layout, passes)


def finish_lists(backend) -> int:
    """Later rounds of the exact pass until every list entry met every triangle over its
    texel; returns the rounds drawn after the first (0 when `hold_rounds` kept
    nothing). A round whose walks stopped at their bound moves each list's head past the
    entries walked (backend.advance_lists) and draws the layers again, scissored to the
    texels whose lists go on, with twice the bound; so a texel of n samples takes about
    log2(n / EXACT_MAX_WALK) + 1 rounds, each entry is walked once per triangle, and a frame
    whose lists all fit (every ordinary one) pays one read of the work counters, which
    also folds the frame's work for `read_hits`."""
    held = held_lists(backend, "finish_lists")
    if held.rounds is None:
        return 0
    (layout, passes), held.rounds = held.rounds, None
    bound = EXACT_MAX_WALK
    for drawn in range(EXACT_MAX_ROUNDS):
        if not exact_round(backend):
            return drawn
        remaining = advance_lists(backend, bound, layout)
        bound *= 2
        for tile, draws, uniforms, scissor in passes:
            box = remaining.get(tile)
            if box is not None:
                clip = box if scissor is None else intersect(box, scissor)
                backend.draw_footprints(tile, draws, {**uniforms, "ow_exact_bound": bound}, scissor=clip, exact=True)
    if exact_round(backend):  # the last round's counters
        log.warning("exact pass: lists still unfinished after %d rounds", EXACT_MAX_ROUNDS)
    return EXACT_MAX_ROUNDS


def intersect(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """The common part of two texel boxes (x0, y0, x1, y1); empty ones have x1 <= x0."""
    return max(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), min(a[3], b[3])
