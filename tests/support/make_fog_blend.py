"""A fog box by a figure, as an artist builds one (issue 43):

    python tests/support/make_fog_blend.py OUT.blend [--noise] [--variant NAME] [--light-size R]
        [--reference OUT.npz]

- `Ground` (a 6 m plane) and `Figure` (a 0.4 x 0.4 x 1.2 m box standing on it);
- `Fog`: a box of volume shader and no surface shader (a medium); by `--variant`:
  - `beside` (the default): a 1.2 m cube of Principled Volume, density 1.5 (with
    --noise, a noise texture times 3), beside the figure;
  - `around`: a Principled Volume of density 1 around the figure, reaching below the
    ground (the ground and the figure stand inside the fog), the light outside it;
  - `light_inside`: a Principled Volume of density 0.8 around the light, above the rest;
  - `absorption`: the `beside` box of a coloured Volume Absorption;
  - `tinted`: the `around` box of a Principled Volume with a colour and an absorption colour;
  - `scatter_add`: the `beside` box of a coloured Volume Scatter added to a Volume
    Absorption, mixed half and half with a Volume Coefficients node;
- a hard point light above (`--light-size`: a sphere of that radius), a camera looking down
  at the ground, 128 x 96 pixels.

`build` makes the scene in the running Blender (on `stage`, which the other volume test
files share); `scripts/fog_box_probe.py` renders it with its own settings; `--reference`
also captures the OmniWarp reference of the scene (reference/capture.py) into a .npz
(ReferenceData).
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

SIZE = (128, 96)
LIGHT = np.array([0.4, 0.3, 3.0])
BOX_CENTRE, BOX_HALF, DENSITY = np.array([0.0, 0.0, 0.8]), 0.6, 1.5
FIGURE_CENTRE, FIGURE_HALF = np.array([1.1, 0.2, 0.6]), np.array([0.2, 0.2, 0.6])


@dataclass(frozen=True)
class Variant:
    """Where the fog box is, where the light is, and which volume shader fills the box."""

    centre: tuple[float, float, float]
    half: tuple[float, float, float]
    shader: str  # a key of _SHADERS
    light: tuple[float, float, float] = tuple(LIGHT)


VARIANTS = {
    "beside": Variant(tuple(BOX_CENTRE), (BOX_HALF,) * 3, "principled"),
    "around": Variant((1.1, 0.2, 0.5), (0.9, 0.9, 0.9), "principled_1"),
    "light_inside": Variant((0.4, 0.3, 2.6), (0.8, 0.8, 0.8), "principled_08"),
    "absorption": Variant(tuple(BOX_CENTRE), (BOX_HALF,) * 3, "absorption"),
    "tinted": Variant((1.1, 0.2, 0.5), (0.9, 0.9, 0.9), "tinted"),
    "scatter_add": Variant(tuple(BOX_CENTRE), (BOX_HALF,) * 3, "scatter_add"),
}


def _box(name: str, size, location):
    import bpy  # first: bmesh is bpy's
    import bmesh

    mesh = bpy.data.meshes.new(name)
    made = bmesh.new()
    bmesh.ops.create_cube(made, size=1.0)
    bmesh.ops.scale(made, vec=size, verts=made.verts)
    made.to_mesh(mesh)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _set(node, **values) -> None:
    for name, value in values.items():
        node.inputs[name.replace("_", " ")].default_value = value


def _principled(tree, density: float):
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    _set(node, Density=density)
    return node.outputs[0]


def _absorption(tree):
    node = tree.nodes.new("ShaderNodeVolumeAbsorption")
    _set(node, Color=(0.2, 0.6, 0.9, 1.0), Density=2.0)
    return node.outputs[0]


def _tinted(tree):
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    _set(node, Color=(0.9, 0.5, 0.1, 1.0), Absorption_Color=(0.3, 0.7, 0.2, 1.0), Density=1.2)
    return node.outputs[0]


def _scatter_add(tree):
    scatter, absorb = tree.nodes.new("ShaderNodeVolumeScatter"), tree.nodes.new("ShaderNodeVolumeAbsorption")
    _set(scatter, Color=(0.8, 0.3, 0.5, 1.0), Density=1.0)
    _set(absorb, Color=(0.5, 0.9, 0.4, 1.0), Density=1.5)
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(scatter.outputs[0], add.inputs[0])
    tree.links.new(absorb.outputs[0], add.inputs[1])
    coefficients = tree.nodes.new("ShaderNodeVolumeCoefficients")
    _set(coefficients, Absorption_Coefficients=(0.4, 1.0, 2.0), Scatter_Coefficients=(0.5, 0.2, 0.1))
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 0.25
    tree.links.new(add.outputs[0], mix.inputs[1])
    tree.links.new(coefficients.outputs[0], mix.inputs[2])
    return mix.outputs[0]


_SHADERS = {
    "principled": lambda tree: _principled(tree, DENSITY),
    "principled_1": lambda tree: _principled(tree, 1.0),
    "principled_08": lambda tree: _principled(tree, 0.8),
    "absorption": _absorption,
    "tinted": _tinted,
    "scatter_add": _scatter_add,
}


def _fog_material(shader: str, noise: bool):
    import bpy

    from addon.compat import blender as blender_compat

    material = bpy.data.materials.new("Fog")
    tree = blender_compat.ensure_node_tree(material)
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    volume = _SHADERS[shader](tree)
    if noise:  # a varying density: heterogeneous
        texture = tree.nodes.new("ShaderNodeTexNoise")
        texture.inputs["Scale"].default_value = 3.0
        scale = tree.nodes.new("ShaderNodeMath")
        scale.operation, scale.inputs[1].default_value = "MULTIPLY", 3.0
        tree.links.new(texture.outputs["Fac"], scale.inputs[0])
        tree.links.new(scale.outputs[0], volume.node.inputs["Density"])
    tree.links.new(volume, output.inputs["Volume"])
    return material


def stage(name: str, light_at=tuple(LIGHT)):
    """An empty file's scene for Cycles at SIZE with `Ground` (a 6 m plane), `Figure` (a
    0.4 x 0.4 x 1.2 m box on it), a hard 1 kW point light `Lamp` at `light_at` and a camera
    looking down at the ground; returns (scene, light). The volume tests' files share it."""
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.name = name
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    ground = bpy.data.meshes.new("Ground")
    ground.from_pydata([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(bpy.data.objects.new("Ground", ground))
    _box("Figure", tuple(2.0 * FIGURE_HALF), tuple(FIGURE_CENTRE))
    light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    light.data.energy, light.data.shadow_soft_size, light.location = 1000.0, 0.0, light_at
    scene.collection.objects.link(light)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location, camera.rotation_euler = (0.0, -4.0, 5.0), (math.radians(38.0), 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    return scene, light


def build(noise: bool = False, variant: str = "beside", light_size: float = 0.0):
    """The scene in the running Blender (an empty file first); returns (scene, light, fog).
    `light_size`: the point light's radius (0: hard)."""
    spec = VARIANTS[variant]
    scene, light = stage("fog", spec.light)
    light.data.shadow_soft_size = light_size
    fog = _box("Fog", tuple(2.0 * np.array(spec.half)), spec.centre)
    fog.data.materials.append(_fog_material(spec.shader, noise))
    return scene, light, fog


def _inside(position: np.ndarray, centre: np.ndarray, half, light: np.ndarray = LIGHT) -> np.ndarray:
    """The length of each point's segment to the light inside a box (position (..., 3))."""
    p = np.asarray(position, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(light, dtype=np.float64) - p
    centre, half = np.asarray(centre, dtype=np.float64), np.asarray(half, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (centre - half - p) / d, (centre + half - p) / d
    enter = np.clip(np.nanmax(np.minimum(t0, t1), axis=1), 0.0, 1.0)
    leave = np.clip(np.nanmin(np.maximum(t0, t1), axis=1), 0.0, 1.0)
    return (np.maximum(leave - enter, 0.0) * np.linalg.norm(d, axis=1)).reshape(np.shape(position)[:-1])


def transmittance(position: np.ndarray) -> np.ndarray:
    """exp(-DENSITY x the length inside the `beside` fog of each point's segment to the light."""
    return np.exp(-DENSITY * _inside(position, BOX_CENTRE, BOX_HALF))


def behind_figure(position: np.ndarray, light: np.ndarray = LIGHT) -> np.ndarray:
    """Whether each point's segment to the light crosses the figure (a point on the
    figure's own lit faces touches it only: a length of float rounding)."""
    return _inside(position, FIGURE_CENTRE, FIGURE_HALF, light) > 1e-4


def grids_oracle(ref) -> tuple[np.ndarray, ...]:
    """A reference of one of the volume files against core.media's march through the grids
    it stores: (its visibility, the lit pixels clear of the figure's shadow, those on the
    ground, the oracle's visibility, the ground's pixels under the grids' shadow)."""
    from addon.core import media, metrics

    ratio = metrics.reference_ratio(ref.shadowed, ref.unshadowed)
    lit = ref.lit_domain() & ~behind_figure(ref.position)
    ground = lit & (np.abs(ref.position[..., 2]) < 1e-3)
    oracle = np.ones(ratio.shape)
    oracle[lit] = media.visibility(media.grid_optical_depths(ref.light_position, ref.position[lit], ref.grids,
                                                             steps=512))
    return ratio, lit, ground, oracle, ground & (oracle < 0.99)


def save_and_capture(out: Path, reference: Path | None = None, soft_samples: int | None = None) -> None:
    """Save the scene just built to `out` and, with `reference`, capture its OmniWarp
    reference (reference/capture.py; `soft_samples` a pixel) into that .npz."""
    import bpy

    bpy.ops.wm.save_as_mainfile(filepath=str(out))
    if reference is not None:
        from addon.reference.capture import capture

        samples = {} if soft_samples is None else {"soft_samples": soft_samples}
        capture(bpy.context.scene, **samples).save(reference)


def variant_main(argv: list[str] | None, description: str, variants, default: str,
                 build: Callable[[str, Path], object], check: Callable[[str, Path], None]) -> int:
    """The command line of a volume test file with variants (make_cloud_blend.py,
    make_shader_density_blend.py): OUT.blend [--variant NAME] [--reference OUT.npz]
    [--soft-samples N] [--check OUT.npz]; `build(variant, folder)` makes the scene, `check`
    writes what its test checks instead of saving the file."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("out", type=Path)
    parser.add_argument("--variant", choices=variants, default=default)
    parser.add_argument("--reference", type=Path, default=None)
    parser.add_argument("--soft-samples", type=int, default=None)
    parser.add_argument("--check", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.check is not None:
        check(args.variant, args.check)
        return 0
    build(args.variant, args.out.parent)
    save_and_capture(args.out, args.reference, args.soft_samples)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--noise", action="store_true")
    parser.add_argument("--variant", choices=sorted(VARIANTS), default="beside")
    parser.add_argument("--light-size", type=float, default=0.0, help="the light's radius in metres (0: hard)")
    parser.add_argument("--reference", type=Path, default=None)
    args = parser.parse_args(argv)
    build(args.noise, args.variant, args.light_size)
    save_and_capture(args.out, args.reference)
    return 0


if __name__ == "__main__":
    sys.exit(main())
