"""What Cycles' visibility is under a fog box (issue 43's first question), with bpy.

    python scripts/fog_box_probe.py [--spp N] [--noise] [--unseen]

The scene of tests/support/make_fog_blend.py (a ground, a figure, a 1.2 m cube of
Principled Volume of density 1.5 and no surface shader, a hard point light); Cycles
renders Diffuse Direct with the light's shadows on and off (direct light only, the pixel
centre, as the reference renders). Prints, over the ground pixels out of the figure's
shadow, the mean and largest
|visibility - exp(-1.5 x the length of the pixel's segment to the light inside the cube)|.
With `--noise` the density is a noise texture times 3 instead, rendered with two seeds:
prints the mean half difference of their visibility, the reference's noise measure for a
sized light. `--unseen` turns the cube's camera ray visibility off: shadow rays still
cross it, camera rays pass it by.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def settle(scene, spp: int) -> None:
    """The reference's render settings, as far as the probe needs them."""
    from addon.compat import blender as blender_compat

    cycles = scene.cycles
    cycles.device, cycles.samples, cycles.use_denoising, cycles.use_adaptive_sampling = "CPU", spp, False, False
    cycles.pixel_filter_type, cycles.filter_width = "GAUSSIAN", 0.01
    for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
        setattr(cycles, attr, 0)
    import bpy

    world = bpy.data.worlds.new("dark")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    layer = scene.view_layers[0]
    layer.use_pass_diffuse_direct = layer.use_pass_position = True
    image = scene.render.image_settings
    blender_compat.set_multilayer_exr(image, lambda owner, name, value: setattr(owner, name, value))
    image.color_depth = "32"


def render(scene, light, shadows: bool, folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """(Diffuse Direct as the mean of RGB, position), each (H, W[, 3])."""
    import bpy

    from addon.reference.pass_files import read_exr_channels

    light.data.use_shadow = shadows
    scene.render.filepath = str(folder / f"pass_{int(shadows)}_{scene.cycles.seed}.exr")
    bpy.ops.render.render(write_still=True)
    channels = read_exr_channels(Path(scene.render.filepath))
    layer = scene.view_layers[0].name
    diffuse = np.mean([channels[f"{layer}.Diffuse Direct.{c}"] for c in "RGB"], axis=0)
    return diffuse, np.stack([channels[f"{layer}.Position.{c}"] for c in "XYZ"], axis=-1)


def visibility(scene, light, folder: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(visibility, lit without shadows, position)."""
    shadowed, position = render(scene, light, True, folder)
    free, _ = render(scene, light, False, folder)
    lit = free > 1e-6
    return np.where(lit, shadowed / np.where(lit, free, 1.0), 0.0), lit, position


def main(argv: list[str] | None = None) -> int:
    from tests.support.make_fog_blend import behind_figure, build, transmittance

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spp", type=int, default=1)
    parser.add_argument("--noise", action="store_true")
    parser.add_argument("--unseen", action="store_true")
    args = parser.parse_args(argv)
    scene, light, fog = build(args.noise)
    fog.visible_camera = not args.unseen
    settle(scene, args.spp)
    folder = Path(tempfile.mkdtemp(prefix="omniwarp_fog_"))
    how = f"{args.spp} spp{', unseen' if args.unseen else ''}"
    if not args.noise:
        vis, lit, position = visibility(scene, light, folder)
        ground = lit & (np.abs(position[..., 2]) < 1e-3) & ~behind_figure(position)
        expected = transmittance(position)
        error = np.abs(vis - expected)[ground]
        print(f"homogeneous, {how}: {int(ground.sum())} ground pixels, {int((expected[ground] < 0.999).sum())} "
              f"under the fog; |visibility - exp(-sigma L)| mean {error.mean():.2e}, largest {error.max():.2e}")
        return 0
    runs = []
    for seed in (0, 1):
        scene.cycles.seed = seed
        runs.append(visibility(scene, light, folder))
    both = runs[0][1] & runs[1][1]
    half = 0.5 * np.abs(runs[0][0] - runs[1][0])[both]
    partial = ((runs[0][0] > 0.02) & (runs[0][0] < 0.98))[both]
    print(f"noise texture, {how}: {int(both.sum())} pixels lit in both seeds (seed 0: {int(runs[0][1].sum())}, "
          f"seed 1: {int(runs[1][1].sum())}); mean half difference {half.mean():.5f}, over the "
          f"{int(partial.sum())} partly shadowed {half[partial].mean():.5f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
