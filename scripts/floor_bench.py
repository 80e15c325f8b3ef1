"""The floor of a frame: each method's trivial frame beside a bare frame of as many passes.

    python scripts/floor_bench.py [--preset room_omni] [--size 64x48] [--resolution 64]
                                  [--methods dpsm,cube,...] [--frames 60] [--out TABLE.md]

The trivial frame is `ShadowPipeline.render` on moderngl with almost no GPU work: the
preset's view samples at `--size` (cast by the test ray caster, tests/support/oracle.py;
read-only, so they stay on the GPU) and maps of `--resolution` texels. Its draws,
dispatches and clears are counted at the device. The bare frame does as many of each
with moderngl directly (a one-invocation dispatch, a clear and a draw of one triangle
into a 64x64 target) and one wait, in the same process and context. Each is timed as
the median wall time of `--frames` frames, interleaved, each ending with its result on
the host: the trivial frame reads its visibility. Prints a markdown table with the
renderer and date; their ratio is the host work a frame adds above its GPU calls.
In further frames, timed apart, the wall time inside moderngl's calls ("in GL calls")
is split from the rest ("host": Python and numpy). On llvmpipe the GPU's work runs on
the CPU inside those calls, so there the split, not the ratio, says what is host work.
"host alone" times the frame with the calls that make the GPU work (draws, dispatches,
clears, barriers, waits) returning at once: its host work with nothing else.
"""
from __future__ import annotations

import argparse
import datetime
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

METHODS = ("dpsm", "cube", "dpsm+notw", "cube+notw", "exact")

_BARE_COMPUTE = """
#version 430
layout(local_size_x = 1) in;
layout(r32ui, binding = 0) uniform uimage2D counter;
void main() { imageAtomicAdd(counter, ivec2(0, 0), 1u); }
"""
_BARE_VERTEX = """
#version 330
in vec2 corner;
void main() { gl_Position = vec4(corner, 0.0, 1.0); }
"""
_BARE_FRAGMENT = """
#version 330
out vec4 color;
void main() { color = vec4(1.0); }
"""


class _Counted:
    """Counts a device's draws, dispatches and clears while installed."""

    def __init__(self, device) -> None:
        self.device = device
        self.counts = {"draw": 0, "dispatch": 0, "clear": 0, "clear_image": 0}
        self._saved = {}

    def __enter__(self) -> "_Counted":
        for name in self.counts:
            real = getattr(self.device, name)
            self._saved[name] = real

            def counted(*args, _real=real, _name=name, **kwargs):
                self.counts[_name] += 1
                return _real(*args, **kwargs)

            setattr(self.device, name, counted)
        return self

    def __exit__(self, *exc) -> None:
        for name in self._saved:
            delattr(self.device, name)


class _GLClock:
    """Sums the wall time spent inside moderngl's calls while installed (every public
    method of its classes). What a frame spends outside them is host work: Python,
    numpy. On llvmpipe the GPU's work runs inside those calls (a compute dispatch is
    synchronous there, and a pass that reads the one before it waits for it)."""

    CLASSES = ("Context", "Texture", "Framebuffer", "VertexArray", "ComputeShader", "Program", "Buffer",
               "Uniform", "Query", "Scope", "Sampler")

    def __init__(self) -> None:
        self.seconds = 0.0
        self._saved: list[tuple[type, str, object]] = []
        self._depth = 0

    def __enter__(self) -> "_GLClock":
        import moderngl

        for cls in (getattr(moderngl, name) for name in self.CLASSES):
            for name, original in list(vars(cls).items()):
                if name.startswith("_") or not callable(original):
                    continue
                self._saved.append((cls, name, original))
                setattr(cls, name, self._timed(original))
        return self

    def _timed(self, original):
        def timed(*args, **kwargs):
            self._depth += 1
            start = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self._depth -= 1
                if self._depth == 0:  # a call inside a call counts once
                    self.seconds += time.perf_counter() - start
        return timed

    def __exit__(self, *exc) -> None:
        for cls, name, original in reversed(self._saved):
            setattr(cls, name, original)


class _NoGPUWork:
    """While installed, moderngl's calls that make the GPU work (draws, dispatches, clears,
    barriers, waits) return at once: a steady frame then costs its host work alone (its
    reads return what the frames before left, which a steady frame reads anyway)."""

    CALLS = (("VertexArray", "render"), ("ComputeShader", "run"), ("Framebuffer", "clear"),
             ("Context", "memory_barrier"), ("Context", "finish"))

    def __enter__(self) -> "_NoGPUWork":
        import moderngl

        self._saved = [(getattr(moderngl, cls), name, getattr(getattr(moderngl, cls), name)) for cls, name in self.CALLS]
        for cls, name, _ in self._saved:
            setattr(cls, name, lambda *args, **kwargs: None)
        return self

    def __exit__(self, *exc) -> None:
        for cls, name, original in self._saved:
            setattr(cls, name, original)


class BareFrame:
    """A frame of moderngl calls alone: dispatches, clears and draws of 64x64, one wait."""

    def __init__(self, ctx, dispatches: int, draws: int, clears: int) -> None:
        self.ctx = ctx
        self.dispatches, self.draws, self.clears = dispatches, draws, clears
        with ctx:
            self._build(ctx)

    def _build(self, ctx) -> None:
        self.image = ctx.texture((1, 1), 1, dtype="u4")
        self.compute = ctx.compute_shader(_BARE_COMPUTE)
        self.target = ctx.texture((64, 64), 4, dtype="f4")
        self.fbo = ctx.framebuffer(color_attachments=[self.target])
        program = ctx.program(vertex_shader=_BARE_VERTEX, fragment_shader=_BARE_FRAGMENT)
        buffer = ctx.buffer(np.array([-1, -1, 3, -1, -1, 3], dtype="f4").tobytes())
        self.vao = ctx.vertex_array(program, [(buffer, "2f", "corner")])

    def run(self) -> None:
        with self.ctx:
            self.image.bind_to_image(0, read=True, write=True)
            for _ in range(self.dispatches):
                self.compute.run(1)
                self.ctx.memory_barrier()
            self.fbo.use()
            for _ in range(self.clears):
                self.fbo.clear(0.0, 0.0, 0.0, 0.0)
            for _ in range(self.draws):
                self.vao.render()
            self.ctx.finish()


def _median_ms(run, frames: int) -> float:
    times = []
    for _ in range(frames):
        start = time.perf_counter()
        run()
        times.append((time.perf_counter() - start) * 1e3)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="room_omni")
    parser.add_argument("--size", default="64x48")
    parser.add_argument("--resolution", type=int, default=64)
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)

    from addon.core.presets import build_preset
    from addon.render.backends.moderngl.backend import ModernGLBackend
    from addon.render.pipeline import ShadowPipeline, ViewSamples, settings_for
    from tests.support.oracle import view_samples

    size = tuple(int(v) for v in args.size.split("x"))
    scene = build_preset(args.preset, size)
    cast, _, _ = view_samples(scene)
    arrays = [np.array(a) for a in (cast.positions, cast.normals, cast.hit)]
    for array in arrays:
        array.flags.writeable = False  # read-only: resident between frames
    samples = ViewSamples(*arrays, cast.camera)
    triangles = scene.world_triangles()
    triangles.flags.writeable = False
    lines = []
    with ModernGLBackend() as backend:
        pipeline = ShadowPipeline(backend)
        renderer = backend.renderer()
        for method in [m for m in args.methods.split(",") if m]:
            settings = settings_for(method, args.resolution, scene.light.emission)

            def frame() -> None:
                _ = pipeline.render(scene.light, triangles, samples, settings).visibility

            frame()
            frame()  # compiled, allocated, resident
            with _Counted(backend.device) as counted:
                frame()
            calls = counted.counts
            bare = BareFrame(backend.ctx, calls["dispatch"], calls["draw"], calls["clear"] + calls["clear_image"])
            bare.run()
            trivial_ms, bare_ms = [], []
            for _ in range(args.frames):  # interleaved, so that both see the same machine
                trivial_ms.append(_median_ms(frame, 1))
                bare_ms.append(_median_ms(bare.run, 1))
            t, b = statistics.median(trivial_ms), statistics.median(bare_ms)
            host_ms, gl_ms = [], []
            for _ in range(args.frames):  # apart: timing each call slows the frame a little
                with _GLClock() as gl:
                    frame_ms = _median_ms(frame, 1)
                gl_ms.append(gl.seconds * 1e3)
                host_ms.append(frame_ms - gl.seconds * 1e3)
            g, h = statistics.median(gl_ms), statistics.median(host_ms)
            with _NoGPUWork():
                alone = _median_ms(frame, args.frames)
            frame()  # the GPU's work again, before the next method
            lines.append(f"| {method} | {t:.2f} | {b:.3f} | {t / b:.1f} | {g:.2f} | {h:.2f} | {alone:.2f} | "
                         f"{calls['dispatch']} | {calls['draw']} | {calls['clear'] + calls['clear_image']} |")
        pipeline.release()
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    text = "\n".join([
        f"Floor benchmark: {args.preset} at {args.size} view samples, maps of {args.resolution}; "
        f"median of {args.frames} interleaved frames each.",
        f"Renderer: {renderer}. Measured {stamp}. Command: `python scripts/floor_bench.py "
        f"{' '.join(argv if argv is not None else sys.argv[1:])}`".rstrip() + "",
        "",
        "| method | trivial frame ms | bare frame ms | ratio | in GL calls ms | host ms | host alone ms | dispatches "
        "| draws | clears |",
        "|---|---|---|---|---|---|---|---|---|---|",
        *lines, ""])
    print(text)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
