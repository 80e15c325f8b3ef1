"""The numpy EXR reader (core/exr.py) against the OpenEXR module on files Blender writes:
every codec and depth Blender offers that the reader claims, multilayer (several parts on
5.x), and the refusals of what it does not read."""
from __future__ import annotations

import struct

import bpy
import numpy as np
import pytest

from addon.core import exr
from addon.compat import blender as blender_compat

OpenEXR = pytest.importorskip("OpenEXR", reason="OpenEXR (dev extra) is the oracle of this test")


def _openexr_channels(path) -> dict[str, np.ndarray]:
    out = {}
    with OpenEXR.File(str(path), separate_channels=True) as exr_file:
        for part in exr_file.parts:
            for name, channel in part.channels.items():
                out[name] = np.asarray(channel.pixels, dtype=np.float32)
    return out


@pytest.fixture(scope="module")
def scene():
    """A lit plane with a cube on it, 23 x 37 pixels (odd sizes: ZIP's 16-line chunks end short)."""
    scene = bpy.data.scenes.new("exr_reader")
    camera = bpy.data.objects.new("exr_cam", bpy.data.cameras.new("exr_cam"))
    camera.location = (0.0, -6.0, 3.0)
    camera.rotation_euler = (1.1, 0.0, 0.0)
    lamp = bpy.data.objects.new("exr_lamp", bpy.data.lights.new("exr_lamp", "POINT"))
    lamp.location = (1.0, -1.0, 3.0)
    lamp.data.energy = 800.0
    mesh = bpy.data.meshes.new("exr_plane")
    mesh.from_pydata([(-9, -9, 0), (9, -9, 0), (9, 9, 0), (-9, 9, 0),
                      (-0.5, -0.5, 1), (0.5, -0.5, 1), (0.5, 0.5, 1), (-0.5, 0.5, 1)], [],
                     [(0, 1, 2, 3), (4, 5, 6, 7)])
    plane = bpy.data.objects.new("exr_plane", mesh)
    for obj in (camera, lamp, plane):
        scene.collection.objects.link(obj)
    scene.camera = camera
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 2
    scene.cycles.device = "CPU"
    scene.render.resolution_x, scene.render.resolution_y = 23, 37
    scene.render.resolution_percentage = 100
    scene.view_layers[0].use_pass_diffuse_direct = True
    scene.view_layers[0].use_pass_z = True
    scene.render.use_file_extension = True
    scene.render.use_compositing = False
    blender_compat.set_multilayer_exr(scene.render.image_settings, setattr)
    yield scene
    for obj in (camera, lamp, plane):
        bpy.data.objects.remove(obj)
    bpy.data.meshes.remove(mesh)
    bpy.data.scenes.remove(scene)


@pytest.mark.parametrize("codec", ["NONE", "ZIPS", "ZIP"])
@pytest.mark.parametrize("depth", ["32", "16"])
def test_reader_equals_openexr(scene, tmp_path, codec, depth):
    scene.render.image_settings.color_depth = depth
    scene.render.image_settings.exr_codec = codec
    scene.render.filepath = str(tmp_path / f"out_{codec}_{depth}")
    bpy.ops.render.render(write_still=True, scene=scene.name)
    path = next(tmp_path.glob(f"out_{codec}_{depth}*.exr"))
    ours, oracle = exr.read_channels(path), _openexr_channels(path)
    assert sorted(ours) == sorted(oracle)
    lit = 0
    for name, plane in oracle.items():
        assert ours[name].dtype == np.float32 and ours[name].shape == (37, 23), name
        np.testing.assert_array_equal(ours[name], plane, err_msg=name)
        lit += int(np.count_nonzero(plane))
    assert lit > 0  # the render holds something to compare
    direct = f"{scene.view_layers[0].name}.{blender_compat.exr_pass_name('Diffuse Direct')}.R"
    assert direct in ours


def _header_bytes(attributes: list[tuple[str, str, bytes]], version: int = 2) -> bytes:
    out = struct.pack("<iI", exr.MAGIC, version)
    for name, kind, value in attributes:
        out += name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value
    return out + b"\0"


def _channels_attr(*names: str) -> bytes:
    return b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for n in names) + b"\0"


def test_refuses_what_it_does_not_read(tmp_path):
    box = struct.pack("<4i", 0, 0, 1, 0)
    cases = {
        "piz": (_header_bytes([("channels", "chlist", _channels_attr("R")), ("compression", "compression", b"\x04"),
                               ("dataWindow", "box2i", box)]), "PIZ"),
        "tiled": (_header_bytes([], version=2 | 0x200), "tiled"),
        "not_exr": (b"\x89PNG\r\n\x1a\n" + bytes(16), "not an OpenEXR"),
        "short": (_header_bytes([("channels", "chlist", _channels_attr("R")), ("compression", "compression", b"\x00"),
                                 ("dataWindow", "box2i", box)]), "ends"),
    }
    for name, (data, words) in cases.items():
        path = tmp_path / f"{name}.exr"
        path.write_bytes(data)
        with pytest.raises(exr.ExrError, match=words):
            exr.read_channels(path)
    with pytest.raises(exr.ExrError, match="cannot read"):
        exr.read_channels(tmp_path / "missing.exr")


def test_reads_a_written_uncompressed_file(tmp_path):
    """A two-line, two-channel NONE file built by hand: values and row order as written."""
    box = struct.pack("<4i", 0, 0, 2, 1)  # 3 x 2
    header = _header_bytes([("channels", "chlist", _channels_attr("A", "B")),
                            ("compression", "compression", b"\x00"), ("dataWindow", "box2i", box)])
    rows = [np.array([[1, 2, 3], [4, 5, 6]], np.float32), np.array([[7, 8, 9], [10, 11, 12]], np.float32)]
    table_at = len(header)
    chunks, offsets = b"", []
    for y in range(2):
        payload = rows[0][y].tobytes() + rows[1][y].tobytes()
        offsets.append(table_at + 16 + len(chunks))
        chunks += struct.pack("<ii", y, len(payload)) + payload
    path = tmp_path / "hand.exr"
    path.write_bytes(header + struct.pack("<2Q", *offsets) + chunks)
    got = exr.read_channels(path)
    np.testing.assert_array_equal(got["A"], rows[0])
    np.testing.assert_array_equal(got["B"], rows[1])
