"""The moderngl pipeline against Cycles on the foundation's hard geometry.

The scene holds a slab straddling the paraboloid seam and a 1 km floor quad of two
triangles. The third hard case, a vertex exactly at the light, is checked against
the same Cycles image: a triangle whose plane holds the light subtends no solid
angle, so adding it must change nothing. (Cycles itself cannot be the judge of
that scene: its shadow rays end exactly at the light and hit such a triangle at
random through float rounding, speckling about a quarter of the floor.)
moderngl and Cycles may share a process (docs/design.md section 3).
"""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from addon.compare import light_from_reference, samples_from_reference  # noqa: E402
from addon.core import metrics  # noqa: E402
from addon.core.scene import SceneBuilder  # noqa: E402
from addon.reference.blender_scene import build_blender_scene, remove_blender_scene  # noqa: E402
from addon.reference.capture import capture  # noqa: E402
from addon.render.pipeline import ShadowPipeline, ShadowSettings  # noqa: E402
from addon.render.frame import Measure

pytestmark = [pytest.mark.blender, pytest.mark.gl]

LIGHT = (0.0, 0.0, 2.2)
FAN = np.array([[LIGHT, [0.8, -0.6, 1.5], [0.8, 0.6, 1.5]]])  # one triangle with a vertex at the light


@pytest.fixture(scope="module")
def hard_scene_reference():
    b = SceneBuilder("hard_geometry", (200, 150))
    b.plane("floor", (0.0, 0.0, 0.0), 2000.0, 2000.0)  # two triangles, 1 km on a side
    b.box("box", (1.4, 0.5, 0.5), (0.8, 0.8, 1.0))
    b.mesh("slab", [[-0.6, -1.6, 1.2], [-0.6, 1.2, 1.2], [-1.0, -0.2, 3.4]], [[0, 1, 2]])  # crosses z = 2.2
    b.point_light(LIGHT)
    b.camera((5.0, -5.5, 4.5), (0.0, 0.0, 0.4), fov_deg=65.0)
    scene = build_blender_scene(b.finish())
    try:
        yield capture(scene)
    finally:
        remove_blender_scene(scene)


@pytest.mark.parametrize("param", ["dpsm", "cube"])
def test_hard_geometry_matches_cycles(gl_backend, hard_scene_reference, param):
    """No NaN in the maps; the floor's shadows match Cycles within 1 % at 1024."""
    ref = hard_scene_reference
    light = light_from_reference(ref)
    samples = samples_from_reference(ref)
    pipeline = ShadowPipeline(gl_backend)
    result = pipeline.render(light, ref.triangles.astype(np.float64), samples, ShadowSettings(param, 1024),
                             measure=Measure(keep_atlas=True))
    assert np.all(np.isfinite(result.atlas))
    ref_lit = metrics.reference_visibility(ref.shadowed, ref.unshadowed)
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
    floor = evaluable & (np.abs(ref.position[..., 2]) < 1e-3)
    assert floor.sum() > 10_000 and (~ref_lit[floor]).sum() > 500  # real shadows on the floor
    on_floor = metrics.error_figure(result.visibility > 0.5, ref_lit, floor)
    overall = metrics.error_figure(result.visibility > 0.5, ref_lit, evaluable)
    assert on_floor.error_pct < 1.0, on_floor
    assert overall.error_pct < 1.0, overall

    with_fan = pipeline.render(light, np.concatenate([ref.triangles.astype(np.float64), FAN]), samples,
                               ShadowSettings(param, 1024), measure=Measure(keep_atlas=True))
    assert np.all(np.isfinite(with_fan.atlas))
    assert with_fan.geometry.skipped_triangles == result.geometry.skipped_triangles + 1
    assert np.array_equal(with_fan.visibility, result.visibility)
