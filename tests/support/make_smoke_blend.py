"""A smoke simulation set up as an artist starts one, not baked (issue 43):

    python tests/support/make_smoke_blend.py OUT.blend

The volume tests' ground, figure, light and camera (make_fog_blend.py's `stage`) and a 0.3 m cube emitter under Object > Quick Effects > Quick Smoke: a gas domain box
around it (Principled Volume, density 5 times the simulation's density grid) that reaches
above the light. Mantaflow does not run in the PyPI bpy (its scripts fail on first use), so
the domain holds no smoke: Cycles renders it as empty Volume geometry and the emitter,
still drawn, is the only shadow besides the figure's. Mantaflow's tracebacks on stderr
are expected.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

EMITTER_SIZE, EMITTER_AT = 0.3, (0.0, 0.0, 0.4)


def build():
    """The scene in the running Blender; returns (scene, the domain object)."""
    import bpy

    from tests.support.make_fog_blend import stage

    scene, _ = stage("smoke")
    bpy.ops.mesh.primitive_cube_add(size=EMITTER_SIZE, location=EMITTER_AT)
    emitter = bpy.context.active_object
    emitter.name = "Emitter"
    emitter.select_set(True)
    bpy.ops.object.quick_smoke()
    domain = next(o for o in scene.objects if any(m.type == "FLUID" and m.fluid_type == "DOMAIN"
                                                  for m in o.modifiers))
    return scene, domain


def main(argv: list[str] | None = None) -> int:
    import bpy

    from addon.reference.blend_file import free_fluids_at_exit

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    args = parser.parse_args(argv)
    build()
    bpy.ops.wm.save_as_mainfile(filepath=str(args.out))
    free_fluids_at_exit()  # or Mantaflow crashes the exit
    return 0


if __name__ == "__main__":
    sys.exit(main())
