"""Headless preview with the Blender `gpu` backend: `omniwarp preview` runs this module
in its own process (one GL owner per process, docs/design.md section 3).

    python -m addon.blender.headless --preset NAME --reference REF.npz --out DIR
    python -m addon.blender.headless --blend FILE --reference REF.npz --out DIR [--light NAME]

It loads the scene, picks the lights and hands them to `preview.run`, which draws,
offscreen and with the scene camera's matrices, exactly what the viewport preview
draws: the shadow composite (`preview.png`) and the map overlay (`overlay.png`);
`preview.json` holds the error against the Cycles reference and the times.
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from ..core import methods as method_registry
from ..core.blockers import pieces
from ..core.errors import OmniWarpError, report_error
from ..core.scene import LightSpec
from ..reference.data import ReferenceData
from ..render.pipeline import ShadowSettings, settings_for
from ..render.resident import ResidentScene
from . import properties, registration
from .preview import run

log = logging.getLogger(__name__)


def _scene_lights(scene, depsgraph, reference: ReferenceData, light_name: str | None,
                  default: ShadowSettings) -> list[tuple[str, LightSpec, ShadowSettings]]:
    """Lights to preview: the viewport's (OmniWarp enabled), else the reference's own
    light with `default` settings (presets carry no OmniWarp settings of their own)."""
    chosen = [entry for entry in properties.enabled_lights(scene, depsgraph) if not light_name or entry[0] == light_name]
    if chosen:
        return chosen
    # With the size the reference rendered it at: a sized preset's light keeps its penumbrae.
    light = reference.light_spec()
    return [(reference.meta.get("light", "light"), light, default)]


def default_settings(method: str | None, emission: str, resolution: int) -> ShadowSettings:
    """Settings of the lights without OmniWarp settings: `method` (the registry's default
    for the emission when None), with its cut and edge AA; an InputError if it does not fit."""
    name = method or method_registry.default_method(emission)
    method_registry.check_fits(name, emission, pipeline_only=True)
    return settings_for(name, resolution, emission)


def _load_scene(args: argparse.Namespace, reference: ReferenceData):
    """The scene to preview: the preset built anew, or the .blend loaded (nothing is saved back)."""
    import bpy

    if args.preset:
        from ..core.presets import build_preset
        from ..reference.blender_scene import build_blender_scene

        return build_blender_scene(build_preset(args.preset, reference.resolution))
    from ..reference.blend_file import open_blend

    open_blend(args.blend)
    return bpy.context.scene


def main(argv: list[str] | None = None) -> int:
    """Entry of the preview subprocess."""
    parser = argparse.ArgumentParser(prog="omniwarp-preview-worker")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--preset")
    source.add_argument("--blend")
    parser.add_argument("--light")
    parser.add_argument("--reference", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--method", default=None)  # None: the registry's default for the reference's light
    parser.add_argument("--resolution", type=int, default=1024)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        from ..reference.capture import evaluated_depsgraph, pick_view_layer
        from ..readers.render_geometry import render_triangles
        from ..readers.shadow_rule import rules_for, shadow_inputs

        reference = ReferenceData.load(args.reference)
        default = default_settings(args.method, reference.emission, args.resolution)
        # Load first, register once after: the file's stored light settings (the
        # IDProperties under "omniwarp") are then read through the new pointers, and the
        # runtime handlers are not dropped by the file load.
        scene = _load_scene(args, reference)
        registration.register()
        try:
            layer = pick_view_layer(scene)
            depsgraph = evaluated_depsgraph(scene, layer)
            lights = _scene_lights(scene, depsgraph, reference, args.light, default)
            # The scene as the renderer reads it (render-level modifiers, hide_render),
            # like the Cycles reference it is measured against; the interactive
            # viewport reads its own depsgraph (scene_cache.py).
            found = render_triangles(scene, layer)

            def resident(keep, key) -> ResidentScene:
                # With the see-through materials, for the G-buffer and each light's blockers,
                # and the hair and points as pieces (the G-buffer leaves those out).
                scene = ResidentScene.of_triangles(found.select(keep), surface=found.select_surface(keep))
                held = pieces(found.select_spheres(keep), found.select_strands(keep))
                if len(held):
                    scene.set_pieces(f"pieces:{key}", held)
                for index, grid in enumerate(found.select_grids(keep)):  # Volume objects' density
                    scene.set_grid(f"grid:{key}:{index}", grid)
                return scene

            rules = rules_for(scene, [name for name, _, _ in lights])
            for name, rule in rules.items():  # what blocks the light in Cycles but is not drawn
                for note in found.left_out.notes(rule.blocks):
                    log.warning("light %r: %s", name, note)
            seen, occluders = shadow_inputs(resident, rules)
            report = run(reference, lights, seen, Path(args.out), occluders=occluders)
        finally:
            registration.unregister()
        print(json.dumps({k: report[k] for k in ("error_pct", "evaluated_pixels")}))
        return 0
    except OmniWarpError as exc:
        return report_error("omniwarp preview", exc)


if __name__ == "__main__":
    sys.exit(main())
