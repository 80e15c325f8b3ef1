"""Results rows outside Blender: written as JSON (the command line's results.json) or CSV."""
from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from .core.errors import InputError


def flatten_row(row: dict) -> dict:
    """One CSV line: time_ms.* as their own columns, other lists and dicts as JSON text."""
    flat: dict[str, Any] = {}
    for key, value in row.items():
        if key == "time_ms":
            flat.update({f"time_ms.{k}": v for k, v in value.items()})
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
