"""The `eevee` method row: Blender's own EEVEE shadows, measured like the Cycles reference.

EEVEE renders the same scene, camera and light twice with the reference set-up of
`capture.py` (white diffuse override, black world, transparent film, hard light):
once with shadows and once with the light's shadow casting off. Visibility is
shadowed / unshadowed >= 0.5 of the Diffuse Light pass, exactly like the Cycles
reference (`metrics.reference_visibility`).

One GL owner per process (docs/design.md section 3): EEVEE uses Blender's GL, the CLI
uses moderngl, and after an EEVEE render moderngl reads back NaN. So EEVEE runs in
a child process, and arrays travel through files:

    python -m addon.reference.eevee --preset NAME [--size WxH] --out DIR [--settings default,fine]
    python -m addon.reference.eevee --blend FILE [--light NAME] [--camera NAME] --out DIR
    python -m addon.reference.eevee --scene-spec SPEC.npz --out DIR

The child writes `DIR/eevee_<setting>.npz` per setting and a `DIR/eevee.json`
summary. The parent side, `eevee_rows.py`, needs only numpy (its mismatch images are
written by core/png.py); it runs the child and turns its output into compare rows. A
scene given as a `SceneSpec` travels as a file (`scene_spec_file.py`).

EEVEE Next facts used here (verified on 5.2.3):
- the engine id is `BLENDER_EEVEE` in 5.x, `BLENDER_EEVEE_NEXT` in 4.2-4.5;
- `Light.shadow_maximum_resolution` is a world-space texel size in metres (RNA
  default 0.001); it is a *cap*: the virtual shadow map picks its LOD per pixel
  footprint and never goes finer than this. At 640x480 the footprint is coarser
  than 1 mm almost everywhere, so "fine" (0.25 mm) gave the same mask as "default";
- a huge light influence radius (from a tiny `light_threshold`) lost the shadow of
  room_omni's lamp shade entirely (most likely the radius sets the shadow maps'
  depth range), so the radius is set from the scene instead (`light_reach`);
- EEVEE renders in background mode without `gpu.init()`;
- the Diffuse Light pass is written as the EXR channels `<layer>.Diffuse Direct.RGB`
  (`DiffDir` before 5.0),
  in half precision (11 significant bits), which is ample for a 0.5 threshold.
"""
from __future__ import annotations

import argparse
import json
import logging
import math
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core import metrics
from ..core.errors import (
    InputError,
    OmniWarpError,
    ReferenceCaptureError,
    report_error,
)
from ..core.scene import parse_size
from ..compat import blender as blender_compat
from .blend_file import open_scene
from .pass_files import save_render_result
from .scene_spec_file import load_scene_spec

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

log = logging.getLogger(__name__)

SETTINGS = ("default", "fine")  # measured by default
KNOWN_SETTINGS = ("default", "fine", "coarse")
FINE_FACTOR = 4.0  # "fine" caps the texel size at default / FINE_FACTOR
COARSE_FACTOR = 16.0  # "coarse" (on request) caps it at default x COARSE_FACTOR
PIXEL_FILTER_WIDTH = 0.01  # px, as the Cycles reference
# The light's influence radius (custom distance) is REACH_FACTOR x the farthest rendered
# bounding-box corner. An unbounded radius (a tiny light_threshold) lost the shadow of
# room_omni's lamp shade entirely. Its smooth falloff
# near the radius scales shadowed and unshadowed alike, so the ratio is unaffected.
REACH_FACTOR = 2.0
PROGRESS_PREFIX = "omniwarp-eevee: "
DEFAULT_TIMEOUT_S = 1800.0
# What EEVEE Next shadows each light with: a point light with up to 6 cube-face tilemaps, a
# spot (180 degrees or narrower) with up to 5, a sun with a clipmap of tilemaps about the view.
TILEMAPS = {"omni": "6 cube-face tilemaps", "hemi": "5 tilemaps", "spot": "up to 5 tilemaps",
            "sun": "a clipmap of tilemaps"}
ROW_NOTE = ("EEVEE times are whole renders (shading included); no map resolution, passes or texels: "
            "EEVEE's virtual shadow maps are paged tilemaps (6 per omni light, up to 5 per hemi or spot, "
            "a clipmap per sun), not counted draws")

AREA_AS_SPOT_NOTE = ("; the hard area light drawn as a 180-degree spot at its centre (EEVEE shades an area "
                     "light under about 1 cm across as if all were in shadow)")

Progress = Callable[[str], None]


# ----------------------------------------------------------------------------
# child side (bpy)
# ----------------------------------------------------------------------------
@dataclass(frozen=True)
class EeveeSetting:
    """One named shadow setting: the light's world-space texel-size cap."""

    name: str
    shadow_maximum_resolution: float  # metres per texel (a cap; smaller is finer)


def parse_settings(text: str | Sequence[str]) -> tuple[str, ...]:
    """Comma list (or sequence) of setting names out of `KNOWN_SETTINGS`."""
    names = tuple(s.strip() for s in (text.split(",") if isinstance(text, str) else text) if s.strip())
    if not names:
        raise InputError(f"no EEVEE settings given; known: {', '.join(KNOWN_SETTINGS)}")
    for name in names:
        if name not in KNOWN_SETTINGS:
            raise InputError(f"unknown EEVEE setting {name!r}; known: {', '.join(KNOWN_SETTINGS)}")
    if len(set(names)) != len(names):
        raise InputError(f"EEVEE settings repeat a name: {','.join(names)}")
    return names


def eevee_engine_id() -> str:
    """The EEVEE (Next) engine id this Blender offers."""
    import bpy

    engine = blender_compat.eevee_engine_id()
    if engine is not None:
        return engine
    raise ReferenceCaptureError(
        f"Blender {bpy.app.version_string} has no EEVEE Next (virtual shadow maps); the eevee row needs 4.2 or later"
    )


def resolve_settings(names: Sequence[str], light: "bpy.types.Light") -> list[EeveeSetting]:
    """The texel-size cap of each named setting; "default" is the RNA default of the light's type."""
    default = float(light.bl_rna.properties["shadow_maximum_resolution"].default)
    values = {"default": default, "fine": default / FINE_FACTOR, "coarse": default * COARSE_FACTOR}
    return [EeveeSetting(name, values[name]) for name in names]


def _render_to(scene, view_layer, path: Path) -> float:
    """Render one still with EEVEE, then save it to `path`; return the render's wall ms (save excluded)."""
    import bpy

    start = time.perf_counter()
    result = bpy.ops.render.render(write_still=False, scene=scene.name, layer=view_layer.name)
    ms = 1000.0 * (time.perf_counter() - start)
    if "FINISHED" not in result:
        raise ReferenceCaptureError(f"EEVEE render of scene {scene.name!r} failed: {result}")
    save_render_result(scene, path, "EEVEE render")
    return ms


def _renderer_string() -> str:
    import bpy
    import gpu

    try:
        gl = f"{gpu.platform.renderer_get()} | {gpu.platform.version_get()}"
    except (RuntimeError, SystemError, AttributeError) as exc:
        log.warning("cannot query the GL renderer: %s", exc)
        gl = "unknown GL renderer"
    return f"{gl} (EEVEE, Blender {bpy.app.version_string})"


def light_reach(depsgraph, light_obj, visible: set[str]) -> float:
    """Distance from the light to the farthest bounding-box corner of the rendered geometry."""
    from ..readers.render_geometry import GEOMETRY_TYPES

    origin = np.array(light_obj.matrix_world.translation, dtype=np.float64)
    reach = 0.0
    for inst in depsgraph.object_instances:
        obj = inst.object
        owner = (inst.parent if inst.is_instance else obj).original
        if obj.type not in GEOMETRY_TYPES or owner.name_full not in visible:
            continue
        corners = np.array([tuple(c) for c in obj.bound_box], dtype=np.float64)
        matrix = np.array(inst.matrix_world, dtype=np.float64)
        world = corners @ matrix[:3, :3].T + matrix[:3, 3]
        distances = np.linalg.norm(world - origin, axis=1)
        if np.all(np.isfinite(distances)):
            reach = max(reach, float(distances.max()))
    return reach


def _remove_dir(path: Path) -> None:
    try:
        shutil.rmtree(path)
    except OSError as exc:
        log.warning("could not remove temporary folder %s: %s", path, exc)


def _area_as_hemi_spot(light_obj, s) -> None:
    """A hard area light, for EEVEE: a 180-degree spot of no radius at its centre, facing
    the same way (the same point and the same half space, so the same shadows). EEVEE 5.2
    shades an area light under about 1 cm across as if nearly every pixel were in shadow:
    on soft_softbox under --hard, 91.8 % error at 1e-5 to 5 mm, 0.106 % at 1 cm (2026-12-07);
    Cycles' reference keeps its tiny area light (light_size.HARD_AREA_SIZE)."""
    s(light_obj.data, "type", "SPOT")
    spot = light_obj.data  # the datablock seen as a spot now (its Python type changed)
    s(spot, "spot_size", math.pi)
    s(spot, "spot_blend", 0.0)
    s(spot, "shadow_soft_size", 0.0)


def _apply_eevee_settings(scene, view_layer, light_obj, visible: set[str], engine: str,
                          filepath: str, overrides, hard: bool = False) -> dict[str, Any]:
    """The reference set-up for EEVEE (the light's size as in the Cycles reference, white
    diffuse, black world); returns what was set."""
    from ..readers import light_size
    from . import reference_materials
    from .capture import black_world, set_pass_output

    s = overrides.set
    render = scene.render
    s(render, "engine", engine)
    eevee = scene.eevee
    s(eevee, "taa_render_samples", 1)
    s(eevee, "use_shadows", True, optional=True)
    s(eevee, "shadow_resolution_scale", 1.0, optional=True)
    # shadow_pool_size stays as the scene has it (512 MB by default): on llvmpipe a 1024 MB
    # pool added ~250 ms to every render; room_omni, room_hemi and courtyard fit in 512 MB.
    s(eevee, "use_shadow_jitter_viewport", False, optional=True)
    s(eevee, "use_raytracing", False, optional=True)
    s(eevee, "use_fast_gi", False, optional=True)
    s(eevee, "use_overscan", False, optional=True)
    s(eevee, "clamp_surface_direct", 0.0, optional=True)
    s(eevee, blender_compat.EEVEE_DIRECT_LIGHT, 1.0, optional=True)  # 5.0+ (blender_compat.line_gaps)
    # use_bloom (legacy EEVEE) is left alone: on 4.2.23 setting it False removed every
    # EEVEE Next shadow (docs/versions.md), and EEVEE Next has no bloom to turn off.
    s(eevee, "use_gtao", False, optional=True)
    s(eevee, "use_ssr", False, optional=True)
    s(render, "filter_size", PIXEL_FILTER_WIDTH)
    set_pass_output(render, filepath, overrides)
    camera = scene.camera.data
    if getattr(getattr(camera, "dof", None), "use_dof", False):
        s(camera.dof, "use_dof", False)

    s(scene, "world", black_world(overrides))
    s(view_layer, "use_pass_combined", True)
    s(view_layer, "use_pass_diffuse_direct", True)
    s(view_layer, "samples", 0)
    # Keeps each material's transparent shadows, and its volumes as EEVEE renders them.
    reference_materials.apply(scene, view_layer, overrides, shadow_rays_only=False)

    light = light_obj.data
    area_as_spot = hard and light.type == "AREA"
    if area_as_spot:
        _area_as_hemi_spot(light_obj, s)
        light = light_obj.data
    elif hard:
        light_size.make_hard(light_obj, s)  # else the file's size, as Cycles renders it
    # use_shadow stays the file's, as in the Cycles reference: off, nothing blocks the light.
    s(light, "use_shadow_jitter", False, optional=True)
    s(light, "shadow_jitter", False, optional=True)  # an older name
    s(light, "shadow_filter_radius", 0.0, optional=True)
    s(light, "use_absolute_resolution", False, optional=True)
    if hard:
        s(light, "use_soft_falloff", False, optional=True)
    from .capture import evaluated_depsgraph

    reach = light_reach(evaluated_depsgraph(scene, view_layer), light_obj, visible)
    if reach <= 0.0:
        raise ReferenceCaptureError(f"scene {scene.name!r} has no rendered geometry for EEVEE to shadow")
    s(light, "use_custom_distance", True, optional=True)
    s(light, "cutoff_distance", REACH_FACTOR * reach, optional=True)
    s(light, "diffuse_factor", 1.0, optional=True)
    for obj in scene.objects:
        if getattr(obj, "is_holdout", False):
            s(obj, "is_holdout", False)
        if obj.type == "LIGHT" and obj != light_obj and obj.name_full in visible:
            s(obj, "hide_render", True)  # only the measured light may light the scene
    return {
        "engine": engine,
        "scene.eevee.taa_render_samples": 1,
        "scene.eevee.shadow_resolution_scale": float(getattr(eevee, "shadow_resolution_scale", 1.0)),
        "scene.eevee.shadow_pool_size": str(getattr(eevee, "shadow_pool_size", "")),
        "scene.eevee.shadow_ray_count": int(getattr(eevee, "shadow_ray_count", 0)),
        "scene.eevee.shadow_step_count": int(getattr(eevee, "shadow_step_count", 0)),
        "light.use_custom_distance": bool(getattr(light, "use_custom_distance", False)),
        "light.cutoff_distance": float(getattr(light, "cutoff_distance", 0.0)),
        "scene.render.filter_size": float(render.filter_size),
        "light.shadow_soft_size": float(light.shadow_soft_size),
        "light.use_shadow_jitter": bool(getattr(light, "use_shadow_jitter", False)),
        "light.shadow_filter_radius": float(getattr(light, "shadow_filter_radius", 0.0)),
        "light.use_absolute_resolution": bool(getattr(light, "use_absolute_resolution", False)),
        "light.shadow_buffer_clip_start": float(getattr(light, "shadow_buffer_clip_start", 0.0)),
        "light.area_as_spot": bool(area_as_spot),
    }


def _diffuse(channels: dict[str, np.ndarray], layer: str, hit: np.ndarray) -> np.ndarray:
    from .pass_files import stack_pass

    diffuse = stack_pass(channels, layer, blender_compat.exr_pass_name("Diffuse Direct"), "RGB")
    return np.where(hit, diffuse.mean(axis=-1), 0.0).astype(np.float32)


def render_eevee(scene: "bpy.types.Scene", out_dir: Path, settings: Sequence[str] = SETTINGS, *,
                 light: "bpy.types.Object | str | None" = None, view_layer: str | None = None,
                 frames: int = 1, progress: Progress | None = None, hard: bool = False) -> dict[str, Any]:
    """Render `scene` with EEVEE per setting into `out_dir`; the scene is left as it was.
    The light keeps its size unless `hard` (as the Cycles reference, capture.capture).

    Order: one warm-up render (shader compilation, timed as `warmup_ms`), then per
    setting `frames` timed shadowed renders (median `render_ms`), then one
    unshadowed render shared by every setting (the cap only affects shadows).
    Returns the summary also written to `out_dir/eevee.json`.
    """
    import bpy

    from .capture import (Overrides, emission_of, evaluated_depsgraph, output_size, pick_light, pick_view_layer,
                          render_visible_objects)
    from .pass_files import pass_channel, read_exr_channels

    if frames < 1:
        raise InputError(f"frames must be at least 1, got {frames}")
    names = parse_settings(settings)
    engine = eevee_engine_id()
    cam_obj = scene.camera
    if cam_obj is None or cam_obj.type != "CAMERA":
        raise ReferenceCaptureError(f"scene {scene.name!r} has no active camera; the eevee row needs one")
    layer = pick_view_layer(scene, view_layer)
    evaluated_depsgraph(scene, layer)  # syncs a new scene's layer collections
    visible = render_visible_objects(layer)
    light_obj = pick_light(scene, visible, light)
    emission = emission_of(light_obj.data)
    if emission not in TILEMAPS:
        raise InputError(f"light {light_obj.name!r} is a {emission} light; the eevee row needs a point, spot, "
                         "sun or area light")
    chosen = resolve_settings(names, light_obj.data)
    say = progress or (lambda message: None)
    width, height = output_size(scene)
    out_dir.mkdir(parents=True, exist_ok=True)

    tmpdir = Path(tempfile.mkdtemp(prefix="omniwarp_eevee_"))
    overrides = Overrides()
    try:
        cap_in_file = float(light_obj.data.shadow_maximum_resolution)
        used = _apply_eevee_settings(scene, layer, light_obj, visible, engine, str(tmpdir / "pass"), overrides,
                                     hard)
        exr = tmpdir / "pass.exr"
        overrides.set(light_obj.data, "shadow_maximum_resolution", chosen[0].shadow_maximum_resolution)
        say(f"EEVEE warm-up render (shader compilation, {width}x{height})")
        warmup_ms = _render_to(scene, layer, exr)
        shadowed: dict[str, tuple[np.ndarray, np.ndarray, list[float]]] = {}
        for setting in chosen:
            light_obj.data.shadow_maximum_resolution = setting.shadow_maximum_resolution
            times = []
            for i in range(frames):
                say(f"EEVEE render, setting {setting.name} (cap {setting.shadow_maximum_resolution:g} m), "
                    f"frame {i + 1}/{frames}")
                times.append(_render_to(scene, layer, exr))
            channels = read_exr_channels(exr)
            hit = pass_channel(channels, layer.name, "Combined.A") > 0.5
            shadowed[setting.name] = (hit, _diffuse(channels, layer.name, hit), times)
        overrides.set(light_obj.data, "use_shadow", False)
        say("EEVEE render without shadows")
        unshadowed_ms = _render_to(scene, layer, exr)
        channels = read_exr_channels(exr)
        free_hit = pass_channel(channels, layer.name, "Combined.A") > 0.5
        unshadowed = _diffuse(channels, layer.name, free_hit)
        renderer = _renderer_string()
    finally:
        try:
            overrides.restore()
        finally:
            _remove_dir(tmpdir)

    if unshadowed.shape != (height, width):
        raise ReferenceCaptureError(f"EEVEE output is {unshadowed.shape[1]}x{unshadowed.shape[0]}, "
                                    f"expected {width}x{height}")
    summary: dict[str, Any] = {
        "scene": scene.name,
        "light": light_obj.name,
        "camera": cam_obj.name,
        "emission": emission,
        "resolution": [width, height],
        "blender_version": bpy.app.version_string,
        "renderer": renderer,
        "warmup_ms": warmup_ms,
        "unshadowed_ms": unshadowed_ms,
        "frames": frames,
        "render_settings": used,
        "light_shadow_maximum_resolution_in_file": cap_in_file,  # overridden by each setting
        "settings": {},
    }
    for setting in chosen:
        hit, lit, times = shadowed[setting.name]
        visibility = metrics.reference_visibility(lit, unshadowed)
        render_ms = float(np.median(times))
        np.savez_compressed(out_dir / f"eevee_{setting.name}.npz", visibility=visibility, shadowed=lit,
                            unshadowed=unshadowed, hit=hit, render_ms=np.asarray(times, dtype=np.float64),
                            warmup_ms=np.float64(warmup_ms))
        summary["settings"][setting.name] = {
            "shadow_maximum_resolution": setting.shadow_maximum_resolution,
            "render_ms": render_ms,
            "render_ms_frames": times,
            "file": f"eevee_{setting.name}.npz",
            "lit_pct": 100.0 * float(visibility.mean()),
        }
        log.info("EEVEE %s: cap %g m, render %.0f ms", setting.name, setting.shadow_maximum_resolution, render_ms)
    (out_dir / "eevee.json").write_text(json.dumps(summary, indent=1), encoding="utf-8")
    return summary


def main(argv: Sequence[str] | None = None) -> int:
    """Entry of the EEVEE child process: exit 0 done, 2 with one line (any OmniWarpError), 1 a bug."""
    parser = argparse.ArgumentParser(prog="python -m addon.reference.eevee",
                                     description="Render EEVEE's shadows for the eevee method row.")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--preset", help="a preset name")
    source.add_argument("--blend", help="a .blend file (its active scene and camera)")
    source.add_argument("--scene-spec", help="a SceneSpec written by save_scene_spec")
    parser.add_argument("--light", help="with --blend: the light object")
    parser.add_argument("--camera", help="with --blend: the camera object")
    parser.add_argument("--frame", type=int, help="with --blend: the frame of its animation to render")
    parser.add_argument("--size", default="640x480", help="with --preset: camera size WxH")
    parser.add_argument("--out", required=True, help="folder for eevee_<setting>.npz and eevee.json")
    parser.add_argument("--settings", default=",".join(SETTINGS), help="comma list of: " + ", ".join(KNOWN_SETTINGS))
    parser.add_argument("--frames", type=int, default=1, help="timed renders per setting (median)")
    parser.add_argument("--hard", action="store_true", help="give the light no size (as compare --hard)")
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")

    def say(message: str) -> None:
        print(PROGRESS_PREFIX + message, flush=True)

    try:
        if (args.light or args.camera or args.frame is not None) and not args.blend:
            raise InputError("--light, --camera and --frame apply to --blend only")
        settings = parse_settings(args.settings)
        from .blender_scene import build_blender_scene, remove_blender_scene

        built = None
        if args.preset:
            from ..core.presets import build_preset

            built = scene = build_blender_scene(build_preset(args.preset, parse_size(args.size)))
        elif args.scene_spec:
            built = scene = build_blender_scene(load_scene_spec(args.scene_spec))
        else:
            scene = open_scene(Path(args.blend), args.camera, args.light, args.frame)
        try:
            summary = render_eevee(scene, Path(args.out), settings, light=args.light, frames=args.frames,
                                   progress=say, hard=args.hard)
        finally:
            if built is not None:
                remove_blender_scene(built)
        say(f"done: warm-up {summary['warmup_ms']:.0f} ms; " + ", ".join(
            f"{name} {entry['render_ms']:.0f} ms" for name, entry in summary["settings"].items()))
        return 0
    except OmniWarpError as exc:
        return report_error("omniwarp eevee", exc)


if __name__ == "__main__":
    sys.exit(main())
