"""Every method's visibility on every preset, on one backend: the rows a refactor must keep.

    python scripts/backend_rows.py OUT.json [--backend moderngl|blender] [--presets P1,P2|all]
                                  [--methods M1,M2] [--resolution 256] [--size 128x96]
    python scripts/backend_rows.py --diff BEFORE.json AFTER.json

`--paced` draws as a command does, with signals handled: long draws in slices, each
waited for (render/pacing.py); its rows must equal an unpaced run's.

For each preset (its cached Cycles reference at `--size`, rendered once when missing) and
each pipeline method that fits its light, one frame at `--resolution`; a row holds the
error %, the evaluated pixels and a SHA-256 of the visibility's bytes, so two runs of two
versions of the code can be compared bit for bit (`--diff`, exit 1 when any row differs).
The `blender` backend runs in a child process that imports bpy (one GL owner per
process); the references must be cached first (a moderngl run caches them).
"""
from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

HARD_PRESETS = ("room_omni", "room_hemi", "courtyard", "spot_street", "sun_field", "foliage")
SOFT_PRESETS = ("soft_room", "soft_softbox", "soft_spot", "soft_sun")


def _presets(text: str) -> list[str]:
    from addon.core.presets import select_presets

    if text == "all":
        return select_presets("all") + select_presets("stress_all")
    return [p for p in text.split(",") if p]


def _rows(args: argparse.Namespace, backend) -> list[dict]:
    from addon import compare
    from addon.core import methods as registry
    from addon.core import metrics
    from addon.reference.cache import load_or_capture
    from addon.render.pipeline import ShadowPipeline, settings_for

    size = tuple(int(v) for v in args.size.split("x"))
    pipeline = ShadowPipeline(backend)
    rows = []
    try:
        for preset in _presets(args.presets):
            ref = load_or_capture(preset, size, cache_dir=args.cache_dir)
            light = compare.light_from_reference(ref)
            samples = compare.samples_from_reference(ref)
            scene = compare.resident_scene(ref)
            evaluable = metrics.evaluable_mask(ref.position, ref.normal, ref.hit, ref.unshadowed, light)
            for method in args.methods.split(","):
                entry = registry.method(method)
                if entry.external or not entry.fits(ref.emission):
                    continue
                settings = settings_for(method, args.resolution, light.emission)
                result = pipeline.render(light, scene, samples, settings)
                vis = result.visibility.astype("f4")
                judged = metrics.judge(result.visibility, ref.shadowed, ref.unshadowed, evaluable,
                                       sized=light.sized, noise=ref.visibility_noise)
                rows.append({"preset": preset, "method": method, "resolution": args.resolution,
                             "error_pct": judged.figure.error_pct,
                             "evaluated": judged.figure.evaluated_pixels,
                             "visibility_sha": hashlib.sha256(vis.tobytes()).hexdigest()[:16]})
                print(f"{backend.name} {preset} {method}: {judged.figure.error_pct:.4f} %", file=sys.stderr)
            backend.release_scene(scene)
    finally:
        backend.release()
    return rows


def _diff(before: Path, after: Path) -> int:
    old = {(r["preset"], r["method"], r["resolution"]): r for r in json.loads(before.read_text())}
    new = {(r["preset"], r["method"], r["resolution"]): r for r in json.loads(after.read_text())}
    differ = 0
    for key in sorted(set(old) | set(new)):
        a, b = old.get(key), new.get(key)
        if a is None or b is None or a != b:
            differ += 1
            print(f"differs: {key}: {a} -> {b}")
    print(f"{len(set(old) & set(new))} rows in both, {differ} differ")
    return 1 if differ else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, nargs="?")
    parser.add_argument("--diff", nargs=2, type=Path)
    parser.add_argument("--backend", choices=("moderngl", "blender"), default="moderngl")
    parser.add_argument("--presets", default=",".join(HARD_PRESETS + SOFT_PRESETS))
    parser.add_argument("--methods", default="dpsm,cube,dpsm+notw,cube+notw,dpsm+rtw,cube+rtw,ipsm,ipsm+notw,"
                                              "ipsm+cut,unfold,unfold+aa,exact,sm,psm")
    parser.add_argument("--resolution", type=int, default=256)
    parser.add_argument("--size", default="128x96")
    parser.add_argument("--cache-dir", default=None)
    parser.add_argument("--paced", action="store_true",
                        help="draw as a command does, signals handled: long draws in slices (render/pacing.py)")
    args = parser.parse_args(argv)
    if args.diff:
        return _diff(*args.diff)
    from addon.core import interrupt

    with interrupt.handling("backend_rows") if args.paced else contextlib.nullcontext():
        rows = _measure(args)
    args.out.write_text(json.dumps(rows, indent=1))
    print(f"{len(rows)} rows -> {args.out}", file=sys.stderr)
    return 0


def _measure(args: argparse.Namespace) -> list[dict]:
    if args.backend == "moderngl":
        from addon.render.backends.moderngl.backend import ModernGLBackend

        return _rows(args, ModernGLBackend())
    else:
        import bpy  # noqa: F401  (Blender owns GL in this process)

        from addon.render.backends.blender.backend import BlenderGPUBackend
        from addon.render.backends.blender.gpu_objects import ensure_gpu

        ensure_gpu()
        return _rows(args, BlenderGPUBackend())


if __name__ == "__main__":
    sys.exit(main())
