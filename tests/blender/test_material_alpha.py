"""addon.readers.material_alpha: a material's alpha for shadow rays, read from its nodes.

Each test builds its materials and images in-process and removes them after. Expected
alphas come from the pixels written here (read back once, for the 8-bit quantisation)
and the rules stated in the module, in numpy, not from the reader.
"""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from addon.core.alpha import TRANSFER_SIZE, luminance, srgb_to_linear  # noqa: E402
from addon.readers.material_alpha import material_alpha, mesh_surface, triangle_uvs  # noqa: E402
from addon.compat import blender as blender_compat  # noqa: E402

pytestmark = pytest.mark.blender

X = np.linspace(0.0, 1.0, TRANSFER_SIZE)


class Scratch:
    """Makes materials, images, meshes and objects, and removes them at the end."""

    def __init__(self) -> None:
        self.made: list[tuple[object, object]] = []

    def material(self, name: str):
        mat = bpy.data.materials.new(name)
        self.made.append((bpy.data.materials, mat))
        tree = blender_compat.ensure_node_tree(mat)
        return mat, tree, tree.nodes["Principled BSDF"]

    def image(self, name: str, rgba: np.ndarray, float_buffer: bool = False, colorspace: str | None = None):
        height, width = rgba.shape[:2]
        image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=float_buffer)
        self.made.append((bpy.data.images, image))
        if colorspace is not None:
            image.colorspace_settings.name = colorspace
        image.pixels.foreach_set(np.asarray(rgba, dtype=np.float32).ravel())
        return image

    def texture(self, tree, image, output: str, socket):
        node = tree.nodes.new("ShaderNodeTexImage")
        node.image = image
        tree.links.new(node.outputs[output], socket)
        return node

    def remove(self) -> None:
        for collection, block in reversed(self.made):
            collection.remove(block)


@pytest.fixture
def scratch():
    made = Scratch()
    yield made
    made.remove()


def pixels(image) -> np.ndarray:
    """What Blender stored (8-bit images quantise what was written)."""
    width, height = image.size
    return np.array(image.pixels[:], dtype=np.float64).reshape(height, width, 4)


def texel_centres(height: int, width: int) -> np.ndarray:
    u, v = (np.arange(width) + 0.5) / width, (np.arange(height) + 0.5) / height
    return np.stack(np.meshgrid(u, v), axis=-1)


RNG = np.random.default_rng(25)
RANDOM_RGBA = RNG.random((3, 5, 4))


def test_principled_alpha_from_image_alpha(scratch):
    """The map samples to the image's alpha channel at every texel centre, row 0 at v = 0."""
    mat, tree, bsdf = scratch.material("ma image alpha")
    image = scratch.image("ma alpha", RANDOM_RGBA)
    scratch.texture(tree, image, "Alpha", bsdf.inputs["Alpha"])
    got = material_alpha(mat)
    assert got.note is None and got.alpha is not None
    assert got.alpha.transfer is None  # no chain: the value itself
    assert got.alpha.image.shape == (3, 5)
    np.testing.assert_allclose(got.alpha.sample(texel_centres(3, 5)), pixels(image)[..., 3], atol=1e-6)
    assert got.uv_map == "" and np.array_equal(got.uv_matrix, [[1, 0, 0], [0, 1, 0]])


@pytest.mark.parametrize("colorspace", ["sRGB", "Non-Color"])
def test_color_output_is_luminance_of_the_linear_colour(scratch, colorspace):
    """An sRGB byte image is decoded before the luminance; a Non-Color one is read raw."""
    rgba = RANDOM_RGBA.copy()
    rgba[..., 3] = 1.0  # opaque texels: no association with alpha
    mat, tree, bsdf = scratch.material("ma colour")
    image = scratch.image("ma colour", rgba, colorspace=colorspace)
    scratch.texture(tree, image, "Color", bsdf.inputs["Alpha"])
    got = material_alpha(mat).alpha
    stored = pixels(image)[..., :3]
    want = luminance(srgb_to_linear(stored) if colorspace == "sRGB" else stored)
    np.testing.assert_allclose(got.image, want, atol=1e-6)
    assert not np.allclose(luminance(srgb_to_linear(stored)), luminance(stored), atol=1e-3)  # the case tells


def test_float_image_colour_is_already_linear(scratch):
    rgba = RANDOM_RGBA.copy()
    rgba[..., 3] = 1.0
    mat, tree, bsdf = scratch.material("ma float")
    image = scratch.image("ma float", rgba, float_buffer=True)
    scratch.texture(tree, image, "Color", bsdf.inputs["Alpha"])
    np.testing.assert_allclose(material_alpha(mat).alpha.image, luminance(rgba), atol=1e-6)


def test_straight_colour_is_premultiplied_unless_alpha_is_used(scratch):
    """Cycles associates colour with alpha; it unassociates only where the Alpha output is used."""
    rgba = RANDOM_RGBA.copy()
    rgba[..., 3] = 0.5
    mat, tree, bsdf = scratch.material("ma assoc")
    image = scratch.image("ma assoc", rgba, colorspace="Linear Rec.709")  # colour, not data: associated
    node = scratch.texture(tree, image, "Color", bsdf.inputs["Alpha"])
    stored = pixels(image)
    np.testing.assert_allclose(material_alpha(mat).alpha.image, luminance(stored[..., :3]) * stored[..., 3],
                               atol=1e-6)
    tree.links.new(node.outputs["Alpha"], tree.nodes.new("ShaderNodeMath").inputs[0])  # Alpha used elsewhere
    np.testing.assert_allclose(material_alpha(mat).alpha.image, luminance(stored[..., :3]), atol=1e-6)


def test_alpha_mode_none_is_opaque(scratch):
    mat, tree, bsdf = scratch.material("ma none")
    image = scratch.image("ma none", RANDOM_RGBA)
    image.alpha_mode = "NONE"
    scratch.texture(tree, image, "Alpha", bsdf.inputs["Alpha"])
    got = material_alpha(mat)
    assert got.alpha is None and got.note is None


def test_math_greater_than_bakes_a_step(scratch):
    mat, tree, bsdf = scratch.material("ma math")
    rgba = np.zeros((1, 2, 4))
    rgba[0, :, 3] = (0.3, 0.7)
    image = scratch.image("ma math", rgba)
    math = tree.nodes.new("ShaderNodeMath")
    math.operation = "GREATER_THAN"
    math.inputs[1].default_value = 0.5
    scratch.texture(tree, image, "Alpha", math.inputs[0])
    tree.links.new(math.outputs[0], bsdf.inputs["Alpha"])
    got = material_alpha(mat).alpha
    np.testing.assert_array_equal(got.transfer, (X > 0.5).astype(np.float32))
    np.testing.assert_allclose(got.sample(texel_centres(1, 2))[0], (0.0, 1.0))


def test_math_chain_with_clamp_and_reroute(scratch):
    """(1 - 2 a) clamped, through a reroute: the transfer is the chain at the source values."""
    mat, tree, bsdf = scratch.material("ma chain")
    image = scratch.image("ma chain", RANDOM_RGBA)
    times, minus = tree.nodes.new("ShaderNodeMath"), tree.nodes.new("ShaderNodeMath")
    times.operation, minus.operation = "MULTIPLY", "SUBTRACT"
    times.inputs[1].default_value = 2.0
    minus.inputs[0].default_value = 1.0
    minus.use_clamp = True
    reroute = tree.nodes.new("NodeReroute")
    scratch.texture(tree, image, "Alpha", times.inputs[0])
    tree.links.new(times.outputs[0], reroute.inputs[0])
    tree.links.new(reroute.outputs[0], minus.inputs[1])
    tree.links.new(minus.outputs[0], bsdf.inputs["Alpha"])
    np.testing.assert_allclose(material_alpha(mat).alpha.transfer, np.clip(1 - 2 * X, 0, 1), atol=1e-6)


def test_color_ramp_constant_is_a_step(scratch):
    mat, tree, bsdf = scratch.material("ma ramp")
    image = scratch.image("ma ramp", RANDOM_RGBA)
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.interpolation = "CONSTANT"
    ramp.color_ramp.elements[0].color = (0.0, 0.0, 0.0, 0.25)
    ramp.color_ramp.elements[1].position = 0.6
    scratch.texture(tree, image, "Alpha", ramp.inputs[0])
    tree.links.new(ramp.outputs["Color"], bsdf.inputs["Alpha"])
    got = material_alpha(mat).alpha.transfer
    assert np.all(got[X < 0.599] == 0.0) and np.all(got[X > 0.601] == 1.0)
    tree.links.new(ramp.outputs["Alpha"], bsdf.inputs["Alpha"])  # the ramp's alpha: 0.25, then 1
    got = material_alpha(mat).alpha.transfer
    assert np.allclose(got[X < 0.599], 0.25) and np.all(got[X > 0.601] == 1.0)


def test_map_range_and_invert(scratch):
    mat, tree, bsdf = scratch.material("ma map range")
    image = scratch.image("ma map range", RANDOM_RGBA)
    remap, invert = tree.nodes.new("ShaderNodeMapRange"), tree.nodes.new("ShaderNodeInvert")
    remap.inputs["From Min"].default_value, remap.inputs["From Max"].default_value = 0.2, 0.6
    remap.clamp = True
    invert.inputs[0].default_value = 1.0
    scratch.texture(tree, image, "Alpha", remap.inputs["Value"])
    tree.links.new(remap.outputs[0], invert.inputs["Color"])
    tree.links.new(invert.outputs[0], bsdf.inputs["Alpha"])
    want = 1.0 - np.clip((X - 0.2) / 0.4, 0.0, 1.0)
    np.testing.assert_allclose(material_alpha(mat).alpha.transfer, want, atol=1e-5)


def test_separate_color_channel(scratch):
    mat, tree, bsdf = scratch.material("ma separate")
    image = scratch.image("ma separate", RANDOM_RGBA, colorspace="Non-Color")
    separate = tree.nodes.new("ShaderNodeSeparateColor")
    scratch.texture(tree, image, "Color", separate.inputs[0])
    tree.links.new(separate.outputs[1], bsdf.inputs["Alpha"])
    np.testing.assert_allclose(material_alpha(mat).alpha.image, pixels(image)[..., 1], atol=1e-6)


def mix_with_transparent(scratch, name: str, transparent_slot: int, fac: float):
    mat, tree, bsdf = scratch.material(name)
    output = tree.get_output_node("CYCLES")
    mix, clear = tree.nodes.new("ShaderNodeMixShader"), tree.nodes.new("ShaderNodeBsdfTransparent")
    mix.inputs[0].default_value = fac
    tree.links.new(clear.outputs[0], mix.inputs[transparent_slot])
    tree.links.new(bsdf.outputs[0], mix.inputs[3 - transparent_slot])
    tree.links.new(mix.outputs[0], output.inputs["Surface"])
    return mat, tree, bsdf, mix, clear


@pytest.mark.parametrize("slot, want", [(1, 0.3), (2, 0.7)])
def test_mix_with_transparent(scratch, slot, want):
    """(1 - f) A + f B: Transparent in A leaves alpha f, in B alpha 1 - f."""
    mat, *_ = mix_with_transparent(scratch, f"ma mix {slot}", slot, 0.3)
    got = material_alpha(mat).alpha
    assert got.image.shape == (1, 1)
    assert got.image[0, 0] == pytest.approx(want, abs=1e-6)


def test_mix_combines_transparent_colour_and_principled_alpha(scratch):
    """Transparency w_T * lum(colour) + w_P (1 - alpha_P) = 0.6 * 0.5 + 0.4 * 0.5."""
    mat, tree, bsdf, mix, clear = mix_with_transparent(scratch, "ma mix both", 1, 0.4)
    bsdf.inputs["Alpha"].default_value = 0.5
    clear.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    assert material_alpha(mat).alpha.image[0, 0] == pytest.approx(1 - (0.6 * 0.5 + 0.4 * 0.5), abs=1e-6)


def test_mix_fac_from_a_texture(scratch):
    mat, tree, bsdf, mix, clear = mix_with_transparent(scratch, "ma mix tex", 2, 0.0)
    image = scratch.image("ma mix tex", RANDOM_RGBA)
    scratch.texture(tree, image, "Alpha", mix.inputs[0])
    got = material_alpha(mat).alpha
    np.testing.assert_allclose(got.transfer, 1.0 - X, atol=1e-6)  # Transparent in B: alpha 1 - f


def test_transparent_alone_passes_its_colour(scratch):
    mat, tree, _ = scratch.material("ma clear")
    clear = tree.nodes.new("ShaderNodeBsdfTransparent")
    tree.links.new(clear.outputs[0], tree.get_output_node("CYCLES").inputs["Surface"])
    assert material_alpha(mat).alpha.image[0, 0] == 0.0
    clear.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
    assert material_alpha(mat).alpha.image[0, 0] == pytest.approx(1 - luminance(np.array([1.0, 0, 0])), abs=1e-6)


def test_constant_alphas(scratch):
    mat, _, bsdf = scratch.material("ma constant")
    got = material_alpha(mat)
    assert got.alpha is None and got.note is None  # alpha 1: opaque, nothing to say
    bsdf.inputs["Alpha"].default_value = 0.5
    got = material_alpha(mat).alpha
    assert got.image.shape == (1, 1) and got.image[0, 0] == 0.5
    assert got.interpolation == "closest" and got.extension == "extend"


def test_unfollowed_sources_give_a_note(scratch):
    mat, tree, bsdf = scratch.material("ma noise")
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs[0], bsdf.inputs["Alpha"])
    got = material_alpha(mat)
    assert got.alpha is None and got.note == "alpha from a noise texture"
    group = tree.nodes.new("ShaderNodeGroup")
    group.node_tree = bpy.data.node_groups.new("ma group", "ShaderNodeTree")
    scratch.made.append((bpy.data.node_groups, group.node_tree))
    group.node_tree.interface.new_socket("Value", in_out="OUTPUT", socket_type="NodeSocketFloat")
    tree.links.new(group.outputs[0], bsdf.inputs["Alpha"])
    assert material_alpha(mat).note == "alpha from a node group (ma group)"


def test_two_textures_and_light_path_are_noted(scratch):
    mat, tree, bsdf, mix, clear = mix_with_transparent(scratch, "ma shadow ray", 2, 0.0)
    path = tree.nodes.new("ShaderNodeLightPath")
    tree.links.new(path.outputs["Is Shadow Ray"], mix.inputs[0])
    assert "light path" in material_alpha(mat).note
    image = scratch.image("ma two", RANDOM_RGBA)
    scratch.texture(tree, image, "Alpha", mix.inputs[0])
    scratch.texture(tree, image, "Alpha", bsdf.inputs["Alpha"])  # a second node: a second source
    assert material_alpha(mat).note == "alpha from more than one texture"


def test_image_without_image_and_generated_coordinates(scratch):
    mat, tree, bsdf = scratch.material("ma empty")
    node = scratch.texture(tree, None, "Alpha", bsdf.inputs["Alpha"])
    assert material_alpha(mat).note == "an image texture without an image"
    node.image = scratch.image("ma coords", RANDOM_RGBA)
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["Generated"], node.inputs["Vector"])
    assert material_alpha(mat).note == "texture coordinates from a texture coordinate (Generated)"
    tree.links.new(coords.outputs["UV"], node.inputs["Vector"])
    assert material_alpha(mat).note is None


@pytest.mark.parametrize("interpolation, want", [("Closest", "closest"), ("Linear", "linear"),
                                                 ("Cubic", "linear"), ("Smart", "linear")])
@pytest.mark.parametrize("extension", ["REPEAT", "EXTEND", "CLIP", "MIRROR"])
def test_interpolation_and_extension(scratch, interpolation, want, extension):
    mat, tree, bsdf = scratch.material("ma modes")
    node = scratch.texture(tree, scratch.image("ma modes", RANDOM_RGBA), "Alpha", bsdf.inputs["Alpha"])
    node.interpolation, node.extension = interpolation, extension
    got = material_alpha(mat).alpha
    assert (got.interpolation, got.extension) == (want, extension.lower())


def test_mapping_and_uv_map_nodes(scratch):
    mat, tree, bsdf = scratch.material("ma mapping")
    node = scratch.texture(tree, scratch.image("ma mapping", RANDOM_RGBA), "Alpha", bsdf.inputs["Alpha"])
    mapping, uv = tree.nodes.new("ShaderNodeMapping"), tree.nodes.new("ShaderNodeUVMap")
    uv.uv_map = "Cutout"
    mapping.inputs["Scale"].default_value = (2.0, 3.0, 1.0)
    mapping.inputs["Location"].default_value = (0.25, 0.5, 7.0)
    tree.links.new(uv.outputs[0], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs[0], node.inputs["Vector"])
    got = material_alpha(mat)
    assert got.uv_map == "Cutout"
    np.testing.assert_allclose(got.uv_matrix, [[2, 0, 0.25], [0, 3, 0.5]], atol=1e-7)
    mapping.vector_type = "TEXTURE"  # the inverse transform
    np.testing.assert_allclose(material_alpha(mat).uv_matrix, [[0.5, 0, -0.125], [0, 1 / 3, -0.5 / 3]], atol=1e-7)
    mapping.vector_type = "POINT"
    mapping.inputs["Scale"].default_value = (1.0, 1.0, 1.0)
    mapping.inputs["Location"].default_value = (0.0, 0.0, 0.0)
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, np.pi / 2)  # a quarter turn: (u, v) -> (-v, u)
    np.testing.assert_allclose(material_alpha(mat).uv_matrix, [[0, -1, 0], [1, 0, 0]], atol=1e-7)


@pytest.fixture
def plane(scratch):
    """The plane primitive (UVs (0,0), (1,0), (1,1), (0,1) at its corners), removed after."""
    bpy.ops.mesh.primitive_plane_add()
    obj = bpy.context.object
    mesh = obj.data
    yield obj, mesh
    bpy.data.objects.remove(obj)
    bpy.data.meshes.remove(mesh)


def test_triangle_uvs_of_a_plane(plane):
    obj, mesh = plane
    mesh.calc_loop_triangles()
    loops = np.array([t.loops[:] for t in mesh.loop_triangles])
    corners = np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])  # the primitive's layout, per loop
    np.testing.assert_array_equal(triangle_uvs(mesh, ""), corners[loops])
    second = mesh.uv_layers.new(name="Second")
    second.uv.foreach_set("vector", (corners * 0.5 + 0.25).ravel())
    np.testing.assert_allclose(triangle_uvs(mesh, "Second"), corners[loops] * 0.5 + 0.25)
    np.testing.assert_array_equal(triangle_uvs(mesh, "Missing"), corners[loops])  # the render one
    second.active_render = True
    np.testing.assert_allclose(triangle_uvs(mesh, ""), corners[loops] * 0.5 + 0.25)
    while mesh.uv_layers:
        mesh.uv_layers.remove(mesh.uv_layers[0])
    np.testing.assert_array_equal(triangle_uvs(mesh, ""), np.zeros((2, 3, 2)))


def test_mesh_surface_with_two_slots(scratch):
    """Two quads: slot 0 a scaled image cut-out, slot 1 opaque; a third slot noted, not used."""
    mesh = bpy.data.meshes.new("ma two slots")
    scratch.made.append((bpy.data.meshes, mesh))
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0)], [],
                     [(0, 1, 2, 3), (1, 4, 5, 2)])
    layer = mesh.uv_layers.new(name="UVMap")
    uv = RNG.random((len(mesh.loops), 2))
    layer.uv.foreach_set("vector", uv.ravel())
    mesh.polygons[1].material_index = 1
    cutout, tree, bsdf = scratch.material("ma cutout")
    node = scratch.texture(tree, scratch.image("ma cutout", RANDOM_RGBA), "Alpha", bsdf.inputs["Alpha"])
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (2.0, 4.0, 1.0)
    tree.links.new(mapping.outputs[0], node.inputs["Vector"])
    opaque, _, _ = scratch.material("ma opaque")
    noisy, ntree, nbsdf = scratch.material("ma noisy")
    ntree.links.new(ntree.nodes.new("ShaderNodeTexNoise").outputs[0], nbsdf.inputs["Alpha"])
    for mat in (cutout, opaque, noisy):
        mesh.materials.append(mat)
    obj = bpy.data.objects.new("ma two slots", mesh)
    scratch.made.append((bpy.data.objects, obj))
    surface, notes = mesh_surface(obj, mesh)
    mesh.calc_loop_triangles()
    loops = np.array([t.loops[:] for t in mesh.loop_triangles])
    index = np.array([t.material_index for t in mesh.loop_triangles])
    assert len(surface.maps) == 1 and surface.maps[0].name == "ma cutout"
    np.testing.assert_array_equal(surface.material, np.where(index == 0, 0, -1))
    np.testing.assert_allclose(surface.uvs[index == 0], uv[loops[index == 0]] * (2.0, 4.0), atol=1e-6)
    assert np.all(surface.uvs[index == 1] == 0)
    assert notes == {}  # the noisy slot has no triangles
    mesh.polygons[1].material_index = 2
    surface, notes = mesh_surface(obj, mesh)
    assert notes == {"ma noisy": "alpha from a noise texture"}
    assert list(surface.material) == [0, 0, -1, -1]
