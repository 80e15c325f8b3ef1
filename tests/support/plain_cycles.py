"""A plain Cycles render of a .blend with its own materials (run in a child process).

    python tests/support/plain_cycles.py FILE.blend OUT.npz

Diffuse Direct with and without the light's shadows, nothing else changed but the
sample count (1), the light's radius (0, as the reference renders it), and the passes:
the check that the reference's per-material overrides keep the file's transparency.
Writes `shadowed`, `unshadowed` and `alpha` (the film's, as the hit mask) (H, W), row 0 at the top.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def mean_visibilities(ref, blend: Path, out: Path) -> tuple[float, float, float]:
    """Render `blend` plainly (a child process) into `out`; the reference's and the plain
    render's mean visibility over the pixels both hit and both light, and that share of the
    reference's hits (a plain render's camera rays can end inside a volume: those go)."""
    from addon.core import metrics
    from tests.support.cli_run import python_ok

    python_ok(Path(__file__), blend, out)
    plain = dict(np.load(out))
    eps = metrics.UNSHADOWED_EPS
    both = ref.hit & (plain["alpha"] > 0.5) & (ref.unshadowed > eps) & (plain["unshadowed"] > eps)
    ours = float(metrics.reference_ratio(ref.shadowed, ref.unshadowed)[both].mean())
    theirs = float(metrics.reference_ratio(plain["shadowed"], plain["unshadowed"])[both].mean())
    return ours, theirs, float(both.sum()) / max(int(ref.hit.sum()), 1)


def main(blend: str, out: str) -> None:
    import bpy

    from addon.reference.capture import Overrides, set_pass_output
    from addon.reference.pass_files import read_exr_channels, stack_pass
    from addon.compat import blender as blender_compat

    bpy.ops.wm.open_mainfile(filepath=blend)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device, cycles.samples, cycles.use_denoising, cycles.use_adaptive_sampling = "CPU", 1, False, False
    cycles.pixel_filter_type, cycles.filter_width = "GAUSSIAN", 0.01
    light = next(o for o in scene.objects if o.type == "LIGHT")
    light.data.shadow_soft_size = 0.0
    layer = scene.view_layers[0]
    layer.use_pass_diffuse_direct = True
    folder = Path(tempfile.mkdtemp())
    set_pass_output(scene.render, str(folder / "pass"), Overrides())  # a multilayer EXR, transparent film
    diffuse = blender_compat.exr_pass_name("Diffuse Direct")
    passes = {}
    for label, shadows in (("shadowed", True), ("unshadowed", False)):
        light.data.use_shadow = shadows
        bpy.ops.render.render(write_still=True)
        path = next(folder.glob("pass*.exr"))
        channels = read_exr_channels(path)
        path.unlink()
        passes[label] = stack_pass(channels, layer.name, diffuse, "RGB").mean(axis=-1)
        passes["alpha"] = channels[f"{layer.name}.Combined.A"]
    np.savez(out, **passes)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
