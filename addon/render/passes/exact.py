"""The exact method's irregular z-buffer on the GPU: its lists, its rounds and its work.

`link_samples` links every view sample into the list of the map texel it falls in; the
exact footprint pass (footprints.draw_footprints with `exact`) walks those lists and
marks the samples whose segment to the light a triangle crosses; a walk stops at its
round's bound, and `advance_lists` moves the heads on for the next round. The marks
(`read_hits`) and the work counters (`exact_work`) are read after the last round.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...core.errors import BackendError
from ..device import UniformValues
from ..shaders import ADVANCE_PROGRAM, WORK_BOX, WORK_CUT, WORK_ENTRIES, WORK_FRAGMENTS, WORK_TEXELS
from ..shaders import ProgramInterface, link_variant
from .atlas import AtlasLayout

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

    def images(self, iface: ProgramInterface) -> dict[str, Any]:
        """The images a program of the exact pass binds, by the names it declares."""
        held = {"ow_counts": self.heads, "ow_next": self.links, "ow_hits": self.hits, "ow_work": self.work}
        return {name: held[name] for _, name in iface.images}

    def all(self) -> tuple[Any, ...]:
        return self.heads, self.links, self.hits, self.work


def _lists(backend, caller: str) -> ExactLists:
    if backend.exact is None:
        raise BackendError(f"{caller} called before link_samples")
    return backend.exact


def link_samples(backend, size: int, tiles: int, uniforms: UniformValues, hit_words: int = 1) -> None:
    """Link every uploaded sample into the list of the map texel it falls in, through the
    full warp (shaders.link_variant, the scatter's uniforms with ow_count_size = the map
    resolution), with `hit_words` words of marks a sample (a sized light's bits)."""
    if backend.samples.size is None:
        raise BackendError("link_samples called before upload_samples")
    device = backend.device
    width, height = backend.samples.size
    sizes = ((size * tiles, size), (width, height), (width, height * hit_words), (WORK_TEXELS, 1))
    held = backend.exact
    if held is None or tuple(device.texture_size(t) for t in held.all()) != sizes:
        free_lists(backend)
        held = backend.exact = ExactLists(*(device.texture(s, "R32UI") for s in sizes))
    for image in held.all():
        device.clear_image(image)
    held.work_done = dict.fromkeys(WORK_KEYS, 0)
    iface = link_variant(uniforms)
    device.dispatch(iface, uniforms, backend.textures, held.images(iface), iface.groups(width * height))


def read_links(backend) -> tuple[np.ndarray, np.ndarray]:
    """The last `link_samples` as (heads (size, size * tiles), links (H, W)) uint32, row 0 at
    the bottom; sample index i is texel (i % W, i // W) of the sample texture."""
    held = _lists(backend, "read_links")
    return backend.device.read(held.heads, "R32UI"), backend.device.read(held.links, "R32UI")


def read_hits(backend) -> tuple[np.ndarray, dict[str, int]]:
    """The exact pass's marks since the last `link_samples`: (words * H, W) uint32, non-zero
    where a triangle crossed the sample's segment to the light (row 0 at the bottom; a sized
    light's bit k of word k // 32 for its point k); and its work as `exact_work` gives it."""
    held = _lists(backend, "read_hits")
    backend.device.barrier()  # the exact pass's fragment atomics, before the read
    return backend.device.read(held.hits, "R32UI"), dict(held.work_done)


def exact_work(backend) -> dict[str, int]:
    """The exact pass's work since the last `link_samples`, as `exact_round` folded it round by
    round: `cut`, the walks that stopped at their round's bound and went on in the next;
    `rounds`, the rounds after the first; and on a measurement frame (shaders.EXACT_COUNT_KEY)
    `entries` and `fragments` walked, and `moved`, the entries the later rounds walked."""
    return dict(_lists(backend, "exact_work").work_done)


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
    done = _lists(backend, "exact_round").work_done
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
    held = _lists(backend, "advance_lists")
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


def free_lists(backend) -> None:
    """Free the lists (a new size, or the backend's release)."""
    if backend.exact is not None:
        backend.device.free(*backend.exact.all())
        backend.exact = None
