"""Writes a small .blend that was never a preset (run in a child process: it resets bpy's data).

    python tests/support/make_blend.py OUT.blend [--no-light] [--bad-geometry] [--light-type SUN|AREA] [--zero-energy]
                                       [--omniwarp METHOD:RESOLUTION] [--light-location X,Y,Z]
                                       [--bias-constant VALUE]

--omniwarp saves OmniWarp settings on the light (enabled, the registry method's
parameterization and warp, the resolution): the add-on is registered for that.
--light-location moves the light (nan and inf are accepted: bad-input tests);
--bias-constant (with --omniwarp) stores that constant bias, e.g. nan.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


# Broken geometry added by --bad-geometry, with the triangle counts the pipeline must skip.
BAD_NAN_TRIANGLES = 2  # a quad with a NaN vertex and one with an inf vertex: one triangle each uses it
BAD_ZERO_AREA_TRIANGLES = 1


def add_bad_geometry(builder) -> None:
    """NaN / inf vertices, a zero-area triangle, a non-manifold fan and a face-less mesh."""
    # Finite here (the scene builder refuses NaN); main() breaks vertex 2 in Blender itself.
    builder.mesh("nan_tri", [[2.0, 2.0, 0.5], [2.5, 2.0, 0.5], [2.2, 2.2, 0.5]], [[0, 1, 2]])
    builder.mesh("inf_tri", [[-2.0, 2.0, 0.5], [-2.5, 2.0, 0.5], [-2.2, 2.2, 0.5]], [[0, 1, 2]])
    builder.mesh("zero_area", [[1.0, -2.0, 0.3], [2.0, -2.0, 0.3], [3.0, -2.0, 0.3]], [[0, 1, 2]])
    # Three triangles sharing one edge: non-manifold, but perfectly drawable.
    builder.mesh("non_manifold", [[-1, -2, 0.2], [-1, -2, 1.2], [-2, -2.5, 0.7], [-2, -1.5, 0.7], [-0.2, -2.2, 0.7]],
                 [[0, 1, 2], [0, 1, 3], [0, 1, 4]])


def save_omniwarp_settings(light, spec: str) -> None:
    """Enable OmniWarp on `light` (bpy Light data) with METHOD:RESOLUTION, e.g. cube+notw:512."""
    from addon.core.methods import method

    name, _, resolution = spec.partition(":")
    entry = method(name)
    props = light.omniwarp
    props.enabled = True
    props.parameterization = entry.parameterization.upper()
    props.warp = entry.warp.upper()
    if resolution:
        props.resolution = int(resolution)


def main(out: str, with_light: bool, bad_geometry: bool = False, light_type: str | None = None,
         zero_energy: bool = False, omniwarp: str | None = None, light_location: str | None = None,
         bias_constant: str | None = None) -> None:
    import bpy

    from addon.core.scene import SceneBuilder
    from addon.reference.blender_scene import build_blender_scene

    bpy.ops.wm.read_homefile(use_empty=True)
    builder = SceneBuilder("user_scene", (160, 120))
    builder.plane("ground", (0.0, 0.0, 0.0), 12.0, 12.0)
    builder.box("crate", (0.5, 0.2, 0.6), (1.0, 0.8, 1.2), rotate_z_deg=20.0)
    builder.box("post", (-1.5, 1.0, 1.0), (0.3, 0.3, 2.0))
    builder.point_light((1.5, -1.0, 3.0))
    builder.camera((5.0, -5.0, 3.5), (0.0, 0.0, 0.5), fov_deg=55.0)
    if bad_geometry:
        add_bad_geometry(builder)
    scene = build_blender_scene(builder.finish())
    if bad_geometry:
        # A mesh object with vertices but no faces.
        mesh = bpy.data.meshes.new("no_faces")
        mesh.from_pydata([(0, 3, 0), (1, 3, 0)], [(0, 1)], [])
        scene.collection.objects.link(bpy.data.objects.new("no_faces", mesh))
        for obj in scene.objects:
            if obj.name.startswith("nan_tri"):
                obj.data.vertices[2].co = (float("nan"), 2.2, 0.5)
            elif obj.name.startswith("inf_tri"):
                obj.data.vertices[2].co = (-2.2, float("inf"), 0.5)
    for obj in [o for o in scene.objects if o.type == "LIGHT"]:
        if light_type:
            obj.data.type = light_type
        if zero_energy:
            obj.data.energy = 0.0
        if light_location:
            obj.location = tuple(float(v) for v in light_location.split(","))
    if not with_light:
        for obj in [o for o in scene.objects if o.type == "LIGHT"]:
            bpy.data.objects.remove(obj)
    bpy.context.window_manager.windows  # noqa: B018 - background: no window to switch
    for other in [s for s in bpy.data.scenes if s != scene]:
        bpy.data.scenes.remove(other)
    if omniwarp is None:
        bpy.ops.wm.save_as_mainfile(filepath=out)
        return
    from addon.blender import registration

    registration.register()
    try:
        for obj in [o for o in scene.objects if o.type == "LIGHT"]:
            save_omniwarp_settings(obj.data, omniwarp)
            if bias_constant is not None:
                obj.data.omniwarp.bias_constant = float(bias_constant)
        bpy.ops.wm.save_as_mainfile(filepath=out)
    finally:
        registration.unregister()


def _option(name: str) -> str | None:
    return sys.argv[sys.argv.index(name) + 1] if name in sys.argv else None


if __name__ == "__main__":
    main(sys.argv[1], "--no-light" not in sys.argv, "--bad-geometry" in sys.argv, _option("--light-type"),
         "--zero-energy" in sys.argv, _option("--omniwarp"), _option("--light-location"), _option("--bias-constant"))
