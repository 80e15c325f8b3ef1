"""Render the Cycles ground truth of a Blender scene into a `ReferenceData`.

`capture(scene)` works on any scene with a perspective or orthographic camera (any
sensor fit, lens shift, pixel aspect and resolution percentage) and one point, spot, sun
or area light (the presets, and user .blend files). It temporarily switches the scene to
the reference set-up of docs/design.md section 5 and restores every setting it touched:

- Cycles on the CPU, by default 1 sample at the pixel centre (no pixel jitter,
  Gaussian filter 0.01 px: Cycles ignores the width of a box filter), no denoising,
  no adaptive sampling, light threshold 0, no bounces (direct light only);
- the light keeps its size, as the artist renders it (`light_size.py`: a sphere's
  radius, a sun's angle, an area light's outline), unless `hard` makes it a point (size
  0); a spot's blend is kept but logged, since it fades the light towards the cone's
  edge; other lights are hidden from the render;
- every material is replaced by a white diffuse one (view-layer material override),
  which also writes the Geometry node's True Normal into a shader AOV;
- a black world and a transparent film (its alpha is the hit mask);
- the camera's depth of field off (every pixel's ray starts at the pinhole).

It renders twice: once as is and once with the light's shadow casting off, which
gives the `shadowed` and `unshadowed` Diffuse Direct passes. A sized light renders each
pass twice, with `soft_samples` / 2 samples and two seeds: the halves' mean is the
reference, and half their difference, `visibility_noise`, its own noise per pixel. The
same seed in the shadowed and unshadowed renders draws the same light points, so their
ratio is the share of those points the pixel sees. A scene with a medium (a volume
shader; `reference_materials.media`) renders so too, whatever its light: a density that
varies makes the shadows' transmittance noisy. The stored triangles are the ones that
block the light: the render depsgraph's geometry (`render_geometry.py`; the light's and
camera's matrices too) sorted by `shadow_rule.ShadowRule`, which follows ray visibility,
shadow linking and the light's own `use_shadow` as Cycles does. `bpy` is imported lazily.
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ..core import interrupt, validate
from ..core.camera import Window, blender_camera_window, window_fov_deg
from ..core.errors import InputError, ReferenceCaptureError
from ..core.light_shape import POINT
from ..core.scene import orthonormalize, spot_emission
from ..compat import blender as blender_compat
from ..readers import light_size
from ..readers.render_geometry import GEOMETRY_TYPES, render_triangles
from ..readers.shadow_rule import ShadowRule
from . import reference_materials
from .data import ReferenceData
from .reference_materials import AOV_NORMAL
from .pass_files import PassReading, read_exr_channels, read_passes, save_render_result

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

log = logging.getLogger(__name__)

# Part of the cache key: bump whenever the capture settings or outputs change.
# 2: see-through materials keep their alpha, triangles their surface (UVs, alpha maps);
# 3: the light's and camera's matrices are the render depsgraph's.
CAPTURE_VERSION = 3
# Transparent bounces a camera or shadow ray may take through see-through surfaces.
TRANSPARENT_BOUNCES = 256

# One sample is exact: a point light with direct light only has no randomness, and
# on 5.2 later samples land slightly off the pixel centre (see _apply_render_settings),
# where data passes (Position) keep the first sample only.
DEFAULT_SAMPLES = 1
# A sized light's samples per pixel, both halves together: the reference's noise then is
# about 1 % of visibility in a penumbra (reported per row as reference_noise_pct).
SOFT_SAMPLES = 256
SOFT_SEEDS = (0, 1)  # one per half
PIXEL_FILTER_WIDTH = 0.01  # px; effectively no filter (Blender's minimum)
# Light types the reference accepts. A SUN has a direction only: nothing in the capture
# depends on its position (Cycles' culling is off, and there is no near/far to fit).
LIGHT_TYPES = {"POINT", "SPOT", "SUN", "AREA"}
# A sun angle or spot blend at or below this counts as hard.
_SOFT_TOLERANCE = 1e-6

Progress = Callable[[str], None]


class Overrides:
    """Set attributes temporarily and put the old values back in reverse order."""

    def __init__(self) -> None:
        self._saved: list[tuple[Any, str, Any]] = []

    def set(self, owner: Any, attr: str, value: Any, optional: bool = False) -> None:
        """Set `owner.attr = value`, remembering the old value.

        `optional` attributes that this Blender version lacks are skipped (logged).
        """
        if optional and not hasattr(owner, attr):
            log.debug("%s has no %r in this Blender version; skipped", type(owner).__name__, attr)
            return
        old = getattr(owner, attr)
        if not isinstance(old, str) and hasattr(old, "__len__") and not hasattr(old, "bl_rna"):
            old = tuple(old)  # bpy arrays (colors, vectors) are views; keep a copy
        self._saved.append((owner, attr, old))
        setattr(owner, attr, value)

    def on_restore(self, fn: Callable[[], None]) -> None:
        """Run `fn` on restore (after the attributes set after it are restored)."""
        self._saved.append((None, "", fn))

    def restore(self) -> None:
        errors = []
        for owner, attr, old in reversed(self._saved):
            try:
                if owner is None:
                    old()
                else:
                    setattr(owner, attr, old)
            except (AttributeError, TypeError, ValueError, RuntimeError, ReferenceError) as exc:
                # Keep restoring the rest; report every failure at the end.
                errors.append(f"{attr or getattr(old, '__name__', 'cleanup')}: {exc}")
        self._saved.clear()
        if errors:
            raise ReferenceCaptureError("could not restore scene settings after capture: " + "; ".join(errors))


# ----------------------------------------------------------------------------
# scene inspection
# ----------------------------------------------------------------------------
def render_visible_objects(view_layer: "bpy.types.ViewLayer") -> set[str]:
    """Names (name_full) of objects Cycles renders in this view layer."""
    names: set[str] = set()

    def walk(layer_collection: "bpy.types.LayerCollection") -> None:
        if layer_collection.exclude or layer_collection.collection.hide_render:
            return
        for obj in layer_collection.collection.objects:
            if not obj.hide_render:
                names.add(obj.name_full)
        for child in layer_collection.children:
            walk(child)

    walk(view_layer.layer_collection)
    return names


def pick_view_layer(scene: "bpy.types.Scene", name: str | None = None) -> "bpy.types.ViewLayer":
    """The named view layer, else the first one enabled for rendering."""
    if name is not None:
        if name not in scene.view_layers:
            raise ReferenceCaptureError(f"scene {scene.name!r} has no view layer {name!r}")
        return scene.view_layers[name]
    for layer in scene.view_layers:
        if layer.use:
            return layer
    raise ReferenceCaptureError(f"scene {scene.name!r} has no view layer enabled for rendering")


def pick_light(scene: "bpy.types.Scene", visible: set[str], light: "bpy.types.Object | str | None"):
    """The point, spot, sun or area light object to capture; the scene must hold exactly one unless named."""
    import bpy

    # The messages keep the phrase "spot, sun or area light" that callers and tests match.
    if light is not None:
        obj = bpy.data.objects.get(light) if isinstance(light, str) else light
        if obj is None or obj.type != "LIGHT" or obj.data.type not in LIGHT_TYPES:
            raise ReferenceCaptureError(f"{light!r} is not a point, spot, sun or area light")
        if obj.name not in scene.objects:
            raise ReferenceCaptureError(f"light {obj.name!r} is not in scene {scene.name!r}")
        return obj
    candidates = [
        o for o in scene.objects
        if o.type == "LIGHT" and o.data.type in LIGHT_TYPES and o.name_full in visible
    ]
    if not candidates:
        raise ReferenceCaptureError(
            f"scene {scene.name!r} has no rendered point, spot, sun or area light; the reference needs one"
        )
    if len(candidates) > 1:
        names = ", ".join(sorted(o.name for o in candidates))
        raise ReferenceCaptureError(
            f"scene {scene.name!r} has several point, spot, sun or area lights ({names}); name the one to capture"
        )
    return candidates[0]


def emission_of(light: "bpy.types.Light") -> str:
    """"omni" (POINT), "hemi" (SPOT wider than 179 degrees, or AREA), "spot" or "sun".

    A blend does not change the emission: it fades the light inside the cone, whose
    edge stays where spot_size puts it.
    """
    if light.type == "POINT":
        return "omni"
    if light.type == "SUN":
        return "sun"
    if light.type == "AREA":
        return "hemi"  # one-sided: it lights the half space in front of it
    return spot_emission(light.spot_size)


def _warn_soft_light(light_obj: "bpy.types.Object") -> None:
    """Log what makes the captured light differ from the light the shadow maps assume."""
    light = light_obj.data
    if light.type == "SPOT" and light.spot_blend > _SOFT_TOLERANCE:
        log.warning("spot light %r has blend %.3g: the reference's cone edge is soft (light fades towards "
                    "it); visibility (shadowed/unshadowed) is unaffected, but pixels near the edge get "
                    "little light", light_obj.name, light.spot_blend)


def _camera_fov_deg(camera: "bpy.types.Camera", width: int, height: int) -> float:
    """Field of view along the larger image side, for any sensor fit (square pixels)."""
    fit = camera.sensor_fit
    if fit == "AUTO":
        return math.degrees(camera.angle)
    if fit == "HORIZONTAL":
        half = math.tan(camera.angle_x / 2.0)
        if width < height:
            half *= height / width
    else:  # VERTICAL
        half = math.tan(camera.angle_y / 2.0)
        if height < width:
            half *= width / height
    return math.degrees(2.0 * math.atan(half))


def _camera_window(camera: "bpy.types.Camera", render: "bpy.types.RenderSettings", width: int,
                   height: int) -> Window | None:
    """The camera's image window (Blender's rule, `core.camera.blender_camera_window`),
    or None for a centred perspective camera with square pixels: `_camera_fov_deg`
    alone describes that one, and its reference stays what it was before windows."""
    aspect = (float(render.pixel_aspect_x), float(render.pixel_aspect_y))
    square = abs(aspect[0] - aspect[1]) <= 1e-6 * max(aspect)
    shift = (float(camera.shift_x), float(camera.shift_y))
    if camera.type == "PERSP" and square and shift == (0.0, 0.0):
        return None
    return blender_camera_window((width, height), ortho=camera.type == "ORTHO", lens=float(camera.lens),
                                 ortho_scale=float(camera.ortho_scale), sensor_fit=camera.sensor_fit,
                                 sensor_width=float(camera.sensor_width), sensor_height=float(camera.sensor_height),
                                 shift=shift, pixel_aspect=aspect)



def _rigid(matrix) -> np.ndarray:
    """4x4 float64 with the rotation part orthonormalized (object scale dropped)."""
    m = np.array(matrix, dtype=np.float64)
    out = np.eye(4)
    out[:3, :3] = orthonormalize(m[:3, :3])
    out[:3, 3] = m[:3, 3]
    return out


def evaluated_depsgraph(scene: "bpy.types.Scene", view_layer: "bpy.types.ViewLayer | None" = None):
    """The evaluated (viewport) depsgraph of a scene that need not be the active one."""
    import bpy

    # view_layer.depsgraph is None until something evaluates the scene; the context
    # override makes Blender create and evaluate it for this scene and layer.
    with bpy.context.temp_override(scene=scene, view_layer=view_layer or scene.view_layers[0]):
        depsgraph = bpy.context.evaluated_depsgraph_get()
    return depsgraph



# ----------------------------------------------------------------------------
# temporary datablocks
# ----------------------------------------------------------------------------
def black_world(overrides: Overrides):
    import bpy

    world = bpy.data.worlds.new("OmniWarp reference black")
    overrides.on_restore(lambda: bpy.data.worlds.remove(world))
    world.color = (0.0, 0.0, 0.0)  # what a world without nodes shows (a new one before 5.0)
    if blender_compat.uses_nodes(world):
        for node in world.node_tree.nodes:
            if node.type == "BACKGROUND":
                node.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
                node.inputs["Strength"].default_value = 0.0
    return world


def _add_aov(view_layer, overrides: Overrides) -> None:
    existing = view_layer.aovs.get(AOV_NORMAL) if hasattr(view_layer.aovs, "get") else None
    if existing is not None:
        view_layer.aovs.remove(existing)  # left over from a crashed capture
    aov = view_layer.aovs.add()
    aov.name = AOV_NORMAL
    aov.type = "COLOR"
    overrides.on_restore(lambda: view_layer.aovs.remove(view_layer.aovs[AOV_NORMAL]))


def _apply_render_settings(scene, view_layer, light_obj, visible: set[str], samples: int,
                           filepath: str, overrides: Overrides, hard: bool) -> list[str]:
    """Switch the scene to the reference set-up (docs/design.md section 5); returns the
    notes of the reference materials (reference_materials.apply)."""
    s = overrides.set
    render = scene.render
    s(render, "engine", "CYCLES")
    cycles = scene.cycles
    s(cycles, "device", "CPU")
    s(cycles, "samples", samples)
    s(cycles, "use_adaptive_sampling", False)
    s(cycles, "use_denoising", False)
    # Sample the pixel centre, so position and visibility describe the same point.
    # Measured on 5.2.3: BOX ignores the width (Cycles forces 1 px for box) and keeps
    # jittering even with use_pixel_jitter off; GAUSSIAN at 0.01 px with the jitter
    # off puts the first sample within 2e-5 px of the centre.
    s(cycles, "pixel_filter_type", "GAUSSIAN", optional=True)
    s(cycles, "filter_width", PIXEL_FILTER_WIDTH, optional=True)
    s(cycles, "use_pixel_jitter", False, optional=True)
    s(cycles, "seed", 0)
    s(cycles, "use_animated_seed", False)
    # The default 0.01 light threshold drops faint light: it would zero far pixels.
    s(cycles, "light_sampling_threshold", 0.0)
    s(cycles, "sample_clamp_direct", 0.0)
    s(cycles, "sample_clamp_indirect", 0.0)
    for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
        s(cycles, attr, 0)
    # Shadow and camera rays pass see-through surfaces as transparent bounces: as many as
    # a thick canopy needs (an opaque scene takes none).
    s(cycles, "transparent_max_bounces", TRANSPARENT_BOUNCES)
    s(cycles, "use_guiding", False, optional=True)
    # Culling would drop geometry that still casts shadows into the view.
    s(cycles, "use_camera_cull", False, optional=True)
    s(cycles, "use_distance_cull", False, optional=True)
    s(cycles, "use_layer_samples", "USE", optional=True)

    set_pass_output(render, filepath, overrides)

    s(scene, "world", black_world(overrides))
    # Depth of field would start each pixel's ray off the pinhole: its position would not
    # lie on the ray through the pixel centre, which the planning frustum and a preview's
    # G-buffer assume. The shadows themselves do not depend on it.
    camera = scene.camera.data
    if getattr(getattr(camera, "dof", None), "use_dof", False):
        log.info("camera %r: depth of field is off for the reference", scene.camera.name)
        s(camera.dof, "use_dof", False)

    s(view_layer, "use_pass_combined", True)
    s(view_layer, "use_pass_position", True)
    s(view_layer, "use_pass_diffuse_direct", True)
    s(view_layer, "samples", 0)  # 0: use the scene's sample count
    notes = reference_materials.apply(scene, view_layer, overrides)
    s(view_layer.cycles, "use_denoising", False, optional=True)
    _add_aov(view_layer, overrides)

    light = light_obj.data
    if hard:
        light_size.make_hard(light_obj, s)
    # The light's own use_shadow is the file's: off, nothing blocks it (ShadowRule).
    if hard:
        s(light, "use_soft_falloff", False, optional=True)
    s(light_obj, "visible_diffuse", True, optional=True)
    for obj in scene.objects:
        # Catchers and holdouts would change the passes and the alpha mask.
        if getattr(obj, "is_shadow_catcher", False):
            s(obj, "is_shadow_catcher", False)
        if getattr(obj, "is_holdout", False):
            s(obj, "is_holdout", False)
        if obj.type == "LIGHT" and obj != light_obj and obj.name_full in visible:
            s(obj, "hide_render", True)  # only the captured light may light the scene
    return notes


def _disable_shadows(scene, light_obj, overrides: Overrides) -> None:
    """The same light without any occlusion, for the `unshadowed` render."""
    if hasattr(light_obj.data, "use_shadow"):
        # One switch on the light: no shadow rays at all (verified equal to cos/r^2).
        overrides.set(light_obj.data, "use_shadow", False)
        return
    for obj in scene.objects:  # older Blender: stop every object from casting
        if hasattr(obj, "visible_shadow"):
            overrides.set(obj, "visible_shadow", False)


# ----------------------------------------------------------------------------
# render and read
# ----------------------------------------------------------------------------
def set_pass_output(render, filepath: str, overrides: Overrides) -> None:
    """Plain film written as a 32-bit multilayer EXR, shared by the Cycles and EEVEE renders.

    Hit mask from alpha (transparent film); no border, compositing, sequencer, motion
    blur, Freestyle or multiview (stereo would rename every EXR channel per view).
    """
    s = overrides.set
    s(render, "film_transparent", True)
    s(render, "use_border", False)
    s(render, "use_compositing", False)
    s(render, "use_sequencer", False)
    s(render, "use_motion_blur", False)
    s(render, "use_freestyle", False, optional=True)
    s(render, "use_multiview", False)
    s(render, "filepath", filepath)
    s(render, "use_file_extension", True)
    image = render.image_settings
    blender_compat.set_multilayer_exr(image, s)
    s(image, "color_depth", "32")
    s(image, "exr_codec", "ZIP", optional=True)


def _render(scene, view_layer, path: Path, what: str = "Cycles render") -> float:
    """Render one still into `path` (multilayer EXR); return wall seconds.

    Python cannot interrupt the render: `interrupt.blocking` lets the command's own
    process stop at once on Ctrl-C, and otherwise raises as soon as it returns.
    """
    import bpy

    # Blender removes its session folder when the process ends normally; an
    # immediate exit on Ctrl-C must remove it as well.
    if bpy.app.tempdir:
        interrupt.register_temporary(Path(bpy.app.tempdir))
    start = time.perf_counter()
    with interrupt.blocking(what):
        result = bpy.ops.render.render(write_still=False, scene=scene.name, layer=view_layer.name)
    seconds = time.perf_counter() - start
    if "FINISHED" not in result:
        raise ReferenceCaptureError(f"Cycles render of scene {scene.name!r} failed: {result}")
    save_render_result(scene, path, "Cycles render")  # under Python's lock (pass_files.py)
    return seconds


def output_size(scene: "bpy.types.Scene") -> tuple[int, int]:
    """The render's size in pixels: Blender's own rounding of the percentage (integer
    division of positive sizes)."""
    render = scene.render
    return (int(render.resolution_x * render.resolution_percentage / 100),
            int(render.resolution_y * render.resolution_percentage / 100))


def _check_transforms(light_obj, cam_obj, depsgraph) -> None:
    """Refuse by name, before the reference starts, a NaN or infinite transform (as the
    viewport has it; the render's again in `_render_matrix`) or camera clip range."""
    for obj, what in ((light_obj, "light"), (cam_obj, "camera")):
        _finite(np.array(obj.evaluated_get(depsgraph).matrix_world, dtype=np.float64), obj, what)
    clip = (float(cam_obj.data.clip_start), float(cam_obj.data.clip_end))
    if not all(math.isfinite(v) for v in clip) or not 0.0 < clip[0] < clip[1]:
        raise ReferenceCaptureError(f"camera {cam_obj.name!r} has clip start/end {clip[0]:g}/{clip[1]:g}; "
                                    "they must be finite with 0 < start < end")


def _render_matrix(found, obj, what: str) -> np.ndarray:
    """`obj`'s world matrix in the render depsgraph (render_geometry.collect), finite."""
    matrix = found.matrices.get(obj.name_full)
    if matrix is None:
        raise ReferenceCaptureError(f"the render does not evaluate the {what} {obj.name!r}")
    return _finite(matrix, obj, what)


def _finite(matrix: np.ndarray, obj, what: str) -> np.ndarray:
    """A NaN or infinite transform renders nothing useful (and the maps evaluate no pixel)."""
    try:
        validate.finite_matrix(f"{what} {obj.name!r}: its transform", matrix)
    except InputError as exc:
        raise ReferenceCaptureError(str(exc)) from None
    return matrix


def capture(scene: "bpy.types.Scene", samples: int = DEFAULT_SAMPLES, *, light: "bpy.types.Object | str | None" = None,
            view_layer: str | None = None, progress: Progress | None = None,
            check: Callable[[str], None] | None = None, hard: bool = False,
            soft_samples: int = SOFT_SAMPLES) -> ReferenceData:
    """Render the Cycles reference of `scene` from its camera; the scene is left as it was.

    `light` picks the point, spot, sun or area light when the scene has several (else
    exactly one rendered light of those types must exist); every other light is hidden
    from the render. `check(emission)` runs once the light is known and before any render,
    so a caller can refuse it (e.g. no requested method fits) without waiting for Cycles.
    A sized light renders with `soft_samples` in two halves (module docstring) unless
    `hard` takes its size away; `samples` is the hard light's count.
    """
    if samples < 1:
        raise ReferenceCaptureError(f"samples must be at least 1, got {samples}")
    if soft_samples < 2 or soft_samples % 2:
        raise ReferenceCaptureError(f"soft samples must be an even number of at least 2, got {soft_samples}")
    cam_obj, layer, visible, light_obj = _checked_inputs(scene, view_layer, light)
    emission = emission_of(light_obj.data)
    media = reference_materials.media(scene, layer)
    if media:
        log.info("media (volume shaders) the reference renders with: %s", ", ".join(media))
    if check is not None:
        check(emission)
    _warn_soft_light(light_obj)
    say = progress or (lambda message: None)
    width, height = output_size(scene)
    # Read before the reference set-up turns shadow catchers and holdouts off: the
    # notes must name what the file has.
    rule = ShadowRule.for_light(scene, light_obj, view_layer=layer)

    # A temporary the interrupt handling knows, so Ctrl-C during a render removes it;
    # the scene's settings are restored before it goes.
    overrides = Overrides()
    with interrupt.temporary_dir("omniwarp_ref_") as tmpdir:
        try:
            say("collecting triangles (render depsgraph)")
            # The render depsgraph: render-level modifiers, hide_render, instancer flags;
            # read before the reference materials replace the file's (their alpha).
            found = render_triangles(scene, layer)
            # As Cycles evaluates them: the viewport does not evaluate an object disabled there
            # (an old file's hidden sun read as the identity, straight down).
            light_world = _render_matrix(found, light_obj, "light")
            camera_world = _render_matrix(found, cam_obj, "camera")
            authored = light_size.light_shape(light_obj, light_world)
            sized = authored.sized and not hard
            noisy = sized or bool(media)  # two halves and their noise (module docstring)
            spp = soft_samples // 2 if noisy else samples
            material_notes = _apply_render_settings(scene, layer, light_obj, visible, spp, str(tmpdir / "pass"),
                                                    overrides, hard)
            _log_geometry(scene, light_obj, light_world, found, visible)
            seeds = SOFT_SEEDS if noisy else SOFT_SEEDS[:1]
            renders = _render_halves(scene, layer, light_obj, seeds, tmpdir / "pass.exr", overrides,
                                     lambda i, kind: say(f"Cycles render {i}/{2 * len(seeds)} ({kind}, "
                                                         f"{width}x{height}, {spp} spp)"))
        finally:
            overrides.restore()

    read = read_passes(renders.lits, renders.frees, layer.name, bool(media), noisy)
    if read.position.shape[:2] != (height, width):
        raise ReferenceCaptureError(f"Cycles output is {read.position.shape[1]}x{read.position.shape[0]}, "
                                    f"expected {width}x{height}")
    blocks = rule.blocks
    triangles, spheres, strands = found.select(blocks), found.select_spheres(blocks), found.select_strands(blocks)
    surface, grids = found.select_surface(blocks), found.select_grids(blocks)
    meta = _meta(scene, light_obj, cam_obj, rule, found, renders, read, material_notes,
                 samples=int(soft_samples if noisy else samples), shape=authored if sized else POINT, authored=authored,
                 counts=(len(triangles), len(spheres), len(strands), len(grids)))
    log.info("captured %r %dx%d: %d triangles, %.1f%% hit, renders %.2f s + %.2f s",
             scene.name, width, height, len(triangles), 100.0 * read.hit.mean(), renders.shadowed_s, renders.free_s)
    return _reference_data(scene, cam_obj, light_obj, emission, light_world, camera_world, read, meta,
                           triangles, surface, spheres, strands, grids)


def _reference_data(scene, cam_obj, light_obj, emission: str, light_world: np.ndarray, camera_world: np.ndarray,
                    read: PassReading, meta: dict, triangles, surface, spheres, strands, grids) -> ReferenceData:
    """The capture as the arrays the comparison reads: the camera as Cycles framed it (lens
    shift, sensor fit, pixel aspect, orthographic scale: its window), the light's and
    camera's rigid matrices, and the blockers."""
    width, height = output_size(scene)
    camera_window = _camera_window(cam_obj.data, scene.render, width, height)
    camera_ortho = cam_obj.data.type == "ORTHO"
    return ReferenceData(
        position=read.position,
        normal=read.normal,
        hit=read.hit,
        shadowed=read.shadowed,
        unshadowed=read.unshadowed,
        triangles=triangles,
        light_matrix=_rigid(light_world),
        emission=emission,
        camera_matrix=_rigid(camera_world),
        camera_fov_deg=(_camera_fov_deg(cam_obj.data, width, height) if camera_window is None
                        else window_fov_deg(camera_window, (width, height), camera_ortho)),
        resolution=(width, height),
        meta=meta,
        # Only a narrower cone restricts the domain; hemi, omni and sun keep pi.
        spot_size=float(light_obj.data.spot_size) if emission == "spot" else math.pi,
        camera_window=camera_window,
        camera_ortho=camera_ortho,
        camera_clip=(float(cam_obj.data.clip_start), float(cam_obj.data.clip_end)),
        surface=surface if surface.see_through or surface.has_media else None,
        visibility_noise=read.noise,
        spheres=spheres if len(spheres) else None,
        strands=strands if len(strands) else None,
        grids=grids,  # Volume geometry's density grids
    )


def _checked_inputs(scene, view_layer: str | None, light):
    """The camera, view layer, rendered object names and light of a capture, each refused
    by name when the reference cannot use it."""
    cam_obj = scene.camera
    if cam_obj is None or cam_obj.type != "CAMERA":
        raise ReferenceCaptureError(f"scene {scene.name!r} has no active camera; the reference needs one")
    if cam_obj.data.type not in ("PERSP", "ORTHO"):
        raise ReferenceCaptureError(
            f"camera {cam_obj.name!r} is {cam_obj.data.type}; the reference needs a perspective or "
            "orthographic camera"
        )
    layer = pick_view_layer(scene, view_layer)
    # A new scene's view layer is synced lazily (layer_collection stays None until
    # the scene is evaluated once), so evaluate before reading its collections.
    depsgraph = evaluated_depsgraph(scene, layer)
    visible = render_visible_objects(layer)
    light_obj = pick_light(scene, visible, light)
    if light_obj.name_full not in visible:
        raise ReferenceCaptureError(f"light {light_obj.name!r} is disabled for rendering")
    energy, colour = float(light_obj.data.energy), [float(c) for c in light_obj.data.color]
    if not all(math.isfinite(v) for v in [energy, *colour]):
        raise ReferenceCaptureError(f"light {light_obj.name!r} has a non-finite energy or colour "
                                    f"({energy:g}, {', '.join(f'{c:g}' for c in colour)})")
    if energy <= 0.0 or max(colour) <= 0.0:
        # For a sun the energy is its strength (W/m^2); zero is equally useless.
        raise ReferenceCaptureError(f"light {light_obj.name!r} emits nothing (energy or colour is zero)")
    _check_transforms(light_obj, cam_obj, depsgraph)
    return cam_obj, layer, visible, light_obj


def _log_geometry(scene, light_obj, light_world: np.ndarray, found, visible: set[str]) -> None:
    """What a reader of the log should know of the geometry: a spot's squashed cone, and
    rendered objects that gave no triangles."""
    scale = np.linalg.norm(light_world[:3, :3], axis=0)
    if light_obj.data.type == "SPOT" and np.ptp(np.abs(scale)) > 1e-4:
        log.warning("spot light %r has non-uniform scale %s: its cone is not circular", light_obj.name, scale)
    empty = {o.name for o in scene.objects if o.type in GEOMETRY_TYPES and o.name_full in visible} - found.names
    if empty:
        log.info("rendered objects without triangles: %s", ", ".join(sorted(empty)))


@dataclass
class _Renders:
    """The Cycles passes of a capture: one EXR's channels a seed, shadowed and not."""

    lits: list[dict[str, np.ndarray]]
    frees: list[dict[str, np.ndarray]]
    shadowed_s: float
    free_s: float


def _render_halves(scene, layer, light_obj, seeds: tuple[int, ...], exr_path: Path, overrides: Overrides,
                   say: Callable[[int, str], None]) -> _Renders:
    """Each seed's render with the light's shadows, then each again without them: the same
    seed draws the same light points in both (module docstring)."""
    out = _Renders([], [], 0.0, 0.0)
    count = 2 * len(seeds)
    for shadows in (True, False):
        if not shadows:
            _disable_shadows(scene, light_obj, overrides)
        for i, seed in enumerate(seeds):
            overrides.set(scene.cycles, "seed", seed)
            step = i + 1 if shadows else len(seeds) + i + 1
            say(step, "shadowed" if shadows else "unshadowed")
            seconds = _render(scene, layer, exr_path, f"Cycles render {step}/{count}")
            (out.lits if shadows else out.frees).append(read_exr_channels(exr_path))
            exr_path.unlink()
            if shadows:
                out.shadowed_s += seconds
            else:
                out.free_s += seconds
    return out


def _meta(scene, light_obj, cam_obj, rule: ShadowRule, found, renders: _Renders, read: PassReading,
          material_notes: list[str], *, samples: int, shape, authored, counts: tuple[int, int, int, int]) -> dict:
    """The reference's record of how it was made and of what blocks the light."""
    import bpy

    triangles, spheres, strands, grids = counts
    meta = {
        "preset": "custom",
        "scene": scene.name,
        "light": light_obj.name,
        "camera": cam_obj.name,
        "blender_version": bpy.app.version_string,
        "samples": samples,
        "mixed_pixels": read.mixed,
        "positions_lost": read.lost,
        # The light as the reference rendered it, and as the file has it.
        "light_shape": shape.as_dict(),
        "light_shape_file": authored.as_dict(),
        "capture_version": CAPTURE_VERSION,
        "render_seconds": {"shadowed": round(renders.shadowed_s, 3), "unshadowed": round(renders.free_s, 3)},
        "light_energy": float(light_obj.data.energy),
        # What blocks the light (ShadowRule), and what the rule could not follow.
        "occluder_triangles": int(triangles),
        "occluder_spheres": int(spheres),
        "occluder_strands": int(strands),
        "occluder_grids": grids,
        "scene_triangles": int(sum(len(t) for t in found.triangles)),
        "light_casts_shadows": rule.casts_shadows,
        "notes": list(rule.notes) + material_notes + found.alpha_notes(),
        # What blocks the light in Cycles but no method draws (left_out.py): every
        # pipeline row's note.
        "left_out": found.left_out.notes(rule.blocks),
    }
    for note in meta["left_out"]:
        log.warning("scene %r, light %r: %s", scene.name, light_obj.name, note)
    if light_obj.data.type == "SPOT":
        meta["spot_size_deg"] = math.degrees(light_obj.data.spot_size)
        meta["spot_blend"] = float(light_obj.data.spot_blend)
    if light_obj.data.type == "SUN":
        meta["sun_angle_deg"] = math.degrees(light_obj.data.angle)  # as authored
    return meta
