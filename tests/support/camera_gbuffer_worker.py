"""The preview's G-buffer for saved references, in its own process (Blender's GL).

    python tests/support/camera_gbuffer_worker.py OUT.json REF.npz [REF.npz ...]

For each reference it rasterises the reference's triangles from `ReferenceData.camera()`
exactly as the headless preview does (`camera.projection() @ view`, normals turned
towards `camera.eye_homogeneous()`), and writes how well the G-buffer agrees with
Cycles: hit mask, positions and camera-facing normals. It also runs the viewport's
`compute_view` on the same matrices with a cube map of the reference's light, and
reports the faces drawn and whether the shadows equal those of an unculled frame.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))


def main(out: str, references: list[str]) -> None:
    from addon.reference.data import ReferenceData
    from addon.render.backends.blender.backend import BlenderGPUBackend
    from addon.render.backends.blender.gpu_objects import ensure_gpu
    from addon.render.backends.blender.draw import render_gbuffer
    from addon.render.resident import ResidentScene

    ensure_gpu()
    backend = BlenderGPUBackend()
    report = {}
    try:
        for path in references:
            ref = ReferenceData.load(path)
            camera = ref.camera()
            view_proj = camera.projection() @ np.linalg.inv(camera.matrix_world)
            gbuffer = render_gbuffer(backend, ResidentScene.of_triangles(ref.triangles), view_proj,
                                     camera.eye_homogeneous(), camera.resolution)
            both = gbuffer.hit & ref.hit
            dist = np.linalg.norm(gbuffer.positions[..., :3][both] - ref.position[both], axis=-1)
            facing = np.sum(gbuffer.normals[..., :3][both] * ref.normal[both], axis=-1)
            report[Path(path).stem] = {
                "hit_agreement": float(np.mean(gbuffer.hit == ref.hit)),
                "both": int(both.sum()),
                "position_p99": float(np.percentile(dist, 99)) if len(dist) else 0.0,
                "normal_agreement": float(np.mean(facing > 0.99)) if len(facing) else 1.0,
                **_viewport(backend, ref, camera),
            }
    finally:
        backend.release()
    Path(out).write_text(json.dumps(report))


def _viewport(backend, ref, camera) -> dict:
    """The viewport's compute path on this camera's matrices: culled cube faces, and the
    shadows against the same frame drawn without a camera (every face)."""
    from addon.blender.viewport import compute_view
    from addon.core.scene import LightSpec
    from addon.render.pipeline import ShadowPipeline, ShadowSettings, ViewSamples
    from addon.render.resident import ResidentScene

    pipeline = ShadowPipeline(backend)
    light = LightSpec(ref.emission, ref.light_matrix)
    settings = ShadowSettings("cube", 256)
    triangles = ref.triangles.astype(np.float64)
    gbuffer, results = compute_view(backend, pipeline, ResidentScene.of_triangles(triangles),
                                    np.linalg.inv(camera.matrix_world),
                                    camera.projection(), camera.resolution, [("light", light, settings)])
    culled = results[0][3]
    # The viewport keeps the visibility on the GPU in a texture of its own: read it here.
    from addon.render.backends.blender.gpu_objects import read_texture

    culled_visibility = read_texture(results[0][5], "RG32F")[::-1][..., 0]
    plain = ViewSamples(gbuffer.positions[..., :3].astype(np.float64), gbuffer.normals[..., :3].astype(np.float64),
                        gbuffer.hit, None)  # read back: no camera, so every face
    unculled = pipeline.render(light, triangles, plain, settings)
    hit = gbuffer.hit
    # The pixels behind viewport_same_shadows (tests/support/checks.py shows them when it fails).
    differ = int(np.count_nonzero((culled_visibility[hit] >= 0.5) != (unculled.visibility[hit] >= 0.5)))
    return {"viewport_frustum": culled.plan.frustum_corners is not None,  # a camera, so culling ran
            "viewport_faces_drawn": len(culled.plan.drawn), "viewport_faces_unculled": len(unculled.plan.drawn),
            "viewport_same_shadows": bool(np.array_equal(culled_visibility[hit] >= 0.5,
                                                         unculled.visibility[hit] >= 0.5)),
            "viewport_same_shadows_values": {"differing_pixels": differ, "hit_pixels": int(hit.sum())}}


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
