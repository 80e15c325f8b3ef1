"""A steady frame's traffic between host and GPU, per method, counted at moderngl's API.

    python scripts/frame_traffic.py [--presets room_omni,courtyard] [--methods dpsm,cube,...]
                                    [--resolution 1024] [--size 640x480] [--cache-dir DIR]
                                    [--backend moderngl|blender]

For each preset (its cached Cycles reference, rendered once when missing) and method, two
frames of `ShadowPipeline.render` on the same read-only samples, each read, then a third
frame counted (tests/support/traffic.py): host waits (finishes and reads), bytes read
back, uploads and their bytes, and uniform bytes. The frame's result is not read inside
the count: it stays on the GPU until read. Prints a markdown table.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

METHODS = ("dpsm", "cube", "dpsm+notw", "cube+notw", "exact")


def steady_traffic(pipeline, light, scene, samples, settings, warm: int = 2, device_calls: bool = False):
    """The Traffic of a frame after `warm` frames of the same inputs (each read), counted
    at moderngl's API or, with `device_calls`, at the pipeline's device."""
    from tests.support.traffic import Traffic, counting_device

    for _ in range(warm):
        _ = pipeline.render(light, scene, samples, settings).visibility
    traffic = Traffic()
    counter = counting_device(pipeline.backend.device, traffic) if device_calls else traffic.counting()
    with counter:
        result = pipeline.render(light, scene, samples, settings)
    _ = result.visibility  # read after the count, as a viewport's compositor or compare would
    return traffic


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="room_omni,courtyard")
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--resolution", type=int, default=1024)
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--cache-dir", type=Path, default=None)
    parser.add_argument("--backend", choices=("moderngl", "blender"), default="moderngl")
    args = parser.parse_args(argv)

    from addon import compare
    from addon.reference.cache import load_or_capture
    from addon.render.pipeline import ShadowPipeline, settings_for

    size = tuple(int(v) for v in args.size.split("x"))
    print("| preset | method | host waits | finishes | reads | bytes read | uploads | bytes uploaded | uniform bytes |")
    print("|---|---|---|---|---|---|---|---|---|")
    with _backend(args.backend) as backend:
        pipeline = ShadowPipeline(backend)
        for preset in [p for p in args.presets.split(",") if p]:
            ref = load_or_capture(preset, size, cache_dir=args.cache_dir)
            light = compare.light_from_reference(ref)
            samples = compare.samples_from_reference(ref)
            scene = compare.resident_scene(ref)
            for method in [m for m in args.methods.split(",") if m]:
                settings = settings_for(method, args.resolution, light.emission)
                row = steady_traffic(pipeline, light, scene, samples, settings,
                                     device_calls=args.backend == "blender").row()
                print(f"| {preset} | {method} | {row['waits']} | {row['finishes']} | {row['reads']} | "
                      f"{row['read_bytes']:,} | {row['uploads']} | {row['upload_bytes']:,} | {row['uniform_bytes']:,} |")
        pipeline.release()
    return 0


def _backend(name: str):
    if name == "moderngl":
        from addon.render.backends.moderngl.backend import ModernGLBackend

        return ModernGLBackend()
    import bpy  # noqa: F401  (Blender owns GL in this process)

    from addon.render.backends.blender.backend import BlenderGPUBackend
    from addon.render.backends.blender.gpu_objects import ensure_gpu

    ensure_gpu()
    return BlenderGPUBackend()


if __name__ == "__main__":
    sys.exit(main())
