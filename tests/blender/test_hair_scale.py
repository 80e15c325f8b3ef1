"""Particle hair under its emitter's scale, read as Cycles reads it (issue 53's grass
field): the emitter hidden in the viewport and rendered gives its strands; a uniform scale
thickens them by itself, a plane scaled across its hair by the ellipse's mean, and a
non-uniform scale is named in the row's note (readers/hair.strand_radius_scale)."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from addon.readers import render_geometry  # noqa: E402
from addon.readers.left_out import KINDS  # noqa: E402

pytestmark = pytest.mark.blender

RADIUS_SCALE = 0.02  # root and tip 1: every key's radius 0.01 before the emitter's scale


def _field(scale) -> "bpy.types.Scene":
    import bmesh

    scene = bpy.data.scenes.new("hair_scale")
    scene.render.engine = "CYCLES"
    mesh = bpy.data.meshes.new("field")
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=2, y_segments=2, size=1.0)
    bm.to_mesh(mesh)
    bm.free()
    field = bpy.data.objects.new("Field", mesh)
    field.scale = scale
    field.hide_viewport = True  # rendered: the render depsgraph has its hair
    scene.collection.objects.link(field)
    settings = field.modifiers.new("grass", "PARTICLE_SYSTEM").particle_system.settings
    settings.type, settings.count, settings.render_type, settings.hair_length = "HAIR", 20, "PATH", 0.3
    settings.radius_scale, settings.root_radius, settings.tip_radius = RADIUS_SCALE, 1.0, 1.0
    settings.use_close_tip = False
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.location = (0.0, -4.0, 2.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


def _read(scale):
    scene = _field(scale)
    try:
        found = render_geometry.render_triangles(scene, scene.view_layers[0], grids=False)
        (owner, strands), = found.strands
        return owner.name, strands, found.left_out.notes()
    finally:
        for obj in list(scene.objects):
            data = obj.data
            bpy.data.objects.remove(obj)
            if isinstance(data, bpy.types.Mesh):
                bpy.data.meshes.remove(data)
            elif data is not None:
                bpy.data.cameras.remove(data)
        bpy.data.scenes.remove(scene)


def test_an_emitter_hidden_in_the_viewport_gives_its_strands_at_their_radius():
    name, strands, notes = _read((1.0, 1.0, 1.0))
    assert name.startswith("Field") and len(strands.offsets) - 1 == 20
    np.testing.assert_allclose(strands.radii, 0.5 * RADIUS_SCALE, rtol=1e-6)
    assert notes == []


def test_a_uniformly_scaled_emitter_thickens_its_hair_by_its_scale():
    _, strands, notes = _read((2.0, 2.0, 2.0))
    np.testing.assert_allclose(strands.radii, 2.0 * 0.5 * RADIUS_SCALE, rtol=1e-6)
    assert notes == []


def test_a_plane_scaled_across_its_hair_thickens_it_and_says_it_is_elliptic():
    # The hair grows along the plane's normal (z, unscaled): its section is the xy circle,
    # scaled by 3 and 1.5: an ellipse of the area of a circle of sqrt(4.5) times the radius.
    _, strands, notes = _read((3.0, 1.5, 1.0))
    np.testing.assert_allclose(strands.radii, np.sqrt(4.5) * 0.5 * RADIUS_SCALE, rtol=1e-4)
    assert notes == [f"{KINDS['elliptic_hair']}: Field"]
