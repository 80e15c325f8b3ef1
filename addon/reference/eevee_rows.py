"""The `eevee` rows, on the parent's side (numpy only): run the EEVEE child process
(reference/eevee.py) and turn its files into compare rows measured against the Cycles
reference, with their mismatch images."""
from __future__ import annotations

import json
import logging
import math
import subprocess
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core import child, metrics
from ..core.errors import InputError, ReferenceCaptureError
from ..core.light_shape import shape_from_dict
from ..core.rows import make_row
from .data import ReferenceData
from .eevee import (AREA_AS_SPOT_NOTE, DEFAULT_TIMEOUT_S, PROGRESS_PREFIX, ROW_NOTE, SETTINGS, TILEMAPS, Progress,
                    parse_settings)

log = logging.getLogger(__name__)


def _progress_line(progress: Progress | None) -> Callable[[str], None]:
    """Pass the child's progress lines on to `progress` (Blender prints on stdout too)."""

    def forward(line: str) -> None:
        if line.startswith(PROGRESS_PREFIX) and progress is not None:
            progress(line[len(PROGRESS_PREFIX):].rstrip())

    return forward


def run_child(args: Sequence[str], out_dir: Path, progress: Progress | None = None,
              timeout_s: float | None = DEFAULT_TIMEOUT_S) -> dict[str, Any]:
    """Run `python -m addon.reference.eevee ARGS --out OUT_DIR`; return its eevee.json.

    Progress lines of the child go to `progress`; a failure raises
    ReferenceCaptureError with the tail of the child's stderr.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    summary_path = out_dir / "eevee.json"
    summary_path.unlink(missing_ok=True)  # never read a stale summary
    # Blender's session folder goes under out_dir: removed with it even if the child is
    # killed (on Ctrl-C), which skips Blender's own clean-up.
    try:
        child.run_module("addon.reference.eevee", [*args, "--out", out_dir.resolve()], what="EEVEE",
                         tmpdir=out_dir.resolve(), on_stdout=_progress_line(progress), timeout_s=timeout_s,
                         refused=lambda line: ReferenceCaptureError(f"the EEVEE render failed: {line}"))
    except subprocess.TimeoutExpired:
        raise ReferenceCaptureError(f"the EEVEE process took longer than {timeout_s:.0f} s; killed") from None
    try:
        return json.loads(summary_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ReferenceCaptureError(f"the EEVEE process left no readable {summary_path}: {exc}") from exc


def _load_setting(out_dir: Path, entry: dict[str, Any], shape: tuple[int, int]) -> dict[str, np.ndarray]:
    path = out_dir / entry["file"]
    try:
        with np.load(path, allow_pickle=False) as npz:
            data = {k: npz[k] for k in ("visibility", "shadowed", "unshadowed", "hit")}
    except (OSError, KeyError, ValueError) as exc:
        raise ReferenceCaptureError(f"cannot read EEVEE output {path}: {exc}") from exc
    for name, array in data.items():
        if array.shape != shape:
            raise ReferenceCaptureError(
                f"EEVEE {name} is {array.shape[1]}x{array.shape[0]} but the reference is {shape[1]}x{shape[0]}; "
                "the child rendered another camera size")
    return data


def _finite(value: float, what: str) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ReferenceCaptureError(f"EEVEE {what} is not finite ({value})")
    return value


def eevee_rows(source_args: list[str], reference: ReferenceData, preset_label: str, out_dir: Path,
               image_dir: Path | None, settings: Sequence[str] = SETTINGS, *, frames: int = 1,
               progress: Progress | None = None, timeout_s: float | None = DEFAULT_TIMEOUT_S,
               image_stem: str | None = None) -> list[dict]:
    """Rows of the `eevee` method, one per setting, measured against `reference`.

    `source_args` names the scene for the child: `["--preset", NAME]` (the camera
    size is taken from the reference), `["--blend", FILE, "--light", NAME]` or
    `["--scene-spec", FILE]`. The child's files go to `out_dir/eevee/<preset_label>/`.
    With `image_dir`, a mismatch image `<preset>_eevee_<setting>_mismatch.png` is written
    (`<image_stem>_eevee_...` when given: a shot's job adds its frame, light and camera).
    """
    names = parse_settings(settings)
    if reference.emission not in TILEMAPS:
        raise InputError(f"the reference light is {reference.emission!r}; the eevee row needs a point, spot, sun "
                         "or area light")
    args = list(source_args)
    if "--preset" in args and "--size" not in args:
        args += ["--size", f"{reference.resolution[0]}x{reference.resolution[1]}"]
    args += ["--settings", ",".join(names), "--frames", str(int(frames))]
    shape = reference.light_shape()
    if not shape.sized and shape_from_dict(reference.meta.get("light_shape_file")).sized:
        args.append("--hard")  # the reference took the file's light size away: so does EEVEE
    child_dir = Path(out_dir) / "eevee" / (image_stem or preset_label)
    summary = run_child(args, child_dir, progress=progress, timeout_s=timeout_s)
    if summary.get("emission") != reference.emission:
        raise ReferenceCaptureError(f"EEVEE measured a {summary.get('emission')} light but the reference has "
                                    f"a {reference.emission} light; the scenes differ")

    light = reference.light_spec()
    ref_lit = metrics.reference_visibility(reference.shadowed, reference.unshadowed)
    evaluable = metrics.evaluable_mask(reference.position, reference.normal, reference.hit, reference.unshadowed, light)
    width, height = reference.resolution
    warmup_ms = _finite(summary["warmup_ms"], "warm-up time")
    rows = []
    for name in names:
        entry = summary["settings"][name]
        data = _load_setting(child_dir, entry, (height, width))
        hit_agreement = 100.0 * float(np.mean(data["hit"] == reference.hit))
        if hit_agreement < 99.0:
            log.warning("EEVEE and Cycles disagree on the hit mask at %.2f %% of pixels: other camera or scene?",
                        100.0 - hit_agreement)
        est_lit = data["visibility"].astype(bool)
        # A sized light's EEVEE shadows are soft: scored as fractions, like the reference.
        estimate = metrics.reference_ratio(data["shadowed"], data["unshadowed"]) if light.sized else est_lit
        judged = metrics.judge(estimate, reference.shadowed, reference.unshadowed, evaluable, sized=light.sized,
                               noise=reference.visibility_noise)
        cap = _finite(entry["shadow_maximum_resolution"], "shadow_maximum_resolution")
        # No map resolution, passes, texels or pipeline stages: EEVEE's virtual shadow maps
        # have none of them (rows.Row); the setting and its finest texel say what was run.
        row = make_row(
            preset_label, "eevee", reference.emission, judged.figure,
            {"total": _finite(entry["render_ms"], "render time"), "warmup": warmup_ms},
            str(summary["renderer"]), "eevee", int(summary["frames"]), (width, height),
            scene_triangles=int(len(reference.triangles)),
            eevee_setting=name,
            shadow_maximum_resolution=cap,
            unshadowed_ms=_finite(summary["unshadowed_ms"], "unshadowed render time"),
            hit_agreement_pct=hit_agreement,
            render_settings=summary["render_settings"],
            note=ROW_NOTE + (AREA_AS_SPOT_NOTE if summary["render_settings"].get("light.area_as_spot") else ""),
            light_shape=shape.describe() if shape.sized else None,
            **judged.columns(),
        )
        if image_dir is not None:
            row["mismatch_image"] = metrics.write_mismatch_image(
                image_dir, f"{image_stem or preset_label}_eevee_{name}", reference.shadowed, est_lit, ref_lit,
                evaluable)
        rows.append(row)
    return rows
