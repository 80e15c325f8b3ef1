"""References of a user's .blend are cached like a preset's (addon/reference/blend_cache.py):
`reference --blend` fills the file that `compare` and `preview` read, and whatever changes
the render changes the key."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("bpy", reason="--blend needs bpy (scripts/setup_env.sh installs it)")

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
from cli_run import env_with, make_blend, omniwarp  # noqa: E402
from cli_run import one_line as refused  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.gl]

RENDERS = "rendering Cycles reference of"
CACHED = "using the cached Cycles reference of"
SMALL = ("--methods", "dpsm,exact", "--resolutions", "256", "--frames", "1", "--no-images")


@pytest.mark.slow
def test_reference_fills_what_compare_and_preview_read(tmp_path):
    blend = make_blend(tmp_path / "shot.blend")
    env = env_with(OMNIWARP_CACHE=tmp_path / "cache")
    filled = omniwarp("reference", "--blend", blend, env=env)
    assert filled.returncode == 0, filled.stderr[-3000:]
    assert RENDERS in filled.stderr
    files = sorted((tmp_path / "cache").glob("shot_*x*_*.npz"))
    assert len(files) == 1, files
    with np.load(files[0]) as stored:
        assert {"hit", "shadowed", "unshadowed", "position", "normal", "triangles"} <= set(stored.files)

    compared = omniwarp("compare", "--blend", blend, *SMALL, "--out", tmp_path / "out", env=env)
    assert compared.returncode == 0, compared.stderr[-3000:]
    assert RENDERS not in compared.stderr and CACHED in compared.stderr
    previewed = omniwarp("preview", "--blend", blend, "--resolution", "256", "--out", tmp_path / "prev", env=env)
    assert previewed.returncode == 0, previewed.stderr[-3000:]
    assert RENDERS not in previewed.stderr and CACHED in previewed.stderr
    assert sorted((tmp_path / "cache").glob("*.npz")) == files


@pytest.mark.slow
def test_a_changed_file_or_light_renders_again(tmp_path):
    env = env_with(OMNIWARP_CACHE=tmp_path / "cache")
    blend = make_blend(tmp_path / "shot.blend")
    assert omniwarp("reference", "--blend", blend, env=env).returncode == 0
    make_blend(blend, "--light-location", "0.5,-0.5,3.5")  # the same name, another light position
    again = omniwarp("compare", "--blend", blend, *SMALL, "--out", tmp_path / "out", env=env)
    assert again.returncode == 0, again.stderr[-3000:]
    assert RENDERS in again.stderr and CACHED not in again.stderr
    assert len(list((tmp_path / "cache").glob("shot_*.npz"))) == 2
    refreshed = omniwarp("reference", "--blend", blend, "--refresh", env=env)
    assert refreshed.returncode == 0 and RENDERS in refreshed.stderr, refreshed.stderr[-3000:]
    assert len(list((tmp_path / "cache").glob("shot_*.npz"))) == 2  # replaced, not added


def test_light_and_camera_need_a_blend(tmp_path):
    line = refused(omniwarp("reference", "--preset", "room_omni", "--light", "Lamp",
                            env=env_with(OMNIWARP_CACHE=tmp_path / "cache")))
    assert "--light and --camera apply to --blend only" in line


def test_files_outside_the_blend_are_in_the_key(tmp_path):
    """An unpacked image (a displacement's, say) can change the geometry: its bytes are keyed."""
    import bpy

    from addon.reference.blend_cache import blend_key_fields

    blend = tmp_path / "shot.blend"
    blend.write_bytes(b"BLENDER-stand-in")
    png = tmp_path / "height.png"
    image = bpy.data.images.new("omniwarp_key_height", 2, 2)
    scene = bpy.data.scenes.new("omniwarp_key_scene")
    try:
        image.filepath_raw = str(png)
        image.file_format = "PNG"
        image.save()
        image.source = "FILE"
        before = blend_key_fields(blend, scene, None, 1)
        png.write_bytes(png.read_bytes() + b"\0")
        after = blend_key_fields(blend, scene, None, 1)
        assert before["external_files"] != after["external_files"]
        assert {k: v for k, v in before.items() if k != "external_files"} == \
               {k: v for k, v in after.items() if k != "external_files"}
    finally:
        bpy.data.images.remove(image)
        bpy.data.scenes.remove(scene)
