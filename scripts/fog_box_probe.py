"""What Cycles' visibility is under a fog box (issue 43's first question), with bpy.

    python scripts/fog_box_probe.py [--spp N] [--noise] [--unseen]

A ground under a 1.2 m cube of Principled Volume (density 1.5, no surface shader) and a
hard point light; Cycles renders Diffuse Direct with the light's shadows on and off
(direct light only, the pixel centre, as the reference renders). Prints, over the ground
pixels, the mean and largest |visibility - exp(-1.5 x the length of the pixel's segment
to the light inside the cube)|. With `--noise` the density is a noise texture times 3
instead, rendered with two seeds: prints the mean half difference of their visibility,
the reference's noise measure for a sized light. `--unseen` turns the cube's camera ray
visibility off: shadow rays still cross it, camera rays pass it by.
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SIZE = (96, 72)
LIGHT = np.array([0.4, 0.3, 3.0])
BOX_CENTRE, BOX_HALF, DENSITY = np.array([0.0, 0.0, 0.8]), 0.6, 1.5


def build(noise: bool, spp: int, unseen: bool = False):
    import bpy  # first: bmesh is bpy's
    import bmesh

    from addon.render import blender_compat

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device, cycles.samples, cycles.use_denoising, cycles.use_adaptive_sampling = "CPU", spp, False, False
    cycles.pixel_filter_type, cycles.filter_width = "GAUSSIAN", 0.01
    for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
        setattr(cycles, attr, 0)
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    world = bpy.data.worlds.new("dark")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    ground = bpy.data.meshes.new("ground")
    ground.from_pydata([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(bpy.data.objects.new("ground", ground))
    cube = bpy.data.meshes.new("fog")
    made = bmesh.new()
    bmesh.ops.create_cube(made, size=2.0 * BOX_HALF)
    made.to_mesh(cube)
    fog = bpy.data.objects.new("fog", cube)
    fog.location = tuple(BOX_CENTRE)
    fog.visible_camera = not unseen
    scene.collection.objects.link(fog)
    material = bpy.data.materials.new("fog")
    tree = blender_compat.ensure_node_tree(material)
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    volume = tree.nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Density"].default_value = DENSITY
    if noise:
        texture = tree.nodes.new("ShaderNodeTexNoise")
        texture.inputs["Scale"].default_value = 3.0
        scale = tree.nodes.new("ShaderNodeMath")
        scale.operation, scale.inputs[1].default_value = "MULTIPLY", 3.0
        tree.links.new(texture.outputs["Fac"], scale.inputs[0])
        tree.links.new(scale.outputs[0], volume.inputs["Density"])
    tree.links.new(volume.outputs[0], output.inputs["Volume"])
    cube.materials.append(material)
    light = bpy.data.objects.new("lamp", bpy.data.lights.new("lamp", "POINT"))
    light.data.energy, light.data.shadow_soft_size, light.location = 1000.0, 0.0, tuple(LIGHT)
    scene.collection.objects.link(light)
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    camera.location, camera.rotation_euler = (0.0, -4.0, 5.0), (math.radians(38.0), 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    layer = scene.view_layers[0]
    layer.use_pass_diffuse_direct = layer.use_pass_position = True
    image = scene.render.image_settings
    blender_compat.set_multilayer_exr(image, lambda owner, name, value: setattr(owner, name, value))
    image.color_depth = "32"
    return scene, light


def render(scene, light, shadows: bool, folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """(Diffuse Direct as the mean of RGB, position), each (H, W[, 3])."""
    import bpy

    from addon.reference.capture import read_exr_channels

    light.data.use_shadow = shadows
    scene.render.filepath = str(folder / f"pass_{int(shadows)}_{scene.cycles.seed}.exr")
    bpy.ops.render.render(write_still=True)
    channels = read_exr_channels(Path(scene.render.filepath))
    diffuse = np.mean([channels[f"ViewLayer.Diffuse Direct.{c}"] for c in "RGB"], axis=0)
    return diffuse, np.stack([channels[f"ViewLayer.Position.{c}"] for c in "XYZ"], axis=-1)


def visibility(scene, light, folder: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(visibility, lit without shadows, position)."""
    shadowed, position = render(scene, light, True, folder)
    free, _ = render(scene, light, False, folder)
    lit = free > 1e-6
    return np.where(lit, shadowed / np.where(lit, free, 1.0), 0.0), lit, position


def transmittance(position: np.ndarray) -> np.ndarray:
    """exp(-density x the length inside the box of each point's segment to the light)."""
    p = position.reshape(-1, 3).astype(np.float64)
    d = LIGHT - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (BOX_CENTRE - BOX_HALF - p) / d, (BOX_CENTRE + BOX_HALF - p) / d
    enter = np.clip(np.nanmax(np.minimum(t0, t1), axis=1), 0.0, 1.0)
    leave = np.clip(np.nanmin(np.maximum(t0, t1), axis=1), 0.0, 1.0)
    inside = np.maximum(leave - enter, 0.0) * np.linalg.norm(d, axis=1)
    return np.exp(-DENSITY * inside).reshape(position.shape[:2])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spp", type=int, default=1)
    parser.add_argument("--noise", action="store_true")
    parser.add_argument("--unseen", action="store_true")
    args = parser.parse_args(argv)
    scene, light = build(args.noise, args.spp, args.unseen)
    folder = Path(tempfile.mkdtemp(prefix="omniwarp_fog_"))
    if not args.noise:
        vis, lit, position = visibility(scene, light, folder)
        ground = lit & (np.abs(position[..., 2]) < 1e-3)
        expected = transmittance(position)
        error = np.abs(vis - expected)[ground]
        print(f"homogeneous, {args.spp} spp{', unseen' if args.unseen else ''}: {int(ground.sum())} ground pixels, "
              f"{int((expected[ground] < 0.999).sum())} under the fog; |visibility - exp(-sigma L)| "
              f"mean {error.mean():.2e}, largest {error.max():.2e}")
        return 0
    runs = []
    for seed in (0, 1):
        scene.cycles.seed = seed
        runs.append(visibility(scene, light, folder))
    both = runs[0][1] & runs[1][1]
    half = 0.5 * np.abs(runs[0][0] - runs[1][0])[both]
    partial = ((runs[0][0] > 0.02) & (runs[0][0] < 0.98))[both]
    print(f"noise texture, {args.spp} spp{', unseen' if args.unseen else ''}: {int(both.sum())} pixels lit in both seeds "
          f"(seed 0: {int(runs[0][1].sum())}, seed 1: {int(runs[1][1].sum())}); mean half difference "
          f"{half.mean():.5f}, over the {int(partial.sum())} partly shadowed {half[partial].mean():.5f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
