"""The results row: one measured (scene, method, map resolution) of `compare`, the
sidebar panel and the EEVEE anchor; written as JSON (results.json) or CSV.

`Row` names the columns; `make_row` is the one place a row is built. Columns that do
not apply to a method are absent, never a placeholder: an EEVEE row has no map
`resolution`, `passes`, `texels` or pipeline stage times, and says which of its
settings it is (`eevee_setting`) and its finest shadow texel (`shadow_maximum_resolution`).
"""
from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any, TypedDict

from .errors import InputError


class Row(TypedDict, total=False):
    """A results row. Every row has the first group; the rest as the method has them."""

    # every row
    preset: str
    method: str
    emission: str
    error_pct: float
    false_shadow_pct: float
    false_lit_pct: float
    evaluated_pixels: int
    time_ms: dict[str, float]  # medians per stage; "total" always
    # GPU ms per stage from timer queries (medians; "total" their sum), where the backend
    # has them (moderngl): the work itself, without the host's waits and round trips
    gpu_ms: dict[str, float]
    renderer: str
    backend: str
    frames: int  # timed repeats (--repeats), not a shot's frames
    camera_size: list[int]
    # a .blend's job (shots.Job): the frame of its animation, its light and camera objects
    frame: int
    light: str
    camera: str
    # the shadow-map methods
    resolution: int  # side of each map, texels
    passes: int
    soft_error_pct: float
    # pixels Cycles lights fractionally (see-through surfaces, metrics.FRACTIONAL_BAND): left
    # out of error_pct, and their own soft error
    fractional_pixels: int
    fractional_soft_error_pct: float
    # a sized light (core/light_shape.py): its shape as the reference rendered it, and the
    # reference's own noise in soft_error_pct's unit (data.ReferenceData.visibility_noise);
    # its error_pct counts the penumbra's pixels too (metrics.judge)
    light_shape: str
    reference_noise_pct: float
    light_points: int  # the light's points a sample's shadow follows: the filter's taps or exact's
    triangles_drawn: int
    scene_triangles: int
    scene_pieces: int  # hair and points, as the pieces the maps draw (resident.set_pieces); absent: none
    texels: int
    max_count_before: float
    max_count_after: float
    texel_utilization: float
    tessellated_triangles: int
    skipped_triangles: int
    nonfinite_texels: int
    layers: list[str]
    warp: dict
    cull: bool
    # exact: the irregular z-buffer's lists (list lengths are the mapped count map) and the
    # triangle pass's work, from one untimed measurement frame
    list_longest: int
    list_mean: float  # over the texels holding a list
    list_fragments: int  # fragments of the triangle pass that walked a list
    list_entries: int  # list entries they walked: the pass's work
    list_cut: int  # walks that stopped at their round's bound and went on in the next round
    list_moved_entries: int  # entries the later rounds walked (work moved, none dropped)
    list_rounds: int  # rounds after the first (0: every list fit the first bound)
    # EEVEE
    eevee_setting: str
    shadow_maximum_resolution: float
    unshadowed_ms: float
    hit_agreement_pct: float
    render_settings: dict
    note: str
    # images and scene notes, when written
    mismatch_image: str
    map_images: list[str]
    scene_notes: list[str]


def make_row(preset: str, method: str, emission: str | None, figure: Any, time_ms: dict[str, float],
             renderer: str | None, backend: str | None, frames: int | None,
             camera_size: tuple[int, int] | list[int] | None, **columns: Any) -> Row:
    """A row from its common columns, the error figure (metrics.error_figure) and the
    method's own `columns`. A column given as None is left out: only a row rebuilt from a
    stored copy (the panel's, after reopening a file) lacks common ones."""
    row: dict[str, Any] = {
        "preset": preset, "method": method, "emission": emission,
        "error_pct": figure.error_pct, "false_shadow_pct": figure.false_shadow_pct,
        "false_lit_pct": figure.false_lit_pct, "evaluated_pixels": figure.evaluated_pixels,
        "time_ms": dict(time_ms), "renderer": renderer, "backend": backend,
        "frames": None if frames is None else int(frames),
        "camera_size": None if camera_size is None else [int(v) for v in camera_size],
    }
    unknown = set(columns) - set(Row.__annotations__)
    if unknown:
        raise KeyError(f"not a results column: {', '.join(sorted(unknown))}")
    row.update(columns)
    return {key: value for key, value in row.items() if value is not None}  # type: ignore[return-value]


def row_label(row: Row) -> str:
    """The row's method as tables show it: EEVEE's setting, or the method and ' (no cull)'."""
    if "eevee_setting" in row:
        return f"{row['method']} ({row['eevee_setting']})"
    return row["method"] + ("" if row.get("cull", True) else " (no cull)")


SHOT_FIELDS = ("frame", "light", "camera")


def row_key(row: Row) -> tuple:
    """What tells two rows of one run apart: scene, method as labelled, map resolution, and
    a sweep's frame, light and camera where the row has them (a preset's key stays short)."""
    return (row["preset"], row_label(row), row.get("resolution"),
            *((key, row[key]) for key in SHOT_FIELDS if key in row))


def with_shot(row: Row, **shot: Any) -> Row:
    """The row with a job's `frame`, `light` and `camera` (those given and not None)."""
    unknown = set(shot) - set(SHOT_FIELDS)
    if unknown:
        raise KeyError(f"not a shot column: {', '.join(sorted(unknown))}")
    row.update({key: value for key, value in shot.items() if value is not None})  # type: ignore[typeddict-item]
    return row


def flatten_row(row: dict) -> dict:
    """One CSV line: time_ms.* and gpu_ms.* as their own columns, other lists and dicts as JSON text."""
    flat: dict[str, Any] = {}
    for key, value in row.items():
        if key in ("time_ms", "gpu_ms"):
            flat.update({f"{key}.{k}": v for k, v in value.items()})
        elif isinstance(value, (dict, list, tuple)):
            flat[key] = json.dumps(value, sort_keys=True)
        else:
            flat[key] = value
    return flat


def write_rows(rows: list[dict], path: Path) -> None:
    """JSON (the command line's results.json format) or CSV, by the file's suffix."""
    suffix = path.suffix.lower()
    if suffix == ".json":
        path.write_text(json.dumps(rows, indent=1), encoding="utf-8")
    elif suffix == ".csv":
        flat = [flatten_row(row) for row in rows]
        columns: list[str] = []
        for line in flat:
            columns += [key for key in line if key not in columns]
        with path.open("w", newline="", encoding="utf-8") as stream:
            writer = csv.DictWriter(stream, fieldnames=columns)
            writer.writeheader()
            writer.writerows(flat)
    else:
        raise InputError(f"export file {path.name!r} must end with .json or .csv")
