"""Runs Blender `gpu` work in its own process for the tests (one GL owner per process).

    python tests/support/blender_gpu_worker.py backends OUT.npz
    python tests/support/blender_gpu_worker.py viewport OUT.json
"""
from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

# (parameterization, warp, edge antialiasing) on the seam scene and the cached reference.
CASES = (("dpsm", "none", False), ("cube", "none", False), ("dpsm", "notw", False), ("cube", "rtw", False),
         ("unfold", "none", False), ("unfold", "none", True))
# Spot and sun maps on the small street of tests/gl/test_projective.py.
PROJECTIVE_CASES = (("spot", "sm"), ("spot", "psm"), ("sun", "psm"))
# The exact pass over those lights' own maps (sm), on the same street.
PROJECTIVE_EXACT_CASES = ("spot", "sun")
# Culled plain layers with readable boxes (scissored clears and draws): the courtyard
# preset at test size, light outside the view, after an ipsm frame fills the atlas.
BOXED_CASES = ("dpsm", "cube")
POINT_CASES = ("dpsm", "cube")  # the point-sprite cloud (tests/gl/test_footprint_pass.point_cloud)
TRAFFIC_METHODS = ("dpsm", "cube+notw", "exact")  # a steady frame's waits and bytes (issue 41)


def boxed_scene():
    from addon.core.presets import build_preset

    return build_preset("courtyard", (128, 96))


def weighted_samples(samples):
    """The seam scene's samples with importance weights 1 to 16 in diagonal stripes,
    for the weighted scatter (ViewSamples.importance) on both backends."""
    rows, cols = np.indices(samples.hit.shape)
    return replace(samples, importance=1.0 + ((rows + cols) // 3) % 16)


# The exact pass's cases the backends must agree on (parameterization, warp).
EXACT_CASES = (("dpsm", "notw"), ("cube", "none"))
# See-through surfaces (tests/gl/test_alpha_pass.py's scene): the maps' veil and `exact`.
ALPHA_CASES = (("dpsm", "notw", False), ("cube", "none", False), ("dpsm", "notw", True))


def one_texel_case():
    """stress_one_texel at test size: lists longer than the exact pass's first bound."""
    from addon.core.presets import build_preset
    from tests.support.oracle import view_samples

    scene = build_preset("stress_one_texel", (96, 72))
    return scene, view_samples(scene)[0]


def alpha_frames(pipeline):
    """Visibility of the see-through scene for every ALPHA_CASES entry, by key."""
    from addon.render.pipeline import ShadowSettings
    from addon.render.resident import ResidentScene
    from tests.gl.test_alpha_pass import _scene
    from tests.support.oracle import view_samples

    scene = _scene()
    samples, _, _ = view_samples(scene)
    resident = ResidentScene.of_triangles(scene.world_triangles(), surface=scene.surface())
    frames = {}
    for param, warp, exact in ALPHA_CASES:
        result = pipeline.render(scene.light, resident, samples, ShadowSettings(param, 256, warp=warp, exact=exact))
        frames[f"alpha_{param}_{warp}{'_exact' if exact else ''}_visibility"] = result.visibility
    pipeline.backend.release_scene(resident)
    return frames


def soft_frames(pipeline):
    """Visibility of the sized lights' scenes (tests/gl/test_soft_filter.py), by key: the
    soft filter, and the exact pass's samples of the light (by segments through the tree,
    and by its lists); a spot's and a sun's over their own map."""
    import dataclasses

    from addon.render.frame import settings_for
    from tests.gl.test_soft_filter import _scene
    from tests.support.oracle import view_samples

    frames = {}
    for name in ("sphere", "area", "spot", "sun"):
        scene = _scene(name)
        samples, _, _ = view_samples(scene)
        methods = ("sm", "psm", "exact") if name in ("spot", "sun") else ("dpsm+notw", "cube", "exact")
        for method in methods:
            settings = settings_for(method, 256, scene.light.emission)
            result = pipeline.render(scene.light, scene.world_triangles(), samples, settings)
            frames[f"soft_{name}_{method}_visibility"] = result.visibility
            if method == "exact":
                lists = dataclasses.replace(settings, exact_segments=False)
                frames[f"soft_{name}_exact_lists_visibility"] = pipeline.render(
                    scene.light, scene.world_triangles(), samples, lists).visibility
    return frames


def pieces_frames(pipeline):
    """Visibility of the tuft of strands and pebbles (tests/gl/test_pieces_pass.py) under a
    point, a spot and a sun light and a sized area light, by key: hair and points in the
    maps and the exact pass."""
    from addon.core.light_shape import Area
    from addon.core.scene import LightSpec, look_at
    from addon.render.frame import settings_for
    from tests.gl.test_pieces_pass import LIGHTS, ground_samples, scene_of, tuft

    scene = scene_of(*tuft())
    samples = ground_samples(48, 36)
    area = LightSpec("hemi", look_at((0.35, 0.25, 3.0), (0.0, 0.0, 0.0)), shape=Area("rectangle", 0.4, 0.4))
    cases = [(name, light, method) for name, light in LIGHTS.items()
             for method in (("dpsm", "cube+notw", "exact") if name == "omni" else ("sm", "exact"))]
    frames = {}
    for name, light, method in cases + [("area", area, "exact")]:
        result = pipeline.render(light, scene, samples, settings_for(method, 256, light.emission))
        frames[f"pieces_{name}_{method}_visibility"] = result.visibility
    pipeline.backend.release_scene(scene)
    return frames


def media_frames(pipeline):
    """Visibility of the fog box around a figure (tests/gl/test_media_pass.py), by key: the
    exact pass's optical depths under a point light (outside the fog and inside it), a spot
    and a sphere light of 0.5 m, and the maps' haze."""
    from addon.core.media import Medium
    from addon.render.frame import settings_for
    from addon.render.resident import ResidentScene
    from tests.gl.test_media_pass import _case, _fog, _resident

    frames = {}
    for name, light, spot, methods in (("outside", (0.8, -0.6, 4.0), False, ("exact", "dpsm+notw", "cube")),
                                       ("inside", (0.5, 0.6, 1.6), False, ("exact", "dpsm")),
                                       ("spot", (0.8, -0.6, 4.0), True, ("exact",))):
        scene, samples, _, _ = _case(light, spot=spot)
        resident = _resident(scene, _fog(), Medium("fog", (0.5, 0.9, 1.4)))
        for method in methods:
            result = pipeline.render(scene.light, resident, samples, settings_for(method, 256, scene.light.emission))
            frames[f"media_{name}_{method}_visibility"] = result.visibility
        pipeline.backend.release_scene(resident)
    # A sphere light of 0.5 m: the exact pass follows a share of its points through the fog
    # and the test weighs them with the surfaces' marks (shadow_test.frag's media variant).
    from addon.core.light_shape import Sphere
    from addon.core.scene import LightSpec

    scene, samples, _, _ = _case()
    sized = LightSpec("omni", scene.light.matrix_world, shape=Sphere(0.5))
    resident = _resident(scene, _fog(), Medium("fog", (0.5, 0.9, 1.4)))
    result = pipeline.render(sized, resident, samples, settings_for("exact", 256, "omni"))
    frames["media_sized_exact_visibility"] = result.visibility
    pipeline.backend.release_scene(resident)
    from tests.gl.test_grid_pass import _case as cloud_case
    from tests.gl.test_grid_pass import cloud

    scene, samples, _, _ = cloud_case()
    resident = ResidentScene.of_triangles(scene.world_triangles())
    resident.set_grid("cloud", cloud())
    for method in ("exact", "dpsm+notw"):
        result = pipeline.render(scene.light, resident, samples, settings_for(method, 256, scene.light.emission))
        frames[f"media_grid_{method}_visibility"] = result.visibility
    pipeline.backend.release_scene(resident)
    return frames


def case_key(param: str, warp: str, aa: bool) -> str:
    return f"{param}_{warp}{'_aa' if aa else ''}"


def backends(out: str, reference: str | None = None) -> None:
    """The pipeline on Blender's gpu backend, every case: on the seam scene, and on a
    cached Cycles reference when one is given."""
    from addon.compare import light_from_reference, samples_from_reference
    from addon.reference.data import ReferenceData
    from addon.render.backends.blender.backend import BlenderGPUBackend
    from addon.render.backends.blender.gpu_objects import ensure_gpu
    from addon.render.pipeline import ShadowPipeline, ShadowSettings, settings_for
    from addon.core.scene import LightSpec
    from addon.render.frame import Measure
    from tests.gl.test_footprint_pass import point_cloud
    from tests.gl.test_exact_pass import slab_scene, random_scene
    from tests.gl.test_izb_lists import _walk
    from tests.gl.test_pipeline_extremes import _seam_straddler
    from tests.gl.test_projective import _street
    from tests.support.oracle import view_samples

    ensure_gpu()
    scene = _seam_straddler()
    samples, _, _ = view_samples(scene)
    backend = BlenderGPUBackend()
    pipeline = ShadowPipeline(backend)
    arrays = {}
    for param, warp, aa in CASES:
        result = pipeline.render(scene.light, scene.world_triangles(), samples,
                                 ShadowSettings(param, 256, warp=warp, edge_aa=aa), measure=Measure(keep_atlas=True))
        arrays[f"{case_key(param, warp, aa)}_visibility"] = result.visibility
        arrays[f"{case_key(param, warp, aa)}_atlas"] = result.atlas
    for light, method in PROJECTIVE_CASES:
        street = _street(light)
        street_samples, _, _ = view_samples(street)
        result = pipeline.render(street.light, street.world_triangles(), street_samples, ShadowSettings(method, 256),
                                 measure=Measure(keep_atlas=True))
        arrays[f"{light}_{method}_visibility"] = result.visibility
        arrays[f"{light}_{method}_atlas"] = result.atlas
    for light in PROJECTIVE_EXACT_CASES:
        street = _street(light)
        street_samples, _, _ = view_samples(street)
        result = pipeline.render(street.light, street.world_triangles(), street_samples,
                                 ShadowSettings("sm", 128, exact=True))
        arrays[f"exact_{light}_visibility"] = result.visibility
    result = pipeline.render(scene.light, scene.world_triangles(), weighted_samples(samples),
                             ShadowSettings("dpsm", 256, warp="notw"), measure=Measure(keep_atlas=True))
    arrays["weighted_visibility"] = result.visibility
    arrays["weighted_atlas"] = result.atlas
    # The irregular z-buffer's lists of that frame: their lengths and members (not their
    # order, which the atomics decide).
    pipeline.link_lists(scene.light, result.plan, result.mappings, 256)
    lengths, members = _walk(*backend.read_links())
    arrays["link_lengths"], arrays["link_members"] = lengths, np.sort(np.asarray(members))
    # The exact pass (irregular z-buffer) on Blender's backend.
    for param, warp in EXACT_CASES:
        result = pipeline.render(scene.light, scene.world_triangles(), samples,
                                 ShadowSettings(param, 128, warp=warp, exact=True))
        arrays[f"exact_{param}_{warp}_visibility"] = result.visibility
    # ... and on a random scene (a hemi light among random blockers).
    rnd = random_scene(1)
    rnd_samples, _, _ = view_samples(rnd)
    result = pipeline.render(rnd.light, rnd.world_triangles(), rnd_samples,
                             ShadowSettings("dpsm", 128, warp="notw", exact=True))
    arrays["exact_random_visibility"] = result.visibility
    # ... and on lists longer than the first round's bound (later rounds finish them).
    texel_scene, texel_samples = one_texel_case()
    result = pipeline.render(texel_scene.light, texel_scene.world_triangles(), texel_samples,
                             ShadowSettings("dpsm", 256, exact=True))
    arrays["exact_one_texel_visibility"] = result.visibility
    arrays["exact_one_texel_rounds"] = np.array(result.exact_work["rounds"])
    # ... and on faces laid over faces (core/coplanar.py): a copy and a patch over a slab.
    twin = slab_scene(True, patch=True)
    twin_samples, _, _ = view_samples(twin)
    arrays["exact_twin_visibility"] = pipeline.render(twin.light, twin.world_triangles(), twin_samples,
                                                      ShadowSettings("dpsm", 128, exact=True)).visibility
    arrays.update(alpha_frames(pipeline))
    arrays.update(soft_frames(pipeline))
    arrays.update(pieces_frames(pipeline))
    arrays.update(media_frames(pipeline))
    court = boxed_scene()
    court_samples, _, _ = view_samples(court)
    for param in BOXED_CASES:
        pipeline.render(court.light, court.world_triangles(), court_samples, ShadowSettings("ipsm", 256))
        result = pipeline.render(court.light, court.world_triangles(), court_samples, ShadowSettings(param, 256),
                                 measure=Measure(keep_atlas=True))
        arrays[f"boxed_{param}_visibility"] = result.visibility
        arrays[f"boxed_{param}_atlas"] = result.atlas
    # Point sprites (the footprint pass's small-triangle chunks) on Blender's backend.
    cloud, cloud_samples = point_cloud()
    arrays["point_sprites"] = np.array(backend.device.point_sprites)
    for param in POINT_CASES:
        result = pipeline.render(LightSpec("omni", np.eye(4)), cloud, cloud_samples,
                                 ShadowSettings(param, 256, cull=False), measure=Measure(keep_atlas=True))
        arrays[f"cloud_{param}_atlas"] = result.atlas
    # A uniform name no program declares: refused by name, not dropped.
    from addon.core.errors import BackendError
    from addon.render.shaders import EDGE_PROGRAM

    try:
        backend.device.bind(EDGE_PROGRAM, {"ow_no_such_uniform": 1.0}, backend.textures)
        arrays["unknown_uniform"] = np.array("")
    except BackendError as exc:
        arrays["unknown_uniform"] = np.array(str(exc))
    # A steady frame's traffic at the device (scripts/frame_traffic.py --backend blender).
    from scripts.frame_traffic import steady_traffic

    triangles = scene.world_triangles()
    triangles.flags.writeable = False  # resident, as the viewport's are
    resident_samples = replace(samples, **{name: np.array(getattr(samples, name)) for name in
                                           ("positions", "normals", "hit")})
    for name in ("positions", "normals", "hit"):
        getattr(resident_samples, name).flags.writeable = False
    for method in TRAFFIC_METHODS:
        traffic = steady_traffic(pipeline, scene.light, triangles, resident_samples,
                                 settings_for(method, 256, scene.light.emission), device_calls=True)
        arrays[f"traffic_{method}"] = np.array([traffic.waits, traffic.read_bytes, traffic.upload_bytes])
    if reference:
        ref = ReferenceData.load(reference)
        for param, warp, aa in CASES:
            result = pipeline.render(light_from_reference(ref), ref.triangles.astype(np.float64),
                                     samples_from_reference(ref), ShadowSettings(param, 512, warp=warp, edge_aa=aa))
            arrays[f"ref_{case_key(param, warp, aa)}_visibility"] = result.visibility
    backend.release()
    np.savez(out, **arrays)


def _grid_cloud(scene, centre) -> object:
    """A Volume object whose geometry nodes make a 1 m Volume Cube of density 3 at `centre`
    (Cycles' default volume shader: an extinction of 3 a metre)."""
    import bpy

    tree = bpy.data.node_groups.new("viewport cloud", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    cube = tree.nodes.new("GeometryNodeVolumeCube")
    cube.inputs["Density"].default_value = 3.0
    cube.inputs["Min"].default_value, cube.inputs["Max"].default_value = (-0.5,) * 3, (0.5,) * 3
    tree.links.new(cube.outputs[0], tree.nodes.new("NodeGroupOutput").inputs[0])
    cloud = bpy.data.objects.new("viewport cloud", bpy.data.volumes.new("viewport cloud"))
    cloud.location = tuple(float(v) for v in centre)
    cloud.modifiers.new("cloud", "NODES").node_group = tree
    scene.collection.objects.link(cloud)
    return cloud


def _current_gl_program() -> int | None:
    """GL_CURRENT_PROGRAM of the context Blender made current (through EGL), or None."""
    import ctypes

    try:
        egl = ctypes.CDLL("libEGL.so.1")
    except OSError:
        return None
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    address = egl.eglGetProcAddress(b"glGetIntegerv")
    if not address:
        return None
    value = ctypes.c_int(0)
    ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.POINTER(ctypes.c_int))(address)(0x8B8D, ctypes.byref(value))
    return value.value


def _preview_case(preset: str, size: tuple[int, int], parameterization: str, resolution: int):
    """A preset built in Blender with its light previewed (NoTW, throttle 0, sample scale 1),
    and an offscreen target to draw the viewport into: (spec, scene, light object, depsgraph,
    view, projection, size, target texture, its framebuffer)."""
    from addon.core.presets import build_preset
    from addon.reference.blender_scene import build_blender_scene
    from addon.reference.capture import evaluated_depsgraph
    from addon.render.backends.blender.gpu_objects import float_texture, framebuffer

    spec = build_preset(preset, size)
    scene = build_blender_scene(spec)
    scene.omniwarp.preview_enabled = True
    scene.omniwarp.camera_resolution_scale = 1.0
    scene.omniwarp.throttle_ms = 0
    light_obj = next(o for o in scene.objects if o.type == "LIGHT")
    light_obj.data.omniwarp.enabled = True
    light_obj.data.omniwarp.parameterization = parameterization
    light_obj.data.omniwarp.warp = "NOTW"
    light_obj.data.omniwarp.resolution = resolution
    target = float_texture(spec.camera.resolution, "RGBA32F")
    return (spec, scene, light_obj, evaluated_depsgraph(scene), np.linalg.inv(spec.camera.matrix_world),
            spec.camera.projection(), spec.camera.resolution, target, framebuffer(color_slots=(target,)))


def viewport(out: str) -> None:
    """Register the extension, preview a preset light through the viewport's own draw
    path with explicit matrices into an offscreen target, then check robustness."""
    import bpy

    from addon.blender import registration, viewport as vp
    from addon.blender.scene_cache import CACHE
    from addon.reference.capture import evaluated_depsgraph
    from addon.render.backends.blender.gpu_objects import ensure_gpu

    ensure_gpu()

    def handler_counts() -> dict[str, int]:
        """Callbacks per app-handler list the preview uses."""
        return {name: len(getattr(bpy.app.handlers, name)) for name in
                ("depsgraph_update_post", "load_post", "undo_post", "redo_post")}

    def held() -> dict:
        """What the preview still holds: its draw handler and its GPU objects."""
        handler = vp._STATE.handler
        return {"handler": None if handler is None else repr(handler), "live_resources": vp.live_resources()}

    def outcome(drew: bool) -> dict:
        """A draw's result and the preview's error message, behind each draw check."""
        return {"draw": drew, "last_error": vp.last_error()}

    handlers_before = handler_counts()
    report: dict = {}
    # Each flag that is computed from values has them next to it as `<flag>_values`
    # (tests/support/checks.py shows them when the flag fails).
    # 20 register/unregister cycles leave no handler and no GPU object behind.
    for _ in range(20):
        registration.register()
        registration.unregister()
    report["cycles_clean_values"] = {**held(), "handlers_before": handlers_before, "handlers_after": handler_counts()}
    report["cycles_clean"] = vp._STATE.handler is None and vp.live_resources() == 0 and all(
        len(getattr(bpy.app.handlers, name)) == count for name, count in handlers_before.items())

    registration.register()
    # Each check here reads what the draw after a change drew: no recompute spread over
    # redraws (a loaded machine may take 0.2 s for one; `spread` tests that mode).
    vp.SPREAD_OVER_S = float("inf")
    spec, scene, light_obj, depsgraph, view, proj, size, target, target_fb = _preview_case(
        "room_hemi", (96, 72), "CUBE", 256)

    def draw(view_matrix) -> bool:
        with target_fb.bind():
            return vp.safe_draw_view(scene, depsgraph, view_matrix, proj, size, "test-region")

    report["first_draw"] = draw(view)
    report["first_draw_values"] = outcome(report["first_draw"])
    cached = vp._STATE.results["test-region"]
    name, light, settings, result, stats, texture = cached.lights[0]
    from addon.render.backends.blender.gpu_objects import read_texture

    # The viewport's visibility stayed on the GPU, in a texture of its own (row 0 at the
    # bottom); read here to check it.
    raw = read_texture(texture, "RG32F")[::-1]
    gbuffer = cached.gbuffer
    # The frame used the G-buffer's textures where they were: nothing was read back.
    report["gbuffer_not_read"] = "positions" not in vars(gbuffer) and "normals" not in vars(gbuffer)
    report["gbuffer_not_read_values"] = {"read_back": [key for key in ("positions", "normals") if key in vars(gbuffer)]}
    report.update({
        "lights": len(cached.lights), "passes": result.passes, "param": settings.parameterization,
        "warp": settings.warp, "hit_share": float(gbuffer.hit.mean()),
        "shadowed_share": float((raw[..., 0][gbuffer.hit] < 0.5).mean()),
        "finite_atlas": bool(np.isfinite(result.atlas).all()),
        "finite_atlas_values": {"non_finite": int(np.count_nonzero(~np.isfinite(result.atlas))),
                                "texels": int(result.atlas.size)},
        "max_before": stats.max_count_before, "max_after": stats.max_count_after,
        "handler_installed": vp._STATE.handler is not None,
    })
    # 200 redraws: 190 of the same view (cached, nothing recomputed) and 10 moved views.
    live_after_first = vp.live_resources()
    report["bytes_first"] = vp._STATE.backend.geometry_bytes
    computed = []
    for i in range(200):
        moved = view.copy()
        if i % 20 == 19:
            moved[0, 3] += 0.01 * (i + 1)
        draw(moved)
        computed.append(vp._STATE.results["test-region"].computed_at)
    report["recomputes"] = len(set(computed))
    report["live_first"] = live_after_first
    report["live_after_200"] = vp.live_resources()
    report["bytes_after_200"] = vp._STATE.backend.geometry_bytes  # the scene stayed resident
    # The view orbits for 30 redraws with a throttle that allows no recompute: each redraw
    # draws the last result reprojected into its own view. The last one's shadow is then
    # compared with a fresh compute of that view.

    def orbit(step: int) -> np.ndarray:
        angle = np.radians(0.5 * step)
        turn = np.eye(4)
        turn[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
        centre = np.eye(4)
        centre[:3, 3] = [0.0, 0.0, 1.0]
        return np.linalg.inv(centre @ turn @ np.linalg.inv(centre) @ spec.camera.matrix_world)

    def darkened() -> np.ndarray:
        return read_texture(target, "RGBA32F")[..., 3] > 0.0

    def clear_target() -> None:
        with target_fb.bind():
            target_fb.clear(color=(0.0, 0.0, 0.0, 0.0))

    scene.omniwarp.throttle_ms = 0
    draw(view)
    scene.omniwarp.throttle_ms = 600000
    drawn, shadowed = [], []
    for step in range(1, 31):
        clear_target()
        draw(orbit(step))
        drawn.append(vp._STATE.last_drawn)
        shadowed.append(float(darkened().mean()))
    reprojected = darkened()
    moved_positions = vp._STATE.results["test-region"].moved.positions  # redrawn in one G-buffer 30 times
    scene.omniwarp.throttle_ms = 0
    clear_target()
    draw(orbit(30))
    fresh = darkened()
    # The G-buffer redrawn for each moved view kept its depth test: it sees what a fresh one sees.
    fresh_positions = vp._STATE.results["test-region"].gbuffer.positions
    report["moved_gbuffer_same"] = bool(np.array_equal(moved_positions, fresh_positions))
    report["moved_gbuffer_same_values"] = {"differ": int(np.count_nonzero(moved_positions != fresh_positions))}
    report["orbit_reprojected"] = drawn == ["reprojected"] * 30 and min(shadowed) > 0.01
    report["orbit_reprojected_values"] = {"drawn": drawn, "shadowed_share": shadowed}
    either = reprojected | fresh
    report["orbit_mismatch"] = float((reprojected != fresh)[either].mean()) if either.any() else 1.0
    report["orbit_fresh_drawn"] = vp._STATE.last_drawn
    report["orbit_live"] = vp.live_resources()
    # With the overlay off a recompute reads no map back and scatters no statistics;
    # turning it on recomputes with them.
    scene.omniwarp.overlay_enabled = False
    vp.request_update("overlay off")
    draw(view)
    bare = vp._STATE.results["test-region"].lights[0]
    scene.omniwarp.overlay_enabled = True
    draw(view)
    full = vp._STATE.results["test-region"].lights[0]
    report["overlay_economy"] = (bare[3].atlas is None and bare[4] is None and full[3].atlas is not None
                                 and full[4] is not None and bool(vp._STATE.results["test-region"].panels))
    report["overlay_economy_values"] = {"atlas_off": bare[3].atlas is None, "stats_off": bare[4] is None,
                                        "atlas_on": full[3].atlas is not None}
    # The first frame again from its G-buffer read back as arrays and uploaded (after the
    # counts above: it holds textures of its own): it shadows the same pixels.
    uploaded = vp._STATE.pipeline.render(light, CACHE.world_triangles(), gbuffer.view_samples(spec.camera), settings)
    report["uploaded_differ"] = float((uploaded.visibility != raw[..., 0]).mean())
    report["uploaded_passes"] = [uploaded.passes, result.passes]
    # The light switched to the exact method: the viewport draws it from its G-buffer, and
    # it shadows the same samples as the exact pass on the uploaded arrays.
    light_obj.data.omniwarp.exact = True
    vp.request_update("exact")
    report["exact_draw"] = draw(view)
    exact_visibility = read_texture(vp._STATE.results["test-region"].lights[0][5], "RG32F")[::-1][..., 0]
    from_arrays = vp._STATE.pipeline.render(light, CACHE.world_triangles(), gbuffer.view_samples(spec.camera),
                                            replace(settings, exact=True))
    report["exact_differ"] = float((exact_visibility != from_arrays.visibility).mean())
    report["exact_shadowed"] = float((exact_visibility[gbuffer.hit] < 0.5).mean())
    light_obj.data.omniwarp.exact = False
    vp.request_update("exact off")
    # A failure inside the draw path is caught, logged once and shown; drawing goes on.
    original = vp.compute_view_steps
    logged = []
    vp.log.error = lambda *a, **k: logged.append(a[0])

    def broken(*_a, **_k):
        raise RuntimeError("synthetic failure")

    vp.compute_view_steps = broken
    vp.request_update("test")
    failures = [draw(view) for _ in range(5)]
    report["error_caught"] = failures == [False] * 5 and "synthetic failure" in vp.last_error()
    report["error_caught_values"] = {"draws": failures, "last_error": vp.last_error()}
    report["error_logged_once"] = len(logged) == 1
    report["error_logged_once_values"] = {"logged": [str(message) for message in logged]}
    vp.compute_view_steps = original
    vp.request_update("test fixed")
    drew = draw(view)
    report["recovered"] = drew and vp.last_error() == ""
    report["recovered_values"] = outcome(drew)
    # A NaN bias (or strength) set from Python: the preview pauses with a message naming
    # it (a warning, no traceback), the light panel's check says the same, and fixing
    # the value resumes drawing.
    from addon.blender.properties import settings_problem

    warned = []
    vp.log.warning = lambda *a, **k: warned.append(a[1] if len(a) > 1 else a[0])
    light_obj.data.omniwarp.bias_constant = float("nan")
    vp.request_update("nan bias")
    nan_draws = [draw(view) for _ in range(3)]
    report["nan_bias_paused"] = nan_draws == [False] * 3 and "bias constant" in vp.last_error()
    report["nan_bias_paused_values"] = {"draws": nan_draws, "last_error": vp.last_error()}
    problem = settings_problem(light_obj.data, light_obj)
    report["nan_bias_panel"] = "bias constant" in problem
    report["nan_bias_panel_values"] = {"settings_problem": problem}
    report["nan_bias_warned_once"] = len(warned) == 1 and "bias constant" in str(warned[0]) and len(logged) == 1
    report["nan_bias_warned_once_values"] = {"warned": [str(w) for w in warned], "logged": [str(m) for m in logged]}
    light_obj.data.omniwarp.bias_constant = 0.3
    vp.request_update("bias fixed")
    drew = draw(view)
    report["nan_bias_recovered"] = (drew and vp.last_error() == ""
                                    and settings_problem(light_obj.data, light_obj) == "")
    report["nan_bias_recovered_values"] = {**outcome(drew),
                                           "settings_problem": settings_problem(light_obj.data, light_obj)}
    scene.omniwarp.shadow_strength = float("nan")
    vp.request_update("nan strength")
    drew = draw(view)
    report["nan_strength_paused"] = not drew and "shadow strength" in vp.last_error()
    report["nan_strength_paused_values"] = outcome(drew)
    scene.omniwarp.shadow_strength = 0.6
    vp.request_update("strength fixed")
    drew = draw(view)
    report["nan_strength_recovered"] = drew and vp.last_error() == ""
    report["nan_strength_recovered_values"] = outcome(drew)
    # A cloud (a Volume object of geometry nodes) under the light: the draw leaves its grid
    # to a timer (geometry nodes add reader objects, which a draw may not); the timer's
    # read adds it and the next draw is darker. Removed, the shadow is as before.
    from addon.compat.blender import grid_nodes_available

    if grid_nodes_available():
        def mean_visibility() -> float:
            result = vp._STATE.results["test-region"]
            texture = read_texture(result.lights[0][5], "RG32F")[::-1][..., 0]
            return float(texture[result.gbuffer.hit].mean())

        clear = mean_visibility()
        cloud = _grid_cloud(scene, np.asarray(light_obj.matrix_world)[:3, 3] - (0.0, 0.0, 0.8))
        depsgraph = evaluated_depsgraph(scene)
        vp.request_update("cloud added")
        draw(view)
        scheduled = bool(bpy.app.timers.is_registered(vp._read_grids)) and bool(CACHE.grids.pending)
        unread = mean_visibility()
        if bpy.app.timers.is_registered(vp._read_grids):
            bpy.app.timers.unregister(vp._read_grids)
        vp._read_grids()  # what the timer runs
        depsgraph = evaluated_depsgraph(scene)
        draw(view)
        read = mean_visibility()
        bpy.data.objects.remove(cloud)
        depsgraph = evaluated_depsgraph(scene)
        vp.request_update("cloud removed")
        draw(view)
        gone = mean_visibility()
        report["grid_read_by_timer"] = scheduled and abs(unread - clear) < 1e-6 and read < clear - 0.02 \
            and abs(gone - clear) < 1e-6 and not CACHE.grids.pending
        report["grid_read_by_timer_values"] = {"scheduled": scheduled, "clear": clear, "unread": unread,
                                               "read": read, "gone": gone}
    else:
        report["grid_read_by_timer"] = True
        report["grid_read_by_timer_values"] = {"skipped": "no grid nodes on this line"}
    # A released backend leaves none of its programs current: Blender skips a bind when a
    # new shader is allocated where the freed, last-bound one was, and a fresh backend then
    # drew its G-buffer with the old program (an empty view, about one time in seven).
    draw(view)
    drawn_with = _current_gl_program()
    # File load and undo between draws: results are dropped or marked stale, never reused.
    vp._on_load_post()
    released_current = _current_gl_program()
    report["released_program_not_current"] = drawn_with is not None and released_current != drawn_with
    report["released_program_not_current_values"] = {"drawn_with": drawn_with, "after_release": released_current}
    report["after_load_live"] = vp.live_resources()
    report["after_load_draw"] = draw(view)
    report["after_load_draw_values"] = outcome(report["after_load_draw"])
    version = vp._STATE.version
    vp._on_undo_redo()
    bumped = vp._STATE.version
    # The draw runs only when the version moved on: the check's short-circuit, kept.
    report["undo_marks_stale"] = bumped == version + 1 and draw(view)
    report["undo_marks_stale_values"] = {"version_before": version, "version_after": bumped,
                                         "last_error": vp.last_error()}
    # Deleting the light mid-preview: the next draw simply has no light to show.
    bpy.data.objects.remove(light_obj)
    depsgraph = evaluated_depsgraph(scene)
    vp.request_update("light deleted")
    draw(view)
    report["after_delete_lights"] = len(vp._STATE.results["test-region"].lights)
    registration.unregister()
    registration.unregister()  # idempotent
    report["handler_removed"] = vp._STATE.handler is None and vp.live_resources() == 0
    report["handler_removed_values"] = held()
    report["handlers_restored"] = all(len(getattr(bpy.app.handlers, name)) == count
                                      for name, count in handlers_before.items())
    report["handlers_restored_values"] = {"before": handlers_before, "after": handler_counts()}
    report["pointer_removed"] = not hasattr(bpy.types.Light, "omniwarp")
    CACHE.clear()
    Path(out).write_text(json.dumps(report))


def spread(out: str) -> None:
    """The preview on stress_million (a million triangles, 640x480): the first draw computes
    at once and makes the scene resident; a moved view's recompute is then spread over
    redraws (issue 52): each draw call's time, what each drew, and the spread result's
    visibility against one computed at once for the same view."""
    import time

    from addon.blender import registration
    from addon.blender import viewport as vp
    from addon.render.backends.blender.gpu_objects import ensure_gpu, read_texture

    ensure_gpu()
    registration.register()
    # The target is kept by name: Blender's framebuffer holds no reference to its texture, and
    # a texture freed under it leaves the slot empty.
    _, scene, _, depsgraph, view, proj, size, target, target_fb = _preview_case("stress_million", (640, 480),
                                                                               "DPSM", 1024)
    scene.omniwarp.overlay_enabled = False

    def draw(view_matrix) -> float:
        with target_fb.bind():
            start = time.perf_counter()
            vp.safe_draw_view(scene, depsgraph, view_matrix, proj, size, "spread-region")
            target_fb.read_color(0, 0, 1, 1, 4, 0, "FLOAT")  # the callback's GPU work done too
            return time.perf_counter() - start

    report: dict = {"first_s": draw(view), "first_drawn": vp._STATE.last_drawn, "error": vp.last_error()}
    for step in range(1, 3):  # two moved views, the second with every rate known
        moved = view.copy()
        moved[0, 3] += 0.05 * step
        times, drawn = [], []
        for _ in range(400):
            times.append(draw(moved))
            drawn.append(vp._STATE.last_drawn)
            if drawn[-1] == "computed":
                break
        report[f"moved{step}"] = {"callbacks": len(times), "max_s": max(times), "total_s": sum(times),
                                  "times_ms": [round(t * 1000) for t in times],
                                  "drawn": sorted(set(drawn)), "last": drawn[-1], "error": vp.last_error()}
    cached = vp._STATE.results["spread-region"]
    spread_vis = read_texture(cached.visibility[0], "RG32F")
    vp.free_resources()  # a fresh backend: the same view computed at once
    report["fresh_s"] = draw(moved)
    report["fresh_error"] = vp.last_error()
    fresh = vp._STATE.results["spread-region"]
    fresh_vis = read_texture(fresh.visibility[0], "RG32F")
    report["same_visibility"] = bool(np.array_equal(spread_vis, fresh_vis))
    report["differ"] = int(np.count_nonzero(spread_vis != fresh_vis))
    report["shadowed"] = float((fresh_vis[..., 0] < 0.5).mean())
    report["spread_shadowed"] = float((spread_vis[..., 0] < 0.5).mean())
    vp.free_resources()
    registration.unregister()
    Path(out).write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    {"backends": backends, "viewport": viewport, "spread": spread}[sys.argv[1]](*sys.argv[2:])
