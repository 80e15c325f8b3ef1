"""The reference renders volumes as Cycles does (issue 43).

A fog box by a figure (tests/support/make_fog_blend.py) keeps its volume shader in the
reference for shadow rays alone (reference_materials.shadow_only), so each pixel's
visibility is the fog's transmittance along its segment to the light, measured in two
halves; its hit pixels' mean visibility is that of a plain Cycles render of the file with
its own materials (tests/support/plain_cycles.py). On every variant of the box (beside
the figure, around it and below the ground, around the light, coloured absorption, a
tinted Principled Volume, scatter + absorption mixed with Volume Coefficients) the
reference's visibility on the ground and the figure is core.media's oracle, run on the
triangles and media the reference stores; `material_medium` reads each node kind's
extinction, and says why it does not follow the others.
"""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy", reason="the reference needs bpy")

from addon.core import media, metrics  # noqa: E402
from addon.reference.data import ReferenceData  # noqa: E402
from addon.readers.material_media import material_medium  # noqa: E402
from addon.compat import blender as blender_compat  # noqa: E402
from tests.support.cli_run import SUPPORT, compared, python_ok  # noqa: E402
from tests.support.plain_cycles import mean_visibilities  # noqa: E402
from tests.support.make_fog_blend import VARIANTS, behind_figure, transmittance  # noqa: E402

pytestmark = pytest.mark.blender


@pytest.fixture(scope="module")
def fog(tmp_path_factory):
    """(reference, rows, the file, its folder)."""
    folder = tmp_path_factory.mktemp("fog")
    blend = folder / "fog.blend"
    python_ok(SUPPORT / "make_fog_blend.py", blend)
    path, rows = compared(blend, folder, "dpsm")
    return ReferenceData.load(path), rows, blend, folder


def test_the_fog_lets_its_transmittance_through(fog):
    ref, rows, _, _ = fog
    ratio = metrics.reference_ratio(ref.shadowed, ref.unshadowed)
    ground = ref.hit & (np.abs(ref.position[..., 2]) < 1e-3) & ~behind_figure(ref.position)
    expected = transmittance(ref.position)
    under = ground & (expected < 0.99)
    # The camera sees through the fog: every pixel hits the ground or the figure.
    assert ref.hit.mean() > 0.99 and under.sum() > 1000
    error = np.abs(ratio - expected)[ground]
    assert error.mean() < 1e-3 and error.max() < 0.05, (error.mean(), error.max())
    assert 0.2 < float(expected[under].mean()) < 0.8  # partly shadowed, not white or clear
    # Measured in two halves, as a sized light: a homogeneous medium's shadow is exact.
    assert ref.visibility_noise is not None and float(ref.visibility_noise[ground].mean()) < 1e-3
    assert ref.meta["samples"] > 1
    # The box's triangles carry its medium, so it is drawn, and no row calls it left out.
    surface = ref.scene_surface()
    assert [m.name for m in surface.media] == ["Fog"] and np.allclose(surface.media[0].sigma, 1.5)
    assert int((surface.medium == 0).sum()) == 12 and int((surface.medium == -1).sum()) == len(surface.medium) - 12
    assert "volume materials" not in rows[0].get("note", "") and not ref.meta["left_out"]


def test_the_reference_matches_a_plain_render(fog):
    """Within 1 point of the plain render's mean visibility over the pixels both hit (its
    camera rays cross the fog, so some of its pixels end there and are left out)."""
    ref, _, blend, folder = fog
    ours, theirs, share = mean_visibilities(ref, blend, folder / "plain.npz")
    assert share > 0.8 and abs(ours - theirs) < 0.01, (ours, theirs, share)


def test_a_file_without_media_loads_without_them(fog, tmp_path):
    ref, _, _, folder = fog
    (path,) = (folder / "cache").glob("*.npz")
    with np.load(path) as npz:
        kept = {k: npz[k] for k in npz.files if k not in ("medium", "media_sigma")}
    np.savez(tmp_path / "old.npz", **kept)
    surface = ReferenceData.load(tmp_path / "old.npz").scene_surface()
    assert not surface.has_media and surface.media == () and len(surface.medium) == len(ref.triangles)


# ---------------------------------------------------------------------------
# every variant against core.media's oracle
# ---------------------------------------------------------------------------
# Where the receivers lie inside the fog: the ground and the figure (around), the light (light_inside).
_INSIDE = {"around", "tinted", "light_inside"}


@pytest.fixture(scope="module", params=sorted(VARIANTS))
def variant(request, tmp_path_factory):
    """(name, its reference)."""
    if request.param == "scatter_add" and not hasattr(bpy.types, "ShaderNodeVolumeCoefficients"):
        pytest.skip("this Blender line has no Volume Coefficients node (4.5 on): the variant mixes one in")
    folder = tmp_path_factory.mktemp(request.param)
    python_ok(SUPPORT / "make_fog_blend.py", folder / "fog.blend", "--variant", request.param,
              "--reference", folder / "ref.npz")
    return request.param, ReferenceData.load(folder / "ref.npz")


def _silhouettes(ref: ReferenceData) -> np.ndarray:
    """(H, W) the pixels whose 8 neighbours do not all lie on their own plane with their normal."""
    pad = lambda a: np.pad(a, [(1, 1), (1, 1)] + [(0, 0)] * (a.ndim - 2), mode="edge")  # noqa: E731
    position, normal = pad(ref.position.astype(np.float64)), pad(ref.normal.astype(np.float64))
    hit = pad(ref.hit)
    height, width = ref.hit.shape
    out = np.zeros((height, width), dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near = (slice(1 + dy, 1 + dy + height), slice(1 + dx, 1 + dx + width))
            off = np.abs(np.einsum("ijk,ijk->ij", ref.normal, position[near] - ref.position)) > 1e-3
            turned = np.linalg.norm(normal[near] - ref.normal, axis=-1) > 1e-3
            out |= off | turned | (hit[near] != ref.hit)
    return out


def test_each_variant_is_the_oracle(variant):
    name, ref = variant
    spec = VARIANTS[name]
    surface = ref.scene_surface()
    assert len(surface.media) == 1 and not ref.meta["left_out"]
    ratio = metrics.reference_ratio(ref.shadowed, ref.unshadowed)
    lit = ref.lit_domain()
    depths = media.optical_depths(ref.light_position, ref.position[lit], ref.triangles, surface.medium,
                                  surface.media)
    oracle = np.ones(ratio.shape)
    oracle[lit] = media.visibility(depths)
    # The figure's own shadow is not the fog's; a silhouette pixel's 128 samples a half
    # spread over the pixel, across two surfaces, while its position is the centre's.
    free = lit & ~behind_figure(ref.position, np.array(spec.light)) & ~_silhouettes(ref)
    assert (lit & _silhouettes(ref)).sum() < 0.02 * lit.sum()
    ground = free & (np.abs(ref.position[..., 2]) < 1e-3)
    figure = free & ~ground
    for pixels in (ground, figure):
        error = np.abs(ratio - oracle)[pixels]
        assert pixels.sum() > 50 and error.mean() < 1e-3 and error.max() < 0.05, (name, error.mean(), error.max())
    under = free & (oracle < 0.99)
    assert under.sum() > 1000 and 0.2 < float(oracle[under].mean()) < 0.95
    if name in _INSIDE:  # the figure stands in the fog, or the light does: its pixels are attenuated
        assert float(oracle[figure].mean()) < 0.9
    sigma = surface.media[0].sigma
    assert (np.ptp(sigma) > 0.3) == (name in ("absorption", "tinted", "scatter_add"))  # coloured


# ---------------------------------------------------------------------------
# material_medium, node by node
# ---------------------------------------------------------------------------
class Scratch:
    """Makes volume materials, and removes them at the end."""

    def __init__(self) -> None:
        self.made: list = []

    def material(self, name: str = "Medium"):
        """(material, tree, its output), no nodes but the output."""
        mat = bpy.data.materials.new(name)
        self.made.append((bpy.data.materials, mat))
        tree = blender_compat.ensure_node_tree(mat)
        tree.nodes.clear()
        return mat, tree, tree.nodes.new("ShaderNodeOutputMaterial")

    def node(self, tree, idname: str, **inputs):
        node = tree.nodes.new(idname)
        for key, value in inputs.items():
            node.inputs[key.replace("_", " ")].default_value = value
        return node

    def medium(self, idname: str, **inputs):
        """A material of one volume node on Volume; (material, node)."""
        mat, tree, out = self.material()
        node = self.node(tree, idname, **inputs)
        tree.links.new(node.outputs[0], out.inputs["Volume"])
        return mat, node

    def remove(self) -> None:
        for collection, block in reversed(self.made):
            collection.remove(block)


@pytest.fixture
def scratch():
    made = Scratch()
    yield made
    made.remove()


def _sigma(material) -> np.ndarray:
    found, note = material_medium(material)
    assert note is None and found is not None, note
    assert found.name == material.name
    return found.sigma


def test_principled_volume(scratch):
    color, absorption = np.array([0.9, 0.5, 0.1]), np.array([0.3, 0.7, 0.2])
    mat, _ = scratch.medium("ShaderNodeVolumePrincipled", Density=1.2, Color=(*color, 1.0),
                           Absorption_Color=(*absorption, 1.0))
    expected = 1.2 * (color + (1.0 - color) * (1.0 - np.sqrt(absorption)))
    assert np.allclose(_sigma(mat), expected, atol=1e-6)
    mat, _ = scratch.medium("ShaderNodeVolumePrincipled", Density=1.5)  # grey 0.5, black absorption: 1.5
    assert np.allclose(_sigma(mat), 1.5, atol=1e-6)
    mat, _ = scratch.medium("ShaderNodeVolumePrincipled", Density=-2.0)  # no density: clear
    found, _ = material_medium(mat)
    assert found is not None and found.clear


def test_absorption_scatter_and_coefficients(scratch):
    mat, _ = scratch.medium("ShaderNodeVolumeAbsorption", Density=2.0, Color=(0.2, 0.6, 0.9, 1.0))
    assert np.allclose(_sigma(mat), 2.0 * np.array([0.8, 0.4, 0.1]), atol=1e-6)
    mat, _ = scratch.medium("ShaderNodeVolumeScatter", Density=3.0, Color=(0.2, 0.6, 0.9, 1.0))
    assert np.allclose(_sigma(mat), 3.0 * np.array([0.2, 0.6, 0.9]), atol=1e-6)
    if hasattr(bpy.types, "ShaderNodeVolumeCoefficients"):  # 4.5 on
        mat, _ = scratch.medium("ShaderNodeVolumeCoefficients", Absorption_Coefficients=(0.4, 1.0, 2.0),
                                Scatter_Coefficients=(0.5, 0.2, 0.1))
        assert np.allclose(_sigma(mat), [0.9, 1.2, 2.1], atol=1e-6)


def test_add_and_mix_shaders_reroutes_and_math(scratch):
    mat, tree, out = scratch.material()
    scatter = scratch.node(tree, "ShaderNodeVolumeScatter", Density=1.0, Color=(0.8, 0.3, 0.5, 1.0))
    absorb = scratch.node(tree, "ShaderNodeVolumeAbsorption", Color=(0.5, 0.9, 0.4, 1.0))
    value = scratch.node(tree, "ShaderNodeValue")
    value.outputs[0].default_value = 0.5
    times = scratch.node(tree, "ShaderNodeMath")
    times.operation, times.inputs[1].default_value = "MULTIPLY", 3.0
    tree.links.new(value.outputs[0], times.inputs[0])
    tree.links.new(times.outputs[0], absorb.inputs["Density"])  # 1.5, from constants
    add = scratch.node(tree, "ShaderNodeAddShader")
    tree.links.new(scatter.outputs[0], add.inputs[0])
    tree.links.new(absorb.outputs[0], add.inputs[1])
    mix = scratch.node(tree, "ShaderNodeMixShader", Fac=0.25)
    reroute = tree.nodes.new("NodeReroute")
    tree.links.new(add.outputs[0], reroute.inputs[0])
    tree.links.new(reroute.outputs[0], mix.inputs[1])  # the second shader left empty: nothing
    tree.links.new(mix.outputs[0], out.inputs["Volume"])
    added = np.array([0.8, 0.3, 0.5]) + 1.5 * np.array([0.5, 0.1, 0.6])
    assert np.allclose(_sigma(mat), 0.75 * added, atol=1e-6)
    mix.inputs[0].default_value = 1.5  # Cycles clamps the factor: all of the empty shader
    assert np.allclose(_sigma(mat), 0.0)


def test_a_node_group_is_followed_inside(scratch):
    group = bpy.data.node_groups.new("Haze", "ShaderNodeTree")
    scratch.made.append((bpy.data.node_groups, group))
    group.interface.new_socket("Density", in_out="INPUT", socket_type="NodeSocketFloat")
    group.interface.new_socket("Volume", in_out="OUTPUT", socket_type="NodeSocketShader")
    inside = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    absorb = group.nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value = (0.5, 0.0, 1.0, 1.0)
    group.links.new(inside[0].outputs[0], absorb.inputs["Density"])
    group.links.new(absorb.outputs[0], inside[1].inputs[0])
    mat, tree, out = scratch.material()
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.inputs[0].default_value = 2.0
    tree.links.new(node.outputs[0], out.inputs["Volume"])
    assert np.allclose(_sigma(mat), [1.0, 2.0, 0.0], atol=1e-6)


def test_what_is_not_followed_says_why(scratch):
    mat, node = scratch.medium("ShaderNodeVolumePrincipled")
    noise = node.id_data.nodes.new("ShaderNodeTexNoise")
    times = node.id_data.nodes.new("ShaderNodeMath")
    node.id_data.links.new(noise.outputs["Fac"], times.inputs[0])
    node.id_data.links.new(times.outputs[0], node.inputs["Density"])
    assert material_medium(mat) == (None, "density varies in space (heterogeneous): not followed")
    mat, node = scratch.medium("ShaderNodeVolumeAbsorption")
    path = node.id_data.nodes.new("ShaderNodeLightPath")
    node.id_data.links.new(path.outputs["Ray Length"], node.inputs["Density"])
    assert material_medium(mat) == (None, "density from a light path: not followed")
    mat, node = scratch.medium("ShaderNodeEmission")
    found, why = material_medium(mat)
    assert found is None and why == "an unknown volume shader (emission): not followed"
    # Cycles' extinction would be negative (a colour above 1): not followed.
    mat, _ = scratch.medium("ShaderNodeVolumeAbsorption", Color=(0.0, 1.5, 0.5, 1.0))
    found, why = material_medium(mat)
    assert found is None and "negative" in why
    # Not a medium at all: a surface as well, or no volume.
    mat, node = scratch.medium("ShaderNodeVolumeScatter")
    surface = node.id_data.nodes.new("ShaderNodeBsdfDiffuse")
    node.id_data.links.new(surface.outputs[0], mat.node_tree.nodes["Material Output"].inputs["Surface"])
    assert material_medium(mat) == (None, None)
    assert material_medium(None) == (None, None)
