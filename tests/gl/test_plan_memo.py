"""A steady frame's plan is the last frame's (render/plan_memo.py): kept while its inputs'
bytes are the same, made again when any of them changes."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from addon.core.presets import build_preset
from addon.render.pipeline import ShadowPipeline, ShadowSettings, ViewSamples
from addon.render.plan_memo import PlanMemo
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


def test_the_memo_hands_back_the_plan_of_equal_inputs_only():
    memo = PlanMemo()
    made = []

    def make():
        made.append(object())
        return made[-1]

    raw = np.arange(19, dtype=np.uint32)
    light = build_preset("room_omni", (16, 12)).light
    first = memo.plan(raw, (light, (0.1, 9.0)), make)
    assert memo.plan(raw.copy(), (dataclasses.replace(light), (0.1, 9.0)), make) is first
    assert memo.plan(raw, (light, (0.1, 9.5)), make) is not first  # another depth range
    changed = raw.copy()
    changed[3] += 1
    assert memo.plan(changed, (light, (0.1, 9.5)), make) is made[-1] and len(made) == 3
    moved = dataclasses.replace(light, matrix_world=light.matrix_world + _shift())
    memo.plan(changed, (moved, (0.1, 9.5)), make)
    assert len(made) == 4 and memo.hits == 1


def _shift() -> np.ndarray:
    out = np.zeros((4, 4))
    out[0, 3] = 0.01
    return out


def test_a_steady_frame_reuses_its_plan_and_a_moved_view_does_not(gl_backend):
    scene = build_preset("room_omni", (64, 48))
    samples, _, _ = view_samples(scene)
    pipeline = ShadowPipeline(gl_backend)
    settings = ShadowSettings("dpsm", 256, warp="notw")
    triangles = scene.world_triangles()
    try:
        first = pipeline.render(scene.light, triangles, samples, settings)
        again = pipeline.render(scene.light, triangles, samples, settings)
        assert again.plan is first.plan
        assert np.array_equal(again.visibility, first.visibility)
        # Half the samples gone: other statistics, so another plan.
        hit = samples.hit.copy()
        hit[:, : hit.shape[1] // 2] = False
        fewer = ViewSamples(samples.positions, samples.normals, hit, samples.camera)
        other = pipeline.render(scene.light, triangles, fewer, settings)
        assert other.plan is not first.plan
        # Another resolution is another input, even with the same statistics.
        finer = pipeline.render(scene.light, triangles, samples, dataclasses.replace(settings, resolution=512))
        assert finer.plan is not first.plan
    finally:
        pipeline.release()
