"""The shadow rule against Cycles, case by case, on the feature scene (tests/support/feature_scene.py).

The Cycles references of three lights are compared with exact numpy ray casting
against the triangles the rule keeps. Each case is then "ignored" in turn (a
triangle group added, removed or swapped for the viewport's reading), and the
ray-cast visibility must move away from Cycles by a clear number of pixels: so
the scene really tests every case, and the rule really follows each one.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("bpy", reason="the feature scene needs bpy")

from addon.core import metrics  # noqa: E402
from addon.core.scene import LightSpec  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from tests.support.cli_run import python_ok  # noqa: E402
from tests.support.oracle import ray_hits  # noqa: E402

pytestmark = pytest.mark.blender

SUPPORT = Path(__file__).resolve().parents[1] / "support"
REPO = Path(__file__).resolve().parents[2]
SIZE = "240x180"
# A case that is ignored must change at least this many evaluated pixels.
MIN_PIXELS = 12
# The rule's own disagreement with Cycles: grazing pixels along shadow edges only.
MAX_RULE_MISMATCH_PCT = 0.3


@pytest.fixture(scope="module")
def feature(tmp_path_factory):
    folder = tmp_path_factory.mktemp("features")
    blend = folder / "features.blend"
    python_ok(SUPPORT / "feature_scene.py", blend, "--size", SIZE, timeout=600)
    python_ok(SUPPORT / "feature_capture.py", blend, folder, timeout=600)
    listing = json.loads((folder / "readings.json").read_text())
    arrays = np.load(folder / "readings.npz")
    readings = {kind: [((name, parent), arrays[f"{kind}_{i}"].astype(np.float64))
                       for i, (name, parent) in enumerate(listing[kind])] for kind in ("render", "viewport", "raw")}
    refs = {light: ReferenceData.load(folder / f"ref_{light}.npz") for light in ("LampA", "LampB", "LampC")}
    oracles = {light: Oracle(ref) for light, ref in refs.items()}
    return {"readings": readings, "listing": listing, "refs": refs, "blend": blend, "oracles": oracles}


class Oracle:
    """Exact shadow rays of one reference, cached per triangle group."""

    def __init__(self, ref: ReferenceData) -> None:
        self.ref = ref
        self.light = LightSpec(ref.emission, ref.light_matrix, spot_size=ref.spot_size)
        self.evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, self.light)
        self.cycles_lit = metrics.reference_visibility(ref.shadowed, ref.unshadowed)
        points = ref.position[self.evaluable].astype(np.float64)
        normals = ref.normal[self.evaluable].astype(np.float64)
        self.origins = points + 1e-4 * normals  # off the receiver, as Cycles offsets its shadow rays
        to_light = self.light.position - self.origins
        self.distance = np.linalg.norm(to_light, axis=1)
        self.dirs = to_light / self.distance[:, None]
        self._lo = np.minimum(self.origins, self.light.position)
        self._hi = np.maximum(self.origins, self.light.position)
        self._cache: dict[int, np.ndarray] = {}  # id of a group's array -> its blocked pixels

    def blocked(self, tris: np.ndarray) -> np.ndarray:
        """Evaluable pixels whose segment to the light crosses one of `tris`."""
        cached = self._cache.get(id(tris))
        if cached is None:
            cached = self._cache[id(tris)] = self._cast(tris)
        return cached

    def _cast(self, tris: np.ndarray) -> np.ndarray:
        out = np.zeros(len(self.origins), dtype=bool)
        if not len(tris):
            return out
        lo, hi = tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)
        near = np.all((self._hi >= lo) & (self._lo <= hi), axis=1)  # segment box meets the group's box
        if near.any():
            t, _ = ray_hits(self.origins[near], self.dirs[near], tris, t_max=self.distance[near] * (1 - 1e-6))
            out[near] = np.isfinite(t)
        return out

    def mismatch(self, groups: list[np.ndarray]) -> int:
        blocked = np.zeros(len(self.origins), dtype=bool)
        for tris in groups:
            blocked |= self.blocked(tris)
        return int(np.count_nonzero(~blocked != self.cycles_lit[self.evaluable]))


def _groups(readings, kind: str, keep) -> list[np.ndarray]:
    return [tris for owner, tris in readings[kind] if keep(*owner)]


def _pick(readings, kind: str, name: str, parent=None) -> list[np.ndarray]:
    found = [tris for (n, p), tris in readings[kind] if n == name and (parent is None or p == parent)]
    assert found, f"{name} (under {parent}) is not in the {kind} reading"
    return found


def _rule_groups(feature, light: str) -> list[np.ndarray]:
    blocks = feature["listing"]["blocks"][light]
    return [tris for (owner, tris), keep in zip(feature["readings"]["render"], blocks) if keep]


@pytest.mark.slow
def test_the_rule_keeps_what_the_reference_stores(feature):
    """The capture's triangles are exactly the render reading filtered by the rule."""
    for light in ("LampA", "LampB", "LampC"):
        kept = _rule_groups(feature, light)
        expected = sum(len(t) for t in kept)
        assert len(feature["refs"][light].triangles) == expected, light


@pytest.mark.slow
def test_lamp_a_matches_cycles(feature):
    oracle = feature["oracles"]["LampA"]
    assert oracle.evaluable.sum() > 10_000
    mismatch = oracle.mismatch(_rule_groups(feature, "LampA"))
    assert 100.0 * mismatch / oracle.evaluable.sum() <= MAX_RULE_MISMATCH_PCT, mismatch


# (case, how a reading that ignores it differs): add or remove triangle groups.
CASES_A = {
    "visible_shadow off": ("add", "render", "no_shadow_box", None),
    "render-only modifier": ("swap", "viewport", "array_post", None),
    "hide_render": ("add", "viewport", "render_hidden", None),
    "hidden in viewport, rendered": ("remove", "render", "viewport_hidden", None),
    "excluded collection": ("add", "raw", "excluded_box", None),
    "collection hide_render": ("add", "viewport", "render_off_box", None),
    "holdout collection casts": ("remove", "render", "holdout_box", None),
    "indirect-only collection casts": ("remove", "render", "indirect_box", None),
    "bevelled curve": ("remove", "render", "tube", "tube"),
    "text": ("remove", "render", "label", "label"),
    "metaball": ("remove", "render", "blob", "blob"),
    "geometry-nodes instances": ("remove", "render", "scatter", "scatter"),
    "particle instances": ("remove", "render", "sprite", "emitter"),
    "emitter not rendered": ("add", "raw", "emitter", None),
    "collection instance": ("remove", "render", "prop_box", "props_a"),
    "instancer visible_shadow off": ("add", "render", "prop_box", "props_b"),
    "hide_render inside an instanced collection": ("add", "viewport", "prop_hidden", "props_a"),
    "a nested instancer's visible_shadow is ignored": ("remove", "render", "prop_box", "nest"),
    "shadow linking EXCLUDE": ("add", "render", "a_excluded", None),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES_A))
def test_each_case_matters_for_lamp_a(feature, case):
    """Ignoring one case moves the ray-cast shadows away from Cycles."""
    action, kind, name, parent = CASES_A[case]
    oracle = feature["oracles"]["LampA"]
    readings = feature["readings"]
    kept = [(owner, tris) for (owner, tris), keep in zip(readings["render"], feature["listing"]["blocks"]["LampA"])
            if keep]
    base = oracle.mismatch([tris for _, tris in kept])
    if action == "add":
        groups = [tris for _, tris in kept] + _pick(readings, kind, name, parent)
    else:
        groups = [tris for (n, p), tris in kept if not (n == name and (parent is None or p == parent))]
        if action == "swap":
            groups += _pick(readings, kind, name, parent)
    ignored = oracle.mismatch(groups)
    assert ignored >= base + MIN_PIXELS, f"{case}: {base} -> {ignored} mismatched pixels of {oracle.evaluable.sum()}"


@pytest.mark.slow
def test_lamp_b_follows_nested_include_linking(feature):
    """Only the pillar (in a nested, included collection) blocks LampB; ignoring the link shadows far more."""
    oracle = feature["oracles"]["LampB"]
    readings = feature["readings"]
    rule = _rule_groups(feature, "LampB")
    assert sum(len(t) for t in rule) == sum(len(t) for t in _pick(readings, "render", "pillar"))
    base = oracle.mismatch(rule)
    assert 100.0 * base / oracle.evaluable.sum() <= MAX_RULE_MISMATCH_PCT
    unlinked = _rule_groups(feature, "LampA") + _pick(readings, "render", "a_excluded")
    assert oracle.mismatch(unlinked) >= base + 10 * MIN_PIXELS
    assert oracle.mismatch([]) >= base + MIN_PIXELS  # and the pillar does block it


@pytest.mark.slow
def test_lamp_b_receivers_exclude_the_slab(feature):
    """Light linking: Cycles gives the excluded slab no LampB light, so it is never evaluated."""
    ref_a, ref_b = feature["refs"]["LampA"], feature["refs"]["LampB"]
    assert feature["listing"]["lights"]["LampB"] == {"slab": False, "ground": True}
    assert feature["listing"]["lights"]["LampA"] == {"slab": True, "ground": True}
    pos = ref_a.position
    on_slab = ref_a.hit & (np.abs(pos[..., 2] - 0.1) < 1e-3) & (np.abs(pos[..., 0] - 1.0) < 0.75) \
        & (np.abs(pos[..., 1] + 3.2) < 0.55)
    assert on_slab.sum() > 50
    assert np.all(ref_b.unshadowed[on_slab] == 0.0)
    assert np.all(ref_a.unshadowed[on_slab] > 0.0)
    light_b = LightSpec(ref_b.emission, ref_b.light_matrix, spot_size=ref_b.spot_size)
    evaluable = metrics.evaluable_mask(ref_b.position, ref_b.normal, ref_b.hit, ref_b.unshadowed, light_b)
    assert not evaluable[on_slab].any()


@pytest.mark.slow
def test_camera_sees_through_indirect_only_objects(feature):
    """Cycles' camera rays pass through the indirect-only box (it still casts, above); `seen` agrees."""
    seen = dict(zip((tuple(o) for o in feature["listing"]["render"]), feature["listing"]["seen"]))
    assert seen[("indirect_box", None)] is False
    assert seen[("no_shadow_box", None)] is True and seen[("ground", None)] is True
    ref = feature["refs"]["LampA"]
    boxes = {name: tris for (name, _), tris in feature["readings"]["render"]}

    def hits_on(name: str) -> int:
        lo, hi = boxes[name].reshape(-1, 3).min(axis=0) - 1e-4, boxes[name].reshape(-1, 3).max(axis=0) + 1e-4
        inside = np.all((ref.position >= lo) & (ref.position <= hi), axis=-1) & ref.hit
        return int(inside.sum())

    assert hits_on("indirect_box") == 0
    assert hits_on("no_shadow_box") > 50


@pytest.mark.slow
def test_the_reference_names_what_the_rule_cannot_follow(feature):
    """The slab is a shadow catcher: captured as a plain surface, and said so in the notes."""
    for light in ("LampA", "LampB", "LampC"):
        notes = feature["refs"][light].meta["notes"]
        assert notes == ["shadow catcher rendered as a plain surface: slab"], notes


@pytest.mark.slow
def test_lamp_c_without_shadows_has_no_occluders(feature):
    ref = feature["refs"]["LampC"]
    assert len(ref.triangles) == 0 and ref.meta["light_casts_shadows"] is False
    light = LightSpec(ref.emission, ref.light_matrix)
    evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
    assert metrics.reference_visibility(ref.shadowed, ref.unshadowed)[evaluable].all()


@pytest.mark.slow
def test_reference_pixels_lie_on_their_pinhole_rays(feature):
    """The camera has a strong depth of field and pixels 1.2 times wider than tall, at 50 %:
    every hit still projects back, through the stored camera, to its own pixel centre."""
    ref = feature["refs"]["LampA"]
    assert ref.resolution == (240, 180)
    rows, cols = np.nonzero(ref.hit)
    pixel = ref.camera().pixel_of(ref.position[rows, cols].astype(np.float64))
    assert np.abs(pixel[:, 0] - (cols + 0.5)).max() < 0.05
    assert np.abs(pixel[:, 1] - (rows + 0.5)).max() < 0.05


@pytest.mark.slow
def test_light_under_a_scaled_empty(feature):
    """LampA sits at local (0, 0, 1) under an empty at z = 2 scaled by 2: world z = 4, matrix without scale."""
    ref = feature["refs"]["LampA"]
    np.testing.assert_allclose(ref.light_position, [0.0, 0.0, 4.0], atol=1e-6)
    np.testing.assert_allclose(ref.light_matrix[:3, :3] @ ref.light_matrix[:3, :3].T, np.eye(3), atol=1e-9)


# ----------------------------------------------------------------------------
# the linking semantics and the notes, on scenes built in this process
# ----------------------------------------------------------------------------
def test_link_set_admits_as_the_manual_says():
    """Only includes: those; only excludes: all but those; both: the included (an object's own state wins)."""
    from addon.readers.shadow_rule import EXCLUDE, INCLUDE, LinkSet

    assert LinkSet().admits("anything")
    assert LinkSet({}, linked=True).admits("anything")  # an empty collection links nothing away
    only_in = LinkSet({"a": INCLUDE}, linked=True)
    assert only_in.admits("a") and not only_in.admits("b")
    only_out = LinkSet({"a": EXCLUDE}, linked=True)
    assert not only_out.admits("a") and only_out.admits("b")
    both = LinkSet({"a": INCLUDE, "b": EXCLUDE}, linked=True)
    assert both.admits("a") and not both.admits("b") and not both.admits("c")


@pytest.fixture
def scratch_scene():
    import bpy

    scene = bpy.data.scenes.new("omniwarp rule scratch")
    made: list = []

    def obj(name: str, data=None):
        made.append(bpy.data.objects.new(name, data))
        scene.collection.objects.link(made[-1])
        return made[-1]

    yield scene, obj, made
    bpy.data.scenes.remove(scene)
    for item in made:
        bpy.data.objects.remove(item)


def test_collection_states_walk_children_first_and_later_entries_win(scratch_scene):
    """The depsgraph's order: nested collections (with their top entry's state), then direct objects."""
    import bpy

    from addon.readers.shadow_rule import collection_states

    _scene, obj, made = scratch_scene
    a, b = obj("rule_a"), obj("rule_b")
    top = bpy.data.collections.new("rule top")
    inner = bpy.data.collections.new("rule inner")
    deeper = bpy.data.collections.new("rule deeper")
    try:
        top.children.link(inner)
        inner.children.link(deeper)
        deeper.objects.link(a)
        inner.objects.link(b)
        top.objects.link(a)  # also a direct entry: visited last, so its state wins
        top.collection_children[0].light_linking.link_state = "EXCLUDE"
        top.collection_objects[0].light_linking.link_state = "INCLUDE"
        # The nested entries' own states do not matter: the top-level entry's state reaches inside.
        inner.collection_objects[0].light_linking.link_state = "INCLUDE"
        assert collection_states(top) == {"rule_a": "INCLUDE", "rule_b": "EXCLUDE"}
    finally:
        for coll in (deeper, inner, top):
            bpy.data.collections.remove(coll)


def test_instances_take_the_instancers_linking_only_when_it_has_one(scratch_scene):
    """Cycles: an instance's blocker set is its instancer's when the instancer is in a blocker collection."""
    import bpy

    from addon.readers.shadow_rule import ShadowRule

    scene, obj, made = scratch_scene
    lamp = obj("rule_lamp", bpy.data.lights.new("rule_lamp", "POINT"))
    source, instancer, other = obj("rule_source"), obj("rule_instancer"), obj("rule_other")
    blockers = bpy.data.collections.new("rule blockers")
    try:
        blockers.objects.link(source)
        lamp.light_linking.blocker_collection = blockers  # include only the source
        rule = ShadowRule.for_light(scene, lamp, notes=False)
        assert rule.blocks(source) and not rule.blocks(other)
        assert rule.blocks("rule_source", "rule_instancer")  # the instancer has no set: the source's counts
        blockers.objects.link(instancer)
        blockers.collection_objects[1].light_linking.link_state = "EXCLUDE"
        rule = ShadowRule.for_light(scene, lamp, notes=False)
        assert not rule.blocks("rule_source", "rule_instancer")  # now the instancer's set counts
        lamp.data.use_shadow = False
        assert not ShadowRule.for_light(scene, lamp, notes=False).blocks(source)
    finally:
        light = lamp.data
        made.remove(lamp)
        bpy.data.objects.remove(lamp)
        bpy.data.lights.remove(light)
        bpy.data.collections.remove(blockers)


def test_notes_name_what_the_rule_cannot_follow(scratch_scene):
    """A shadow catcher and a glass material each get one note; a plain scene none. Hair is
    not the rule's: the render geometry's walk names it (readers/left_out.py,
    tests/blender/test_left_out.py)."""
    import bpy

    from addon.readers.shadow_rule import unfollowed

    scene, obj, made = scratch_scene
    assert unfollowed(scene) == []
    mesh = bpy.data.meshes.new("rule_glass_mesh")
    catcher = obj("rule_catcher", mesh)
    catcher.is_shadow_catcher = True
    glass = bpy.data.materials.new("rule glass")
    if glass.node_tree is None:  # node trees are opt-in before Blender 5.0
        glass.use_nodes = True
    glass.node_tree.nodes.new("ShaderNodeBsdfGlass")
    mesh.materials.append(glass)
    hair = obj("rule_hair", bpy.data.hair_curves.new("rule_hair"))
    try:
        notes = unfollowed(scene)
        assert len(notes) == 2, notes
        assert any("shadow catcher" in n and "rule_catcher" in n for n in notes)
        assert any("rule glass (a glass shader)" in n for n in notes)
    finally:
        made.remove(hair)
        bpy.data.objects.remove(hair)
        bpy.data.materials.remove(glass)
