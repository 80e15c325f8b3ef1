"""Fog boxes whose density is a shader texture (issue 43, `readers/shader_density.py`):

    python tests/support/make_shader_density_blend.py OUT.blend [--variant NAME] [--reference OUT.npz]
        [--soft-samples N] [--check OUT.npz]

- `noise`: make_fog_blend.py's `beside` box with `--noise` (a Noise Texture, its Vector
  unlinked: Generated coordinates, times 3 into the Principled Volume's Density);
- `mapped`: the same box, its density a Noise Texture of Object coordinates through a
  Mapping (moved, turned, scaled) and a Map Range (0.35..0.65 to 0..4), with a colour.

`--check` writes what `render_triangles` found (the grid, what it left out, bpy.data's
counts before and after); `--reference` captures the OmniWarp reference (capture.py).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from tests.support.make_fog_blend import variant_main  # noqa: E402

VARIANTS = ("noise", "mapped")
# The extinction per unit density of each variant's Principled Volume (make_fog_blend:
# colour 0.5, no absorption colour: 1; `mapped`: colour 0.8: 0.8 + 0.2 = 1).
SIGMA = {"noise": 1.0, "mapped": 1.0}


def build(variant: str):
    """The scene in the running Blender; returns (scene, fog)."""
    import bpy

    from tests.support.make_fog_blend import build as build_fog

    scene, _, fog = build_fog(noise=True)
    if variant == "mapped":
        tree = bpy.data.materials["Fog"].node_tree
        volume = next(n for n in tree.nodes if n.type == "PRINCIPLED_VOLUME")
        volume.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
        for node in [n for n in tree.nodes if n.type == "MATH"]:
            tree.nodes.remove(node)
        noise = next(n for n in tree.nodes if n.type == "TEX_NOISE")
        noise.inputs["Scale"].default_value = 2.5
        noise.inputs["Detail"].default_value = 3.0
        coords = tree.nodes.new("ShaderNodeTexCoord")
        mapping = tree.nodes.new("ShaderNodeMapping")
        mapping.inputs["Location"].default_value = (0.3, -0.2, 0.1)
        mapping.inputs["Rotation"].default_value = (0.3, 0.5, 0.9)
        mapping.inputs["Scale"].default_value = (1.0, 1.5, 0.7)
        ranged = tree.nodes.new("ShaderNodeMapRange")
        ranged.inputs["From Min"].default_value, ranged.inputs["From Max"].default_value = 0.35, 0.65
        ranged.inputs["To Min"].default_value, ranged.inputs["To Max"].default_value = 0.0, 4.0
        tree.links.new(coords.outputs["Object"], mapping.inputs["Vector"])
        tree.links.new(mapping.outputs["Vector"], noise.inputs["Vector"])
        tree.links.new(noise.outputs["Fac"], ranged.inputs["Value"])
        tree.links.new(ranged.outputs["Result"], volume.inputs["Density"])
    return scene, fog


def check(variant: str, out: Path) -> None:
    import bpy

    from addon.readers.render_geometry import render_triangles

    scene, _ = build(variant)
    counts = lambda: [len(getattr(bpy.data, k)) for k in ("objects", "meshes", "node_groups", "materials")]  # noqa: E731
    before = counts()
    found = render_triangles(scene, scene.view_layers[0])
    after = counts()
    (medium,) = [grid for _, grid in found.grids]
    np.savez(out, density=medium.density, to_index=medium.to_index, sigma=medium.sigma, name=medium.name,
             before=before, after=after, owners=np.array([o.name for o in found.owners], dtype=str),
             left_out=np.array(found.left_out.notes(), dtype=str))


def main(argv: list[str] | None = None) -> int:
    return variant_main(argv, __doc__.splitlines()[0], VARIANTS, "noise", lambda variant, _: build(variant), check)


if __name__ == "__main__":
    sys.exit(main())
