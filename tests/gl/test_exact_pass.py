"""The irregular z-buffer pass (issue 19, in progress: ShadowSettings.exact, no method yet):
the view samples are linked into per-texel lists of the (warped) map, every triangle walks
the lists of the texels its footprint touches, and a sample is shadowed when a triangle
crosses its segment to the light. That is the exact ray caster's answer, whatever the map's
resolution."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core.presets import build_preset
from addon.core.scene import CameraSpec, LightSpec, MeshSpec, SceneSpec, look_at
from addon.render.pipeline import ShadowPipeline, ShadowSettings
from addon.render.shaders import EXACT_MAX_WALK
from addon.render.frame import Measure
from tests.gl.test_izb_lists import _walk
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl

CASES = [("dpsm", "notw"), ("dpsm", "none"), ("cube", "notw"), ("cube", "none")]


PRESET_CASES = ["room_omni", "room_hemi", "courtyard", "stress_seam", "stress_light_inside_object",  # conftest
                "stress_grazing", "stress_scale_large", "stress_scale_small", "stress_vertex_at_light"]
PRESET_CASE_SIZE = (64, 48)


@pytest.mark.parametrize("param,warp", CASES)
def test_exact_pass_equals_the_ray_caster(gl_backend, preset_case, param, warp):
    name, scene, samples, exact, evaluable = preset_case
    pipe = ShadowPipeline(gl_backend)
    result = pipe.render(scene.light, scene.world_triangles(), samples,
                         ShadowSettings(param, 128, warp=warp, exact=True))
    wrong = ((result.visibility > 0.5) != (exact > 0.5))[evaluable]
    # A map of 128^2 texels errs at every shadow edge; the lists do not.
    assert wrong.sum() <= max(1, int(1e-3 * evaluable.sum())), (name, param, warp, int(wrong.sum()))
    assert result.exact_work["cut"] == 0


def test_the_map_resolution_does_not_matter(gl_backend):
    scene = build_preset("courtyard", (64, 48))
    samples, exact, evaluable = view_samples(scene)
    pipe = ShadowPipeline(gl_backend)
    shadowed = [(pipe.render(scene.light, scene.world_triangles(), samples,
                             ShadowSettings("dpsm", res, warp="notw", exact=True)).visibility < 0.5)[evaluable]
                for res in (64, 512)]
    assert np.array_equal(shadowed[0], shadowed[1]) and shadowed[0].any()


def test_a_list_past_the_walk_bound_is_finished_by_later_rounds(gl_backend):
    """stress_one_texel puts every sample in a texel or two: the first round stops at the
    bound (no hang), the later rounds walk the rest, and no sample is left untested: the
    pass equals the ray caster there too, and says what work it moved."""
    scene = build_preset("stress_one_texel", (96, 72))
    samples, exact, evaluable = view_samples(scene)
    assert samples.hit.sum() > EXACT_MAX_WALK
    pipe = ShadowPipeline(gl_backend)
    result = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("dpsm", 256, exact=True),
                         measure=Measure(count_work=True))
    work = result.exact_work
    assert work["cut"] > 0 and work["rounds"] >= 1 and work["moved"] > 0, work
    wrong = ((result.visibility > 0.5) != (exact > 0.5))[evaluable]
    assert wrong.sum() <= max(1, int(1e-3 * evaluable.sum())), int(wrong.sum())


@pytest.mark.parametrize("bound", [1, 2])
def test_rounds_walk_every_entry_once(gl_backend, monkeypatch, bound):
    """With a first bound of one or two entries every list takes several rounds; the marks,
    see-through optical depths included (summed, so an entry walked twice would show), are
    those of one round, and the entries walked are the same."""
    from addon.render.resident import ResidentScene
    from tests.gl.test_alpha_pass import _scene

    scene = _scene()
    samples, _, _ = view_samples(scene)
    pipe = ShadowPipeline(gl_backend)
    settings = ShadowSettings("dpsm", 128, warp="none", exact=True)  # plain: lists of up to ~10
    resident = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    once = pipe.render(scene.light, resident, samples, settings, measure=Measure(count_work=True))
    from addon.render.passes import exact as exact_pass
    monkeypatch.setattr(exact_pass, "EXACT_MAX_WALK", bound)  # the first round's bound (passes/exact.py)
    rounds = pipe.render(scene.light, resident, samples, settings, measure=Measure(count_work=True))
    assert once.exact_work["rounds"] == 0 and rounds.exact_work["rounds"] >= 2, rounds.exact_work
    assert np.array_equal(rounds.visibility, once.visibility)
    # A frame that does not wait draws its later rounds at its first read, with the same marks.
    deferred = pipe.render(scene.light, resident, samples, settings)
    assert deferred.pending and deferred.completer is not None
    assert np.array_equal(deferred.visibility, once.visibility)
    assert deferred.exact_work["rounds"] == rounds.exact_work["rounds"]
    gl_backend.release_scene(resident)
    assert rounds.exact_work["entries"] == once.exact_work["entries"] > rounds.exact_work["moved"] > 0


def test_exact_takes_only_footprint_parameterizations():
    from addon.core.errors import InputError

    with pytest.raises(InputError, match="exact"):
        ShadowSettings("unfold", 256, exact=True)


def test_work_counts_follow_the_lists(gl_backend):
    """A counting frame reports the triangle pass's work (every fragment, and the list entries
    they walked); a walk stops at its list's end, so the entries are at most the fragments
    times the longest list. Timed frames count nothing, and counting changes no shadow."""
    scene = build_preset("room_omni", (64, 48))
    samples, _, _ = view_samples(scene)
    pipe = ShadowPipeline(gl_backend)
    settings = ShadowSettings("dpsm", 128, warp="notw", exact=True)
    plain = pipe.render(scene.light, scene.world_triangles(), samples, settings)
    assert plain.exact_work["entries"] == plain.exact_work["fragments"] == 0  # not counted when timed
    counted = pipe.render(scene.light, scene.world_triangles(), samples, settings, measure=Measure(count_work=True))
    assert np.array_equal(counted.visibility, plain.visibility)
    work = counted.exact_work
    lengths, _ = _walk(*gl_backend.read_links())
    assert work["fragments"] > 0 and 0 < work["entries"] <= work["fragments"] * int(lengths.max())
    assert work["cut"] == 0


def random_blockers(rng: np.random.Generator) -> list[MeshSpec]:
    """A floor, a back wall and 20-60 random triangles of several sizes over the floor."""
    quad = np.array([[-6.0, -6.0, 0.0], [6.0, -6.0, 0.0], [6.0, 6.0, 0.0], [-6.0, 6.0, 0.0]])
    wall = quad[:, [0, 2, 1]] + np.array([0.0, 6.0, 6.0])
    meshes = [MeshSpec("floor", quad, np.array([[0, 1, 2], [0, 2, 3]])),
              MeshSpec("wall", wall, np.array([[0, 1, 2], [0, 2, 3]]))]
    count = int(rng.integers(20, 60))
    centres = rng.uniform([-4.0, -4.0, 0.3], [4.0, 4.0, 4.0], (count, 3))
    corners = centres[:, None, :] + rng.normal(size=(count, 3, 3)) * rng.uniform(0.05, 1.0, (count, 1, 1))
    meshes.append(MeshSpec("blockers", corners.reshape(-1, 3), np.arange(3 * count).reshape(-1, 3)))
    return meshes


def random_scene(seed: int) -> SceneSpec:
    """Random blockers (random_blockers) around an omni or hemi light, seen by a camera
    from outside (the light in view or not)."""
    rng = np.random.default_rng(seed)
    meshes = random_blockers(rng)
    light = np.eye(4)
    light[:3, 3] = rng.uniform([-2.0, -2.0, 3.0], [2.0, 2.0, 6.0])
    eye, target = rng.uniform([-9.0, -12.0, 3.0], [9.0, -7.0, 9.0]), rng.uniform([-2.0, -1.0, 0.0], [2.0, 3.0, 2.0])
    return SceneSpec(f"random{seed}", meshes, LightSpec("hemi" if seed % 2 else "omni", light),
                     CameraSpec(look_at(eye, target), 60.0, (48, 36)))


@pytest.mark.parametrize("seed", range(6))
def test_exact_pass_equals_the_ray_caster_on_random_scenes(gl_backend, seed):
    scene = random_scene(seed)
    samples, exact, evaluable = view_samples(scene)
    pipe = ShadowPipeline(gl_backend)
    for param, warp in (("dpsm", "notw"), ("cube", "none")):
        result = pipe.render(scene.light, scene.world_triangles(), samples,
                             ShadowSettings(param, 128, warp=warp, exact=True))
        wrong = ((result.visibility > 0.5) != (exact > 0.5))[evaluable]
        assert wrong.sum() <= max(1, int(1e-3 * evaluable.sum())), (seed, param, int(wrong.sum()))
    assert (exact[evaluable] < 0.5).any() and (exact[evaluable] > 0.5).any()  # shadow and light to get right


def slab_scene(twice: bool, emission: str = "omni", patch: bool = False) -> SceneSpec:
    """A floor and a square slab over it, the slab's top face laid down once or twice (as a
    Mirror modifier lays a copy onto the original; the twin's triangles list their corners
    in another order), with `patch` a face of other corners over part of it, under a light
    above (a spot's or sun's axis, its local -Z, down), seen from above."""
    quad = np.array([[-6.0, -6.0, 0.0], [6.0, -6.0, 0.0], [6.0, 6.0, 0.0], [-6.0, 6.0, 0.0]])
    top = np.array([[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    meshes = [MeshSpec("floor", quad, faces), MeshSpec("slab", top, faces)]
    if twice:
        meshes.append(MeshSpec("slab_twin", top, np.array([[1, 2, 0], [2, 3, 0]])))  # the same, other corners first
    if patch:
        # Over x > 0.2 and past the slab, a coplanar face of other corners (booleans leave such).
        half = np.array([[0.2, -1.5, 1.0], [1.5, -1.5, 1.0], [1.5, 1.5, 1.0], [0.2, 1.5, 1.0]])
        meshes.append(MeshSpec("patch", half, faces))
    light = np.eye(4)
    light[:3, 3] = (0.3, 0.2, 5.0)
    if emission == "spot":
        spec = LightSpec(emission, light, spot_size=np.radians(90.0))
    else:
        spec = LightSpec(emission, light)
    return SceneSpec("slab", meshes, spec, CameraSpec(look_at(np.array([0.5, -6.0, 7.0]), np.zeros(3)), 50.0, (48, 36)))


@pytest.mark.parametrize("emission", ["omni", "spot", "sun"])
def test_a_face_laid_twice_shadows_itself_as_in_cycles(gl_backend, emission):
    # Cycles' shadow ray skips only the primitive it leaves from: the twin face blocks it.
    pipe = ShadowPipeline(gl_backend)
    seen = {}
    for twice in (False, True):
        scene = slab_scene(twice, emission)
        samples, exact, evaluable = view_samples(scene)
        at = samples.positions
        on_top = evaluable & (np.abs(at[..., 2] - 1.0) < 1e-4) & (np.abs(at[..., :2]).max(axis=-1) < 0.98)
        param = "dpsm" if emission == "omni" else "sm"
        result = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings(param, 128, exact=True))
        seen[twice] = result.visibility[on_top]
        assert on_top.sum() > 20 and (exact[on_top] > 0.5).all()  # the oracle skips both: lit
    assert (seen[False] > 0.5).all() and (seen[True] < 0.5).all()


def test_a_face_partly_over_another_shadows_where_they_overlap(gl_backend):
    pipe = ShadowPipeline(gl_backend)
    scene = slab_scene(False, patch=True)
    samples, exact, evaluable = view_samples(scene)
    at = samples.positions
    top = evaluable & (np.abs(at[..., 2] - 1.0) < 1e-4)
    inside = np.abs(at[..., :2]).max(axis=-1) < 0.98
    both = top & inside & (at[..., 0] > 0.25)  # the slab and the patch
    one = top & ((inside & (at[..., 0] < 0.15)) | (np.abs(at[..., :2]).max(axis=-1) > 1.02))  # one face
    vis = pipe.render(scene.light, scene.world_triangles(), samples, ShadowSettings("dpsm", 128, exact=True)).visibility
    assert both.sum() > 10 and one.sum() > 10
    assert (vis[both] < 0.5).all() and (vis[one] > 0.5).all()
