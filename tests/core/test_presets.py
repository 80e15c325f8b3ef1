"""Preset registry and the shipped presets (addon/core/presets.py, presets/*.py)."""
from __future__ import annotations

import math
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
    """The three design presets and the spot and sun scenes ship with the repository."""
    assert {"room_omni", "room_hemi", "courtyard", "spot_street", "sun_field"} <= set(SHIPPED)
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
    assert a.light.spot_size == b.light.spot_size
    assert np.array_equal(a.camera.matrix_world, b.camera.matrix_world)
    assert a.camera.fov_deg == b.camera.fov_deg


@pytest.mark.parametrize("name", SHIPPED)
def test_preset_contract(name):
    """Each preset has a light, a camera at the requested resolution, finite geometry
    and non-empty DESCRIPTION and STRESSES, also listed by available_presets."""
    scene = PR.build_preset(name, (80, 60))
    assert scene.name == name
    assert scene.light.emission in ("omni", "hemi", "spot", "sun")
    assert len(scene.world_triangles()) < 50_000  # shipped scenes stay quick to capture and draw
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


def _view_direction(camera: CameraSpec) -> np.ndarray:
    return -np.asarray(camera.matrix_world)[:3, 2]


def _ground_points_in_view(scene, depths) -> list[np.ndarray]:
    """Points on the ground (z = 0) straight ahead of the camera at the given horizontal distances."""
    cam = np.asarray(scene.camera.matrix_world)[:3, 3]
    ahead = _view_direction(scene.camera).copy()
    ahead[2] = 0.0
    ahead /= np.linalg.norm(ahead)
    return [np.array([cam[0], cam[1], 0.0]) + d * ahead for d in depths]


def test_spot_street_is_a_deep_spot_lit_street():
    """spot_street: a wide spot cone (100-140 degrees) from high up over the street, in front
    of the camera plane but out of view, reaching both the ground 6 m ahead of the low camera
    and 70 m down the street; the camera looks along it."""
    scene = PR.build_preset("spot_street")
    light, camera = scene.light, scene.camera
    assert light.emission == "spot"
    assert 100.0 <= math.degrees(light.spot_size) <= 140.0
    cam = np.asarray(camera.matrix_world)[:3, 3]
    assert cam[2] < 2.0 and 50.0 <= camera.fov_deg <= 70.0
    assert abs(_view_direction(camera)[2]) < 0.2  # looks along the street, not down at it
    assert light.position[2] > 15.0 and not _in_view(camera, light.position)
    assert (light.position - cam) @ _view_direction(camera) > 10.0  # a PPS point light, not inverted
    half = light.spot_size / 2.0
    for point in _ground_points_in_view(scene, (6.0, 20.0, 45.0, 70.0)):
        assert _in_view(camera, point)
        d = point - light.position
        assert math.acos(float(d @ light.axis) / np.linalg.norm(d)) < half, point
    # The street is tens of metres deep: the ground reaches past 70 m along the view.
    ground = next(m for m in scene.meshes if m.name == "ground").world_triangles().reshape(-1, 3)
    assert ground[:, 1].max() - cam[1] > 70.0


def test_sun_field_sun_is_low_and_across_the_view():
    """sun_field: a sun 25-45 degrees high whose horizontal direction is within 20 degrees of
    perpendicular to the view; a low camera over a field at least 150 m wide; occluders both
    within 15 m of the camera and over 100 m away."""
    scene = PR.build_preset("sun_field")
    light, camera = scene.light, scene.camera
    assert light.emission == "sun"
    elevation = math.degrees(math.asin(-light.axis[2]))
    assert 25.0 <= elevation <= 45.0
    view = _view_direction(camera)
    horizontal = light.axis[:2] / np.linalg.norm(light.axis[:2])
    view_h = view[:2] / np.linalg.norm(view[:2])
    assert abs(math.degrees(math.acos(abs(float(horizontal @ view_h)))) - 90.0) < 20.0
    cam = np.asarray(camera.matrix_world)[:3, 3]
    assert cam[2] < 2.0
    ground = next(m for m in scene.meshes if m.name == "ground").world_triangles().reshape(-1, 3)
    assert np.ptp(ground[:, 0]) >= 150.0 and np.ptp(ground[:, 1]) >= 150.0
    distances = [np.linalg.norm(m.world_triangles().reshape(-1, 3).mean(axis=0) - cam)
                 for m in scene.meshes if m.name != "ground"]
    assert min(distances) < 15.0 and max(distances) > 100.0


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
