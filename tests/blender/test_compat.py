"""addon.compat.blender on the running Blender line (docs/versions.md).

The suite runs on every tested line (scripts/test.sh), so each gate is checked against
what that line really does: a gate that picks the wrong branch fails here, on that line.
"""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from addon import cli  # noqa: E402
from addon.blender import panels  # noqa: E402
from addon.compat import blender as blender_compat  # noqa: E402
from tests.support.cli_run import REPO, run_python  # noqa: E402

pytestmark = pytest.mark.blender

LINE = tuple(bpy.app.version[:2])

# What each tested line lacks (docs/versions.md, "What a line lacks"). A new line or a
# changed gate shows up here as a failure, not as a silent change of behaviour.
EXPECTED_GAPS = {
    (4, 2): {"direct_light_intensity", "depth_write", "get_transform", "grid_nodes"},
    (4, 5): {"direct_light_intensity", "get_transform", "grid_nodes"},
    (5, 2): set(),
}


def test_line_is_a_tested_one():
    assert LINE in EXPECTED_GAPS, f"Blender {bpy.app.version_string} is not a tested line"


def test_gaps_pin_each_line():
    gaps = blender_compat.line_gaps()
    assert {gap.name for gap in gaps} == EXPECTED_GAPS[LINE]
    for gap in gaps:
        assert "\n" not in gap.text and gap.text.startswith("Blender %d.%d" % LINE), gap.text


def test_gaps_follow_the_api():
    """Each gap is there exactly when its API is missing (feature detection, not a list)."""
    import gpu

    names = {gap.name for gap in blender_compat.line_gaps()}
    assert ("depth_write" in names) == (not hasattr(gpu.types.GPUShaderCreateInfo, "depth_write"))
    eevee_props = bpy.types.SceneEEVEE.bl_rna.properties
    assert ("direct_light_intensity" in names) == ("direct_light_intensity" not in eevee_props)
    assert ("get_transform" in names) == (bpy.app.version < (5, 0, 0))
    assert ("grid_nodes" in names) == (bpy.app.version < (5, 0, 0) or not hasattr(bpy.types, "GeometryNodeSampleGrid"))


def test_cli_says_each_gap_in_one_line(capsys):
    cli._say_line_gaps()
    lines = capsys.readouterr().err.splitlines()
    assert lines == [f"note: {gap.text}" for gap in blender_compat.line_gaps()]


def test_panels_draw_each_gap_in_one_line():
    labels: list[str] = []

    class Layout:
        def label(self, text: str, icon: str = "NONE") -> None:
            labels.append(text)

    panels.draw_line_gaps(Layout())
    assert labels == [gap.text for gap in blender_compat.line_gaps()]


def test_eevee_engine_is_offered():
    engine = blender_compat.eevee_engine_id()
    items = {item.identifier for item in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    assert engine in items
    assert engine == ("BLENDER_EEVEE_NEXT" if LINE < (5, 0) else "BLENDER_EEVEE")


def test_multilayer_exr_is_selected():
    scene = bpy.data.scenes.new("compat_exr")
    try:
        calls = []

        def setter(owner, name, value):
            calls.append(name)
            setattr(owner, name, value)

        blender_compat.set_multilayer_exr(scene.render.image_settings, setter)
        assert scene.render.image_settings.file_format == "OPEN_EXR_MULTILAYER"
        assert calls[-1] == "file_format"
        assert ("media_type" in calls) == (LINE >= (5, 0))
    finally:
        bpy.data.scenes.remove(scene)


def test_node_trees_for_new_materials():
    material = bpy.data.materials.new("compat_material")
    try:
        tree = blender_compat.ensure_node_tree(material)
        assert tree is not None and tree == material.node_tree
        assert blender_compat.uses_nodes(material)
        if LINE < (5, 0):
            material.use_nodes = False  # before 5.0 the flag switches the tree off
            assert not blender_compat.uses_nodes(material)
    finally:
        bpy.data.materials.remove(material)


def test_light_linking_is_present():
    assert blender_compat.has_light_linking()
    assert hasattr(bpy.types.Object, "bl_rna") and "light_linking" in bpy.types.Object.bl_rna.properties


def test_exr_pass_name_matches_a_real_render(tmp_path):
    """The Diffuse Direct channel of a tiny Cycles multilayer EXR has the name the gate gives."""
    from addon.reference.pass_files import read_exr_channels

    scene = bpy.data.scenes.new("compat_pass")
    camera = bpy.data.objects.new("compat_cam", bpy.data.cameras.new("compat_cam"))
    lamp = bpy.data.objects.new("compat_lamp", bpy.data.lights.new("compat_lamp", "POINT"))
    mesh = bpy.data.meshes.new("compat_plane")
    mesh.from_pydata([(-9, -9, -2), (9, -9, -2), (9, 9, -2), (-9, 9, -2)], [], [(0, 1, 2, 3)])
    plane = bpy.data.objects.new("compat_plane", mesh)
    try:
        for obj in (camera, lamp, plane):
            scene.collection.objects.link(obj)
        scene.camera = camera
        scene.render.engine = "CYCLES"
        scene.cycles.samples = 1
        scene.render.resolution_x = scene.render.resolution_y = 4
        scene.view_layers[0].use_pass_diffuse_direct = True
        scene.render.filepath = str(tmp_path / "pass")
        scene.render.use_file_extension = True
        scene.render.use_compositing = False  # 5.x would write the composite only
        blender_compat.set_multilayer_exr(scene.render.image_settings, setattr)
        bpy.ops.render.render(write_still=True, scene=scene.name)
        path = next(tmp_path.glob("pass*.exr"))
        channels = read_exr_channels(path)  # the reader the captures use (every part of a 5.x file)
        layer = scene.view_layers[0].name
        wanted = f"{layer}.{blender_compat.exr_pass_name('Diffuse Direct')}.R"
        assert wanted in channels, sorted(channels)
    finally:
        for obj in (camera, lamp, plane):
            bpy.data.objects.remove(obj)
        bpy.data.meshes.remove(mesh)
        bpy.data.scenes.remove(scene)


_GPU_SCRIPT = r"""
import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
import bpy
from addon.compat import blender as blender_compat
from addon.render.backends.blender.gpu_objects import empty_texture, ensure_gpu, float_texture, read_texture, read_uint
ensure_gpu()
data = np.arange(4 * 3 * 4, dtype=np.float32).reshape(3, 4, 4)
assert np.array_equal(read_texture(float_texture((4, 3), "RGBA32F", data), "RGBA32F"), data)
single = np.arange(12, dtype=np.float32).reshape(3, 4)
assert np.array_equal(read_texture(float_texture((4, 3), "R32F", single), "R32F"), single)
ints = empty_texture((5, 2), "R32UI")
ints.clear(format="UINT", value=(7,))
assert read_uint(ints).shape == (2, 5) and (read_uint(ints) == 7).all()
print("ok")
"""


def test_texture_creation_and_read_back():
    """Empty textures (no `data=None` before 5.0) and read-backs in memory order (4.x Buffers
    export Fortran strides), in a child process: one GL owner per process."""
    proc = run_python("-c", _GPU_SCRIPT, REPO, timeout=300)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("ok"), proc.stderr[-2000:]

