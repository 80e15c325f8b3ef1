"""The `omniwarp` command line (also `python -m addon`), docs/design.md section 6.

    omniwarp presets
    omniwarp reference --preset SEL [--size WxH] [--refresh]
    omniwarp compare --preset SEL | --blend FILE [--light NAME | --lights all|L1,L2]
                     [--camera NAME | --cameras all|C1,C2] [--frame-range A-B[:STEP]]
                     [--methods m1,m2] [--resolutions 512,1024] [--no-cull | --cull-both] [--repeats N]
                     [--workers N | --scheduler ADDRESS] [--cache-dir DIR] [--out DIR]
    omniwarp preview --preset NAME | --blend FILE [--light NAME] [--method M] [--resolution R] [--out DIR]

The method names and what each fits come from `core/methods.py`.

The exit contract (`core/errors.py`), the same for every command: 0 done; 2 bad
input or environment, with one line on stderr naming the problem and what to do;
130 interrupted (Ctrl-C; 143 for SIGTERM), one line, temporaries removed; 1 a bug only, with its
traceback. Input is checked before any long work starts. Result lines go to stdout;
progress, Blender's own log and errors go to stderr.
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import logging
import os
import sys
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TextIO

from .core import child, interrupt
from .core import methods as method_registry
from .core.errors import (
    EXIT_BAD_INPUT,
    EXIT_BUG,
    EXIT_CONTRACT,
    InputError,
    OmniWarpError,
    report_error,
    report_interrupt,
)
from .core.outputs import StagedOutput, check_output_dir
from .core.presets import available_presets, build_preset, select_presets
from .core.scene import parse_size
# capture.py imports bpy only inside functions: this import needs no Blender.
from .reference.capture import DEFAULT_SAMPLES, SOFT_SAMPLES
from .render.frame import EXACT_SAMPLES, check_exact_samples
from .render.shaders import EXACT_SOFT_MAX_POINTS
from .core.rows import row_label

log = logging.getLogger("omniwarp")

PROGRAM = "omniwarp"
MAX_FRAMES = 1000  # timing repeats per row
DEFAULT_REPEATS = 3
MAX_SAMPLES = 64
MAX_SOFT_SAMPLES = 4096
MAX_WORKERS = 256


class _Parser(argparse.ArgumentParser):
    """argparse with the exit contract: a usage error is one line and status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROGRAM, description="Omnidirectional shadow maps measured against Cycles. "
                                                "Result lines go to stdout; progress and Blender's log to stderr.",
                     epilog=EXIT_CONTRACT)
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", required=True)

    sub.add_parser("presets", help="list presets and what each stresses", epilog=EXIT_CONTRACT)

    ref = sub.add_parser("reference", help="build or refresh the Cycles reference cache", epilog=EXIT_CONTRACT)
    rsource = ref.add_mutually_exclusive_group(required=True)
    rsource.add_argument("--preset", help="a preset, a comma list, 'all' or 'stress_all'")
    rsource.add_argument("--blend", help="a saved .blend file (its scene camera and one point/spot light or sun)")
    ref.add_argument("--light", help="with --blend: the light object to use")
    ref.add_argument("--camera", help="with --blend: the camera object to use")
    ref.add_argument("--size", default="640x480", help="camera size WxH for presets (default 640x480)")
    ref.add_argument("--refresh", action="store_true", help="render again even when cached")
    ref.add_argument("--samples", type=int, default=DEFAULT_SAMPLES,
                     help=f"Cycles samples per pixel, 1-{MAX_SAMPLES} (default {DEFAULT_SAMPLES}: exact for a hard "
                          f"point light, and the reference compare and preview read)")
    _add_light_size_options(ref)

    cmp_ = sub.add_parser("compare", help="measure methods against Cycles: error %% and time per stage",
                          epilog=EXIT_CONTRACT)
    source = cmp_.add_mutually_exclusive_group(required=True)
    source.add_argument("--preset", help="a preset, a comma list, 'all' (non-stress) or 'stress_all'")
    source.add_argument("--blend", help="a saved .blend file (its scene camera and one point/spot light)")
    cmp_.add_argument("--light", help="with --blend: the light object to use")
    cmp_.add_argument("--camera", help="with --blend: the camera object to use")
    cmp_.add_argument("--lights", help="with --blend: 'all' (every rendered point, spot, sun or area light) or L1,L2: "
                                       "one job per light")
    cmp_.add_argument("--cameras", help="with --blend: 'all' or C1,C2: one job per camera")
    cmp_.add_argument("--frame-range", metavar="A-B[:STEP]",
                      help="with --blend: the frames A, A+STEP, ... B of the file's animation, one job each "
                           "(default: the file's current frame)")
    cmp_.add_argument("--methods", default=",".join(method_registry.DEFAULT_METHODS),
                      help=f"comma list of methods: {method_registry.help_list()} "
                           f"(default {','.join(method_registry.DEFAULT_METHODS)})")
    cmp_.add_argument("--resolutions", help="comma list of map resolutions")
    culling = cmp_.add_mutually_exclusive_group()
    culling.add_argument("--no-cull", action="store_true", help="draw every layer and triangle (measure culling)")
    culling.add_argument("--cull-both", action="store_true",
                         help="measure every row with and without culling, in the same run")
    cmp_.add_argument("--exact-samples", type=int, default=EXACT_SAMPLES,
                      help=f"a sized light's points per view sample in the exact method, a square number up to "
                           f"{EXACT_SOFT_MAX_POINTS} (default {EXACT_SAMPLES})")
    cmp_.add_argument("--out", default="out/compare", help="output folder (default out/compare)")
    cmp_.add_argument("--size", default="640x480", help="camera size WxH for presets (default 640x480)")
    cmp_.add_argument("--repeats", type=int, default=None,
                      help=f"timed repeats per row after one warm-up, 1-{MAX_FRAMES} (default {DEFAULT_REPEATS})")
    cmp_.add_argument("--frames", type=int, default=None, help="deprecated: the old name of --repeats")
    where = cmp_.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="run the jobs on a local Dask cluster of N worker processes "
                                                   "(one thread, one GL context and one bpy each)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="run the jobs on the Dask cluster at ADDRESS, e.g. tcp://10.0.0.5:8786 (docs/sweeps.md)")
    cmp_.add_argument("--cache-dir", help="the Cycles reference cache folder (default $OMNIWARP_CACHE or .cache/); "
                                          "with --scheduler, a folder every worker shares")
    cmp_.add_argument("--no-images", action="store_true",
                      help="skip the mismatch images (and remove the images/ of an earlier run)")
    _add_light_size_options(cmp_)

    prev = sub.add_parser("preview", help="the viewport preview and map overlay, drawn headless with Blender's gpu",
                          epilog=EXIT_CONTRACT)
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


def _result(args: argparse.Namespace, line: str) -> None:
    """One result line on the real stdout (fd 1 carries Blender's log to stderr meanwhile)."""
    print(line, file=getattr(args, "results", None) or sys.stdout, flush=True)


def _add_light_size_options(parser: argparse.ArgumentParser) -> None:
    """The light's size in the reference (capture.capture): kept as the file has it, or not."""
    parser.add_argument("--hard", action="store_true",
                        help="give the light no size in the references (radius 0, a sun's angle 0, a tiny area "
                             "light): the hard-shadow study")
    parser.add_argument("--soft-samples", type=int, default=SOFT_SAMPLES,
                        help=f"Cycles samples per pixel of a sized light's reference, even, 2-{MAX_SOFT_SAMPLES} "
                             f"(default {SOFT_SAMPLES}, in two halves that measure its noise)")


def _light_size(args: argparse.Namespace) -> dict:
    """The reference loaders' light-size arguments, checked (exit 2 on a bad count)."""
    soft = getattr(args, "soft_samples", SOFT_SAMPLES)
    if not 2 <= soft <= MAX_SOFT_SAMPLES or soft % 2:
        raise InputError(f"bad --soft-samples {soft}: use an even number in 2-{MAX_SOFT_SAMPLES}")
    return {"hard": bool(getattr(args, "hard", False)), "soft_samples": soft}


def cmd_presets(args: argparse.Namespace) -> int:
    for info in available_presets().values():
        _result(args, f"{info.name:14s} {info.description}\n{'':14s} stresses: {info.stresses}")
    return 0


def cmd_reference(args: argparse.Namespace) -> int:
    from .reference.cache import load_or_capture

    size = parse_size(args.size)
    if not 1 <= args.samples <= MAX_SAMPLES:
        raise InputError(f"bad --samples {args.samples}: use 1-{MAX_SAMPLES}")
    if args.blend is not None:
        ref = _blend_reference(args)()
        _result(args, f"{Path(args.blend).name}: {ref.hit.shape[1]}x{ref.hit.shape[0]}, {int(ref.hit.sum())} hit "
                      f"pixels, {len(ref.triangles)} triangles, key {ref.meta.get('cache_key', '?')}")
        _say_line_gaps()
        return 0
    if args.light or args.camera:
        raise InputError("--light and --camera apply to --blend only")
    names = select_presets(args.preset)
    if args.samples != DEFAULT_SAMPLES:
        _say(f"note: compare and preview read the {DEFAULT_SAMPLES}-sample reference; "
             f"this {args.samples}-sample one is cached beside it")
    for name in names:
        ref = load_or_capture(name, size, refresh=args.refresh, samples=args.samples, log_progress=_say,
                              **_light_size(args))
        seconds = ref.meta.get("render_seconds", {})
        _result(args, f"{name}: {size[0]}x{size[1]}, {int(ref.hit.sum())} hit pixels, {len(ref.triangles)} triangles, "
                      f"key {ref.meta.get('cache_key', '?')}, render s {seconds}")
    _say_line_gaps()
    return 0


def _say_line_gaps() -> None:
    """One note per API the installed Blender line lacks (docs/versions.md); none on 5.2 or without bpy.

    Said after a run's results, so bad input stays the one error line."""
    import importlib.util

    if importlib.util.find_spec("bpy") is None:
        return
    from .compat.blender import line_gaps

    for gap in line_gaps():
        _say(f"note: {gap.text}")


def _need_bpy(option: str) -> None:
    """InputError (exit 2) when bpy is missing, before anything is loaded."""
    import importlib.util

    if importlib.util.find_spec("bpy") is None:
        pin = "bpy==5.2.3" if sys.version_info[:2] >= (3, 13) else "bpy==4.5.15"  # PyPI: one CPython per line
        raise InputError(f"{option} needs the bpy module (pip install {pin})")


def _blend_reference(args: argparse.Namespace, check: Callable[[str], None] | None = None) -> Callable[[], object]:
    """The loader of a --blend reference; the file is checked now, before any long work.

    `check(emission)` runs once the light is known and before Cycles renders.
    """
    from .reference.blend_file import check_blend_file

    path = check_blend_file(args.blend)
    size_options = _light_size(args)
    _need_bpy("--blend")

    def load():
        from .reference.blend_cache import load_or_capture_blend
        from .reference.blend_file import open_scene

        scene = open_scene(path, args.camera, args.light)
        return load_or_capture_blend(path, scene, args.light, samples=getattr(args, "samples", DEFAULT_SAMPLES),
                                     refresh=getattr(args, "refresh", False), progress=_say, check=check,
                                     **size_options)

    return load


def _repeats(args: argparse.Namespace) -> tuple[int, str]:
    """--repeats, or its deprecated alias --frames, and the one warning line that alias
    gets ("" for --repeats); the caller says it at the end of a run that succeeded."""
    if args.frames is not None and args.repeats is not None:
        raise InputError("--frames is the old name of --repeats: give --repeats only")
    option, value = ("--frames", args.frames) if args.frames is not None else ("--repeats", args.repeats)
    value = DEFAULT_REPEATS if value is None else value
    if not 1 <= value <= MAX_FRAMES:
        raise InputError(f"bad {option} {value}: use 1-{MAX_FRAMES}")
    warning = ("warning: --frames is deprecated: use --repeats (the timed repeats per row); "
               "a shot's frames are --frame-range") if option == "--frames" else ""
    return value, warning


def _compare_jobs(args: argparse.Namespace, methods: Sequence[str]) -> list:
    """The run's jobs, one per (scene, frame, light, camera), their names checked now."""
    from .compare import check_methods_fit
    from .shots import blend_jobs, parse_frame_range, parse_names, preset_jobs

    shot_options = {"--light": args.light, "--camera": args.camera, "--lights": args.lights,
                    "--cameras": args.cameras, "--frame-range": args.frame_range}
    if args.preset is not None:
        given = [name for name, value in shot_options.items() if value is not None]
        if given:
            named = "--light and --camera" if set(given) <= {"--light", "--camera"} else " and ".join(given)
            raise InputError(f"{named} apply to --blend only")
        size = parse_size(args.size)
        names = select_presets(args.preset)
        # Building a preset is cheap (no Blender): its light says which methods fit.
        check_methods_fit(methods, {name: build_preset(name, size).light.emission for name in names})
        return preset_jobs(names, size)
    for one, several in (("--light", "--lights"), ("--camera", "--cameras")):
        if shot_options[one] is not None and shot_options[several] is not None:
            raise InputError(f"{one} and {several}: give one of them")
    frames = parse_frame_range(args.frame_range)
    lights = parse_names(args.lights, "--lights") or ([args.light] if args.light else None)
    cameras = parse_names(args.cameras, "--cameras") or ([args.camera] if args.camera else None)
    from .reference.blend_file import check_blend_file

    path = check_blend_file(args.blend)
    _need_bpy("--blend")
    return blend_jobs(path, frames, lights, cameras, lambda emissions: check_methods_fit(methods, emissions))


def cmd_compare(args: argparse.Namespace) -> int:
    from .compare import DEFAULT_RESOLUTIONS, CompareOptions, parse_resolutions, run_compare

    # Everything the user typed is checked here, before any render or measurement.
    methods = method_registry.parse_methods(args.methods)
    resolutions = DEFAULT_RESOLUTIONS if args.resolutions is None else parse_resolutions(args.resolutions)
    repeats, deprecated = _repeats(args)
    if args.workers is not None and not 1 <= args.workers <= MAX_WORKERS:
        raise InputError(f"bad --workers {args.workers}: use 1-{MAX_WORKERS}")
    out = check_output_dir(args.out)
    if args.cache_dir is not None:
        from .reference.cache import check_cache_dir

        check_cache_dir(Path(args.cache_dir))
    size_options = _light_size(args)  # checked before the scenes are opened
    check_exact_samples(args.exact_samples, "bad --exact-samples")
    jobs = [dataclasses.replace(job, **size_options) for job in _compare_jobs(args, methods)]
    options = CompareOptions(methods, resolutions, cull=not args.no_cull, cull_both=args.cull_both, frames=repeats,
                             exact_samples=args.exact_samples, out_dir=out, write_images=not args.no_images,
                             command="omniwarp " + " ".join(args.argv))
    if args.workers is not None or args.scheduler is not None:
        if importlib.util.find_spec("distributed") is None:
            raise InputError("--workers and --scheduler need Dask (pip install 'omniwarp-shadows[dask]')")
        from . import cluster  # Dask is imported here only

        def measure(image_dir):
            return cluster.run_jobs(jobs, options, image_dir, workers=args.workers, scheduler=args.scheduler,
                                    cache_dir=args.cache_dir)
    else:
        from .render.backends.moderngl.backend import ModernGLBackend
        from .render.pipeline import ShadowPipeline
        from .shots import run_jobs

        def measure(image_dir):
            return run_jobs(jobs, options, lambda: ShadowPipeline(ModernGLBackend()), image_dir, args.cache_dir)
    rows = run_compare(measure, options)
    # A sweep's lines say the frame, light and camera where they vary; one job's stay as they were.
    varying = [key for key in ("frame", "light", "camera") if len({str(row.get(key)) for row in rows}) > 1]
    for row in rows:
        passes = f"  passes {row['passes']}" if "passes" in row else ""
        passes += f"  GPU {row['gpu_ms']['total']:7.2f} ms" if "gpu_ms" in row else ""
        shot = "".join(f" {key} {row[key]}" for key in varying if key in row)
        _result(args, f"{row['preset']:12s}{shot} {row_label(row):6s} {row.get('resolution', ''):>5}  "
                      f"error {row['error_pct']:6.3f} %  total {row['time_ms']['total']:8.1f} ms{passes}")
    if deprecated:
        _say(deprecated)  # after the run, like the line notes: a failed run shows its error line only
    _say_line_gaps()
    return 0


def cmd_preview(args: argparse.Namespace) -> int:
    """Reference first (Cycles, this process), then the Blender gpu backend in a child process."""
    from .compare import parse_resolutions

    # The method is checked here, before any Cycles render: unknown or external (eevee) at
    # once, a misfit as soon as the light's emission is known (a preset's from its spec,
    # a .blend's once its light is picked, before its reference renders).
    entry = _preview_method(args.method)  # None: chosen by the light (worker)
    resolution = parse_resolutions(str(args.resolution))[0]
    out = check_output_dir(args.out)

    def fits(emission: str) -> None:
        if entry is not None:
            method_registry.check_fits(entry.name, emission, pipeline_only=True)

    if args.preset is not None:
        if "," in args.preset or args.preset in ("all", "stress_all"):
            raise InputError("preview takes one preset name")
        name = select_presets(args.preset)[0]
        size = parse_size(args.size)
        fits(build_preset(name, size).light.emission)
        _need_bpy("preview")
        from .reference.cache import load_or_capture

        reference = load_or_capture(name, size, log_progress=_say)
        source = ["--preset", name]
    else:
        args.camera = None

        def check(emission: str) -> None:
            fits(emission)
            _check_stored_settings(args.light)

        load = _blend_reference(args, check=check)
        reference = load()
        source = ["--blend", str(Path(args.blend).resolve())] + (["--light", args.light] if args.light else [])
    fits(reference.emission)
    method = entry.name if entry is not None else None
    with StagedOutput(out) as stage, interrupt.temporary_dir("omniwarp_preview_") as tmp:
        ref_path = reference.save(tmp / "reference.npz")
        _say("drawing the preview with Blender's gpu (child process)")
        # One GL owner per process: Blender's gpu runs in a child (docs/design.md section 3).
        # Blender's session folder goes inside ours: gone with it even if the child is killed.
        child.run_module("addon.blender.headless", [*source, "--reference", ref_path, "--out", stage.path,
                                                    *(["--method", method] if method else []),
                                                    "--resolution", resolution],
                         what="preview", tmpdir=tmp, refused=InputError)
        stage.commit()
    _result(args, f"wrote {out / 'preview.png'}, {out / 'overlay.png'}, {out / 'preview.json'}")
    report = json.loads((out / "preview.json").read_text())
    _result(args, f"error {report['error_pct']:.3f} % of {report['evaluated_pixels']} px; "
                  f"total {report['time_ms']['total']:.1f} ms (+ G-buffer {report['time_ms']['gbuffer']:.1f} ms)")
    _say_line_gaps()
    return 0


def _check_stored_settings(light_name: str | None) -> None:
    """The OmniWarp settings saved on the loaded file's lights, checked with the
    pipeline's own rules before the Cycles render: a NaN or infinite bias is refused
    here rather than after the reference. Read raw (the ID properties under "omniwarp"):
    the add-on is registered in the preview's child process only."""
    import bpy

    from .compat import blender as blender_compat
    from .render.pipeline import BiasSettings

    default = BiasSettings()
    for obj in bpy.context.scene.objects:
        if obj.type != "LIGHT" or (light_name and obj.name != light_name):
            continue
        group = blender_compat.system_properties(obj.data)
        stored = group.get("omniwarp") if group is not None else None
        if stored is None or not stored.get("enabled", False):
            continue
        try:
            BiasSettings(**{name: stored.get(f"bias_{name}", getattr(default, name))
                            for name in ("constant", "slope", "normal")})
        except InputError as exc:
            raise InputError(f"light {obj.name!r}: {exc} (its OmniWarp settings)") from None


COMMANDS = {"presets": cmd_presets, "reference": cmd_reference, "compare": cmd_compare, "preview": cmd_preview}


class ResultStreams:
    """While a command runs, file descriptor 1 is taken from the terminal, so that
    Blender's log ("Read blend", "Saved: ...pass.exr", written from C to fd 1) never
    mixes with the results: `results` writes to the real stdout.

    Blender's log is kept in a temporary file (`log_tail()` shows its end after a bug)
    or, with --verbose, goes to stderr. When sys.stdout is not descriptor 1 (a test's
    capture), it is the results stream itself and only the descriptor is redirected.
    """

    def __init__(self, verbose: bool = False) -> None:
        self.verbose = verbose
        self.results: TextIO = sys.stdout
        self._saved: int | None = None
        self._log: TextIO | None = None

    def __enter__(self) -> "ResultStreams":
        import tempfile

        stream = sys.stdout
        try:
            stream.flush()
            own = stream.fileno() == 1
        except (AttributeError, OSError, ValueError):
            own = False
        try:
            self._saved = os.dup(1)
        except OSError:
            return self  # no descriptor 1 at all: nothing to keep apart
        if self.verbose:
            os.dup2(2, 1)
        else:
            self._log = tempfile.TemporaryFile(mode="w+", encoding="utf-8", errors="replace")
            os.dup2(self._log.fileno(), 1)
        if own:
            self.results = os.fdopen(os.dup(self._saved), "w", buffering=1, errors="replace",
                                     encoding=getattr(stream, "encoding", None) or "utf-8")
        return self

    def log_tail(self, limit: int = 4000) -> str:
        """The end of Blender's captured log ("" with --verbose, where it went to stderr)."""
        if self._log is None:
            return ""
        try:
            sys.stdout.flush()
            self._log.seek(0)
            return self._log.read()[-limit:]
        except (OSError, ValueError):
            return ""

    def __exit__(self, *exc_info) -> None:
        if self._saved is None:
            return
        if self.results is not sys.stdout:
            try:
                self.results.close()
            except OSError as exc:  # e.g. a closed pipe: the results are gone either way
                log.debug("closing the results stream: %s", exc)
        try:
            sys.stdout.flush()
        except (OSError, ValueError) as exc:
            log.debug("flushing stdout: %s", exc)
        os.dup2(self._saved, 1)
        os.close(self._saved)
        self._saved = None


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `omniwarp` console script (and `python -m addon`).

    Called without `argv` the process is the command's own: Ctrl-C during a Cycles
    render then ends it at once (`core/interrupt.py`). Called with `argv` (from Python,
    a test) an interrupt is raised when the render returns instead.
    """
    own_process = argv is None
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    args.argv = argv
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    streams = ResultStreams(verbose=args.verbose)
    try:
        with interrupt.handling(PROGRAM, exit_at_once=own_process), streams:
            args.results = streams.results
            try:
                return COMMANDS[args.command](args)
            except (KeyboardInterrupt, OmniWarpError):
                raise
            except Exception:  # noqa: BLE001 - re-raised below, with Blender's log
                blender_log = streams.log_tail()
                if blender_log.strip():
                    print(f"--- the end of Blender's log ---\n{blender_log.rstrip()}\n---", file=sys.stderr)
                raise
    except KeyboardInterrupt as exc:  # Interrupted, or Python's own before the handler was in place
        return report_interrupt(PROGRAM, exc, interrupt.kept_note())
    except OmniWarpError as exc:
        return report_error(PROGRAM, exc)
    except Exception:  # noqa: BLE001 - the contract: anything unnamed is a bug, shown in full
        traceback.print_exc()
        print(f"{PROGRAM}: internal error: this is a bug; please report it with the traceback above",
              file=sys.stderr, flush=True)
        return EXIT_BUG


if __name__ == "__main__":
    sys.exit(main())
