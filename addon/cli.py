"""The `omniwarp` command line (also `python -m addon`), DESIGN.md section 6.

    omniwarp presets
    omniwarp reference --preset SEL [--size WxH] [--refresh]
    omniwarp compare --preset SEL | --blend FILE [--light NAME] [--camera NAME]
                     [--methods m1,m2] [--resolutions 512,1024] [--no-cull | --cull-both] [--out DIR]
    omniwarp preview --preset NAME | --blend FILE [--light NAME] [--method M] [--resolution R] [--out DIR]

The method names and what each fits come from `core/methods.py`.

Bad input exits with status 2 and one line naming the problem; other known
failures exit with status 1.
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from .core import methods as method_registry
from .core.errors import InputError, OmniWarpError, child_stderr_tail, report_error
from .core.presets import DEFAULT_PRESET, available_presets, select_presets
from .core.scene import parse_size

log = logging.getLogger("omniwarp")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="omniwarp", description="Omnidirectional shadow maps measured against Cycles.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", required=True)

    sub.add_parser("presets", help="list presets and what each stresses")

    ref = sub.add_parser("reference", help="build or refresh the Cycles reference cache")
    ref.add_argument("--preset", required=True, help="a preset, a comma list, 'all' or 'stress_all'")
    ref.add_argument("--size", default="640x480", help="camera size WxH (default 640x480)")
    ref.add_argument("--refresh", action="store_true", help="render again even when cached")
    ref.add_argument("--samples", type=int, default=2, help="Cycles samples per pixel (1-4 suffice)")

    cmp_ = sub.add_parser("compare", help="measure methods against Cycles: error %% and time per stage")
    source = cmp_.add_mutually_exclusive_group(required=True)
    source.add_argument("--preset", help="a preset, a comma list, 'all' (non-stress) or 'stress_all'")
    source.add_argument("--blend", help="a saved .blend file (its scene camera and one point/spot light)")
    cmp_.add_argument("--light", help="with --blend: the light object to use")
    cmp_.add_argument("--camera", help="with --blend: the camera object to use")
    cmp_.add_argument("--methods", default=",".join(method_registry.DEFAULT_METHODS),
                      help=f"comma list of methods: {method_registry.help_list()} "
                           f"(default {','.join(method_registry.DEFAULT_METHODS)})")
    cmp_.add_argument("--resolutions", default="512,1024,2048", help="comma list of map resolutions")
    culling = cmp_.add_mutually_exclusive_group()
    culling.add_argument("--no-cull", action="store_true", help="draw every layer and triangle (measure culling)")
    culling.add_argument("--cull-both", action="store_true",
                         help="measure every row with and without culling, in the same run")
    cmp_.add_argument("--out", default="out/compare", help="output folder (default out/compare)")
    cmp_.add_argument("--size", default="640x480", help="camera size WxH for presets (default 640x480)")
    cmp_.add_argument("--frames", type=int, default=3, help="timed frames per row after one warm-up (default 3)")
    cmp_.add_argument("--no-images", action="store_true", help="skip the mismatch images")

    prev = sub.add_parser("preview", help="the viewport preview and map overlay, drawn headless with Blender's gpu")
    psource = prev.add_mutually_exclusive_group(required=True)
    psource.add_argument("--preset", help="one preset name")
    psource.add_argument("--blend", help="a saved .blend file (its scene camera)")
    prev.add_argument("--light", help="with --blend: the light object to preview")
    prev.add_argument("--out", default="out/preview", help="output folder (default out/preview)")
    prev.add_argument("--size", default="640x480", help="camera size WxH for presets (default 640x480)")
    prev.add_argument("--method", default=None, help=_preview_method_help())
    prev.add_argument("--resolution", type=int, default=1024, help="map resolution for those lights (default 1024)")
    return parser


def _preview_method_help() -> str:
    """The `preview --method` help, from the method registry."""
    external = method_registry.external_methods()
    return (f"method for lights without OmniWarp settings, e.g. a preset's: one of "
            f"{', '.join(method_registry.pipeline_methods())}"
            + (f"; {', '.join(external)} only in compare" if external else "")
            + f"; default {method_registry.default_method('omni')} for point lights, "
              f"{method_registry.default_method('spot')} for spot and sun lights")


def _preview_method(text: str | None) -> method_registry.Method | None:
    """The `preview --method` entry: one method the pipeline draws (InputError otherwise)."""
    if text is None:
        return None
    name = text.strip()
    if "," in name:
        raise InputError(f"--method {text!r}: preview takes one method")
    entry = method_registry.method(name)
    if entry.external:
        raise InputError(f"--method {name}: preview draws the pipeline's methods only "
                         f"({', '.join(method_registry.pipeline_methods())}); {name} is measured by compare")
    return entry


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def cmd_presets(_: argparse.Namespace) -> int:
    for info in available_presets().values():
        print(f"{info.name:14s} {info.description}\n{'':14s} stresses: {info.stresses}")
    return 0


def cmd_reference(args: argparse.Namespace) -> int:
    from .reference.cache import load_or_capture

    size = parse_size(args.size)
    if not 1 <= args.samples <= 64:
        raise InputError(f"bad --samples {args.samples}: use 1-64")
    for name in select_presets(args.preset):
        ref = load_or_capture(name, size, refresh=args.refresh, samples=args.samples, log_progress=_say)
        seconds = ref.meta.get("render_seconds", {})
        print(f"{name}: {size[0]}x{size[1]}, {int(ref.hit.sum())} hit pixels, {len(ref.triangles)} triangles, "
              f"key {ref.meta.get('cache_key', '?')}, render s {seconds}")
    return 0


def _blend_reference(args: argparse.Namespace) -> Callable[[], object]:
    path = Path(args.blend)
    if not path.is_file():
        raise InputError(f"--blend file not found: {path}")
    if path.suffix.lower() != ".blend":
        raise InputError(f"--blend expects a .blend file, got {path.name}")

    def load():
        try:
            import bpy
        except ImportError:
            raise InputError("--blend needs the bpy module (pip install bpy==5.2.3)") from None
        from .reference.capture import capture

        # Loading replaces bpy's in-memory data only; nothing is ever saved back.
        bpy.ops.wm.open_mainfile(filepath=str(path.resolve()), load_ui=False)
        scene = bpy.context.scene
        if args.camera:
            cam = bpy.data.objects.get(args.camera)
            if cam is None or cam.type != "CAMERA":
                raise InputError(f"--camera {args.camera!r}: no camera object of that name in {path.name}")
            scene.camera = cam
        if args.light and (bpy.data.objects.get(args.light) is None):
            raise InputError(f"--light {args.light!r}: no object of that name in {path.name}")
        _say(f"rendering Cycles reference of {path.name}")
        return capture(scene, light=args.light, progress=_say)

    return load


def cmd_compare(args: argparse.Namespace) -> int:
    from .compare import CompareOptions, parse_resolutions, run_compare
    from .render.moderngl_backend import ModernGLBackend
    from .render.pipeline import ShadowPipeline

    methods = method_registry.parse_methods(args.methods)
    resolutions = parse_resolutions(args.resolutions)
    if args.frames < 1:
        raise InputError(f"bad --frames {args.frames}: at least 1")
    if args.preset is not None and (args.light or args.camera):
        raise InputError("--light and --camera apply to --blend only")
    if args.preset is not None:
        size = parse_size(args.size)
        from .reference.cache import load_or_capture

        names = select_presets(args.preset)
        references = {name: (lambda n=name: load_or_capture(n, size, log_progress=_say)) for name in names}
        sources = {name: ["--preset", name, "--size", f"{size[0]}x{size[1]}"] for name in names}
    else:
        references = {Path(args.blend).stem: _blend_reference(args)}
        sources = {Path(args.blend).stem: ["--blend", str(Path(args.blend).resolve())]
                   + (["--light", args.light] if args.light else [])
                   + (["--camera", args.camera] if args.camera else [])}
    options = CompareOptions(methods, resolutions, cull=not args.no_cull, cull_both=args.cull_both, frames=args.frames,
                             out_dir=Path(args.out), write_images=not args.no_images,
                             command="omniwarp " + " ".join(args.argv))
    rows = run_compare(references, options, lambda: ShadowPipeline(ModernGLBackend()), sources)
    for row in rows:
        print(f"{row['preset']:12s} {row['method']:6s} {row['resolution']:5d}  error {row['error_pct']:6.3f} %  "
              f"total {row['time_ms']['total']:8.1f} ms  passes {row['passes']}")
    return 0


def cmd_preview(args: argparse.Namespace) -> int:
    """Reference first (Cycles, this process), then the Blender gpu backend in a child process."""
    import os
    import subprocess
    import tempfile

    from .compare import parse_resolutions

    # The method is checked here, before any Cycles render: unknown or external (eevee) at
    # once, a misfit as soon as the light's emission is known (a preset's from its spec,
    # a .blend's once its reference is rendered).
    entry = _preview_method(args.method)  # None: chosen by the light (worker)
    resolution = parse_resolutions(str(args.resolution))[0]
    if args.preset is not None:
        if "," in args.preset or args.preset in ("all", "stress_all"):
            raise InputError("preview takes one preset name")
        name = select_presets(args.preset)[0]
        size = parse_size(args.size)
        if entry is not None:
            from .core.presets import build_preset

            method_registry.check_fits(entry.name, build_preset(name, size).light.emission, pipeline_only=True)
        from .reference.cache import load_or_capture

        reference = load_or_capture(name, size, log_progress=_say)
        source = ["--preset", name]
    else:
        args.camera = None
        reference = _blend_reference(args)()
        source = ["--blend", str(Path(args.blend).resolve())] + (["--light", args.light] if args.light else [])
    if entry is not None:
        method_registry.check_fits(entry.name, reference.emission, pipeline_only=True)
    method = entry.name if entry is not None else None
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="omniwarp_preview_") as tmp:
        ref_path = reference.save(Path(tmp) / "reference.npz")
        env = dict(os.environ)
        repo_root = str(Path(__file__).resolve().parents[1])
        env["PYTHONPATH"] = repo_root + os.pathsep + env.get("PYTHONPATH", "")
        # One GL owner per process: Blender's gpu runs in a child (DESIGN.md section 3).
        proc = subprocess.run([sys.executable, "-m", "addon.blender.headless", *source,
                               "--reference", str(ref_path), "--out", str(out.resolve()),
                               *(["--method", method] if method else []), "--resolution", str(resolution)],
                              env=env, cwd=repo_root, capture_output=True, text=True)
    if proc.returncode != 0:
        raise OmniWarpError(f"the preview process failed (exit {proc.returncode}):\n{child_stderr_tail(proc.stderr)}")
    print(f"wrote {out / 'preview.png'}, {out / 'overlay.png'}, {out / 'preview.json'}")
    report = json.loads((out / "preview.json").read_text())
    print(f"error {report['error_pct']:.3f} % of {report['evaluated_pixels']} px; "
          f"total {report['time_ms']['total']:.1f} ms (+ G-buffer {report['time_ms']['gbuffer']:.1f} ms)")
    return 0


COMMANDS = {"presets": cmd_presets, "reference": cmd_reference, "compare": cmd_compare, "preview": cmd_preview}


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `omniwarp` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    args.argv = argv
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return COMMANDS[args.command](args)
    except OmniWarpError as exc:
        return report_error("omniwarp", exc)


if __name__ == "__main__":
    sys.exit(main())


__all__ = ["main", "DEFAULT_PRESET"]
