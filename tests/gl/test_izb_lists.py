"""The irregular z-buffer's lists (issue 19, first step): linking the view samples into
per-texel lists through the full warp gives every hit sample exactly once, in lists whose
lengths are the count map of the same mapping."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.presets import build_preset
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


def _walk(heads: np.ndarray, links: np.ndarray) -> tuple[np.ndarray, list[int]]:
    """List lengths per head texel, and every sample index met (numpy, the oracle's side)."""
    flat_links = links.ravel()
    lengths = np.zeros(heads.shape, dtype=np.int64)
    met: list[int] = []
    for (row, col), head in np.ndenumerate(heads):
        node = int(head)
        while node:
            met.append(node - 1)
            lengths[row, col] += 1
            node = int(flat_links[node - 1])
            assert lengths[row, col] <= flat_links.size, "a list loops"
    return lengths, met


@pytest.mark.parametrize("preset,param,warp", [("room_omni", "dpsm", "notw"), ("courtyard", "dpsm", "notw"),
                                               ("room_hemi", "cube", "notw"), ("room_omni", "dpsm", "none")])
def test_lists_hold_every_sample_once_with_the_count_maps_lengths(gl_backend, preset, param, warp):
    scene = build_preset(preset, (64, 48))
    samples, _, _ = view_samples(scene)
    pipe = ShadowPipeline(gl_backend)
    res = 128
    result = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings(param, res, warp=warp))
    pipe.link_lists(scene.light, result.plan, result.mappings, res)
    heads, links = gl_backend.read_links()
    lengths, met = _walk(heads, links)
    counts = pipe.count_maps(scene.light, result.plan, result.mappings, res, 2)
    for tile, slot in enumerate(result.plan.drawn_slots):
        np.testing.assert_array_equal(lengths[:, tile * res:(tile + 1) * res], counts[slot])
    # Every sample the count maps count is in exactly one list; the others in none.
    assert len(met) == len(set(met)) == int(sum(c.sum() for c in counts.values()))
    rows, cols = np.divmod(np.asarray(met), samples.hit.shape[1])
    assert samples.hit[::-1][rows, cols].all()  # the sample texture's rows run bottom-up
    assert len(met) > 0.5 * samples.hit.sum()
