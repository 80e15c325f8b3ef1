"""Read-only view samples stay on the GPU between frames (issue 41's first step): a steady
frame uploads none, and anything that could make the held samples stale uploads again."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from addon.core.presets import build_preset
from addon.core.scene import LightSpec
from addon.render.frame import resident_samples_key
from addon.render.pipeline import ShadowPipeline, ShadowSettings, ViewSamples
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl

SETTINGS = ShadowSettings("dpsm", 256, warp="notw")


def _frozen(samples: ViewSamples) -> ViewSamples:
    arrays = [np.array(a) for a in (samples.positions, samples.normals, samples.hit)]
    for array in arrays:
        array.flags.writeable = False
    return ViewSamples(*arrays, samples.camera)


@pytest.fixture(scope="module")
def case():
    scene = build_preset("room_omni", (64, 48))
    samples, _, evaluable = view_samples(scene)
    return scene, samples, evaluable


def _counted(gl_backend, case, monkeypatch):
    """A pipeline whose backend counts its sample uploads, the case's samples read-only,
    and its triangles."""
    scene, samples, _ = case
    calls: list[int] = []
    real = gl_backend.upload_samples

    def spy(positions, normals):
        calls.append(1)
        return real(positions, normals)

    monkeypatch.setattr(gl_backend, "upload_samples", spy)
    return ShadowPipeline(gl_backend), calls, _frozen(samples), scene.world_triangles()


def test_read_only_samples_upload_once_and_shadow_alike(gl_backend, case, monkeypatch):
    scene, samples, _ = case
    pipeline, calls, frozen, tris = _counted(gl_backend, case, monkeypatch)
    first = pipeline.render(scene.light, tris, frozen, SETTINGS)
    later = [pipeline.render(scene.light, tris, frozen, SETTINGS) for _ in range(3)]
    assert len(calls) == 1
    for result in later:
        assert np.array_equal(result.visibility, first.visibility)
    # Writable arrays may change in place between frames: every frame uploads them.
    for _ in range(2):
        pipeline.render(scene.light, tris, samples, SETTINGS)
    assert len(calls) == 3


def test_a_moved_light_or_other_samples_upload_again(gl_backend, case, monkeypatch):
    scene, samples, _ = case
    pipeline, calls, frozen, tris = _counted(gl_backend, case, monkeypatch)
    pipeline.render(scene.light, tris, frozen, SETTINGS)
    moved_matrix = scene.light.matrix_world.copy()
    moved_matrix[:3, 3] += (0.05, -0.03, 0.02)
    moved = LightSpec(scene.light.emission, moved_matrix)
    held = pipeline.render(moved, tris, frozen, SETTINGS)
    assert len(calls) == 2
    # Another pipeline on the same backend uploads the writable samples (the spy counts it).
    fresh = ShadowPipeline(gl_backend).render(moved, tris, samples, SETTINGS)
    assert len(calls) == 3 and np.array_equal(held.visibility, fresh.visibility)
    # The backend now holds those: the frozen ones go up again, and shadow alike.
    again = pipeline.render(moved, tris, frozen, SETTINGS)
    assert len(calls) == 4 and np.array_equal(again.visibility, fresh.visibility)
    # Other read-only arrays with the same values are other samples.
    pipeline.render(moved, tris, _frozen(samples), SETTINGS)
    assert len(calls) == 5


def test_only_arrays_that_cannot_change_are_keyed(case):
    scene, samples, _ = case
    frozen = _frozen(samples)
    assert resident_samples_key(samples, scene.light) is None
    key = resident_samples_key(frozen, scene.light)
    assert key is not None and key.matches(resident_samples_key(frozen, scene.light))
    base = np.array(samples.positions)
    view = base[:]
    view.flags.writeable = False  # read-only, but its base may still change
    assert resident_samples_key(replace(frozen, positions=view), scene.light) is None
    weights = np.ones(samples.hit.shape)
    weights.flags.writeable = False
    weighted = replace(frozen, importance=weights)
    assert not key.matches(resident_samples_key(weighted, scene.light))
