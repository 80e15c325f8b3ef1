"""Preset registry and the shipped presets (addon/core/presets.py, presets/*.py)."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from addon.core import presets as PR
from addon.core.errors import InputError, PresetError
from addon.core.scene import CameraSpec

SHIPPED = PR.select_presets("all")  # the non-stress presets; stress_* have their own tests


def _in_view(camera: CameraSpec, point: np.ndarray) -> bool:
    """True when `point` projects inside the camera's image and clip range."""
    homo = np.append(np.asarray(point, dtype=float), 1.0)
    clip = camera.projection() @ np.linalg.inv(camera.matrix_world) @ homo
    if clip[3] <= 0:
        return False
    ndc = clip[:3] / clip[3]
    return bool(np.all(np.abs(ndc) <= 1.0))


def test_shipped_presets_exist():
    """The three design presets ship with the repository."""
    assert {"room_omni", "room_hemi", "courtyard"} <= set(SHIPPED)
    assert PR.DEFAULT_PRESET in SHIPPED


@pytest.mark.parametrize("name", SHIPPED)
def test_preset_builds_deterministically(name):
    """Two builds of a preset give bit-identical geometry, light and camera."""
    a = PR.build_preset(name, (64, 48))
    b = PR.build_preset(name, (64, 48))
    ta, tb = a.world_triangles(), b.world_triangles()
    assert ta.shape == tb.shape and len(ta) > 0
    assert np.array_equal(ta, tb)
    assert [m.name for m in a.meshes] == [m.name for m in b.meshes]
    assert np.array_equal(a.light.matrix_world, b.light.matrix_world)
    assert a.light.emission == b.light.emission and a.light.energy == b.light.energy
    assert np.array_equal(a.camera.matrix_world, b.camera.matrix_world)
    assert a.camera.fov_deg == b.camera.fov_deg


@pytest.mark.parametrize("name", SHIPPED)
def test_preset_contract(name):
    """Each preset has a light, a camera at the requested resolution, finite geometry
    and non-empty DESCRIPTION and STRESSES, also listed by available_presets."""
    scene = PR.build_preset(name, (80, 60))
    assert scene.name == name
    assert scene.light.emission in ("omni", "hemi")
    assert scene.camera.resolution == (80, 60)
    assert np.all(np.isfinite(scene.world_triangles()))
    assert scene.description.strip() and scene.stresses.strip()
    info = PR.available_presets()[name]
    assert info.description == scene.description and info.stresses == scene.stresses
    assert not info.is_stress


def test_room_omni_light_is_in_view():
    """room_omni: the camera sees the light (inside its view frustum)."""
    scene = PR.build_preset("room_omni")
    assert scene.light.emission == "omni"
    assert _in_view(scene.camera, scene.light.position)


def test_courtyard_light_is_out_of_view():
    """courtyard: the light is outside the view frustum (behind the camera)."""
    scene = PR.build_preset("courtyard")
    assert scene.light.emission == "omni"
    assert not _in_view(scene.camera, scene.light.position)
    view_dir = -scene.camera.matrix_world[:3, 2]
    to_light = scene.light.position - scene.camera.matrix_world[:3, 3]
    assert float(view_dir @ to_light) < 0.0  # behind the camera


def test_room_hemi_is_hemi_pointing_down():
    """room_hemi: a hemispherical light whose axis points at the floor."""
    scene = PR.build_preset("room_hemi")
    assert scene.light.emission == "hemi"
    assert np.allclose(scene.light.axis, [0.0, 0.0, -1.0], atol=1e-12)


def test_room_lights_are_inside_the_room_box():
    """The room presets put the light inside the closed room (not in a wall)."""
    for name in ("room_omni", "room_hemi"):
        scene = PR.build_preset(name)
        room = next(m for m in scene.meshes if m.name == "room").world_triangles().reshape(-1, 3)
        lo, hi = room.min(axis=0), room.max(axis=0)
        assert np.all(scene.light.position > lo) and np.all(scene.light.position < hi)


# ---------------------------------------------------------------- selection


@pytest.fixture()
def preset_dir(tmp_path: Path) -> Path:
    """A private preset folder: two shipped presets plus two stress presets."""
    for name in ("room_omni", "courtyard"):
        shutil.copy(PR.PRESET_DIR / f"{name}.py", tmp_path / f"{name}.py")
    shutil.copy(PR.PRESET_DIR / "room_hemi.py", tmp_path / "stress_vertex_at_light.py")
    shutil.copy(PR.PRESET_DIR / "room_hemi.py", tmp_path / "stress_nan.py")
    (tmp_path / "_helpers.py").write_text("raise RuntimeError('private modules are not presets')\n")
    return tmp_path


def test_select_all_excludes_stress(preset_dir):
    """'all' is every non-stress preset; 'stress_all' every stress_* one."""
    assert sorted(PR.select_presets("all", preset_dir)) == ["courtyard", "room_omni"]
    assert sorted(PR.select_presets("stress_all", preset_dir)) == ["stress_nan", "stress_vertex_at_light"]


def test_select_all_on_shipped_presets():
    """On the shipped folder, 'all' lists exactly the non-stress presets."""
    chosen = PR.select_presets("all")
    assert chosen and not any(n.startswith("stress_") for n in chosen)
    assert sorted(chosen) == [n for n in SHIPPED if not n.startswith("stress_")]


def test_select_comma_list(preset_dir):
    """A comma list keeps its order and tolerates spaces."""
    assert PR.select_presets(" courtyard , stress_nan", preset_dir) == ["courtyard", "stress_nan"]


@pytest.mark.parametrize("selection", ["no_such_preset", "room_omni,no_such_preset"])
def test_unknown_preset_raises_naming_it(selection, preset_dir):
    """An unknown name is a PresetError (an InputError) that names the bad preset."""
    with pytest.raises(PresetError, match="no_such_preset") as info:
        PR.select_presets(selection, preset_dir)
    assert isinstance(info.value, InputError)
    with pytest.raises(PresetError, match="no_such_preset"):
        PR.build_preset("no_such_preset", preset_dir=preset_dir)


def test_empty_selection_and_missing_stress_presets_raise(tmp_path):
    """An empty selection, or 'stress_all' with no stress preset, is a PresetError."""
    shutil.copy(PR.PRESET_DIR / "room_omni.py", tmp_path / "room_omni.py")
    with pytest.raises(PresetError):
        PR.select_presets(" , ", tmp_path)
    with pytest.raises(PresetError, match="stress"):
        PR.select_presets("stress_all", tmp_path)


def test_preset_file_without_contract_is_rejected(tmp_path):
    """A preset module lacking build/DESCRIPTION/STRESSES is a PresetError naming it."""
    (tmp_path / "broken.py").write_text("DESCRIPTION = 'x'\nSTRESSES = 'y'\n")
    with pytest.raises(PresetError, match="broken.py"):
        PR.available_presets(tmp_path)


def test_preset_source_hash_tracks_file_content(preset_dir):
    """The hash is stable for the same file and changes when the builder changes."""
    h1 = PR.preset_source_hash("room_omni", preset_dir)
    assert h1 == PR.preset_source_hash("room_omni", preset_dir)
    assert h1 != PR.preset_source_hash("courtyard", preset_dir)
    path = preset_dir / "room_omni.py"
    path.write_text(path.read_text() + "\n# a comment is a change\n")
    h2 = PR.preset_source_hash("room_omni", preset_dir)
    assert h2 != h1
    # ... and the changed builder still builds the same scene.
    assert np.array_equal(PR.build_preset("room_omni", preset_dir=preset_dir).world_triangles(),
                          PR.build_preset("room_omni").world_triangles())
