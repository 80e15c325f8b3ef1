#!/usr/bin/env bash
# The GPU benchmark tables: `omniwarp compare` on room_omni, courtyard and stress_million,
# at 1024 and 2048, for dpsm, cube, dpsm+notw, cube+notw and exact (report.md, with GPU
# ms from timer queries); then the floor benchmark (floor.md, scripts/floor_bench.py)
# and a steady frame's traffic (traffic.md, scripts/frame_traffic.py).
#
#   bash scripts/gpu_bench.sh prepare   # here, with .venv and bpy: render the Cycles references
#   bash scripts/gpu_bench.sh [ARGS]    # anywhere: measure, and write $OUT/report.md (ARGS go to
#                                       # `omniwarp compare`, e.g. --exact-samples 64)
#
# `prepare` renders the references into .cache/bench/ (about 21 MB). The measuring step
# needs only Python 3.11+ with numpy and moderngl (an EGL driver: Mesa llvmpipe here, the
# vendor's on a GPU machine); no bpy, matplotlib or package registry. It reads the
# references from .cache/bench/, so carry that folder to a bare machine along with the
# working tree. Where numpy or moderngl is missing and $OMNIWARP_WHEELS names a folder of
# wheels, they are installed from there into a temporary folder first.
#
# Environment: OUT (default out/gpu_bench), PRESETS, METHODS, RESOLUTIONS, FRAMES (5),
# SIZE (640x480), FLOOR_FRAMES (60, the floor benchmark's), OMNIWARP_PYTHON (the
# interpreter), OMNIWARP_WHEELS. The traffic table takes the presets, the methods and the
# first resolution.
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO_ROOT"

PRESETS="${PRESETS:-room_omni,courtyard,stress_million}"
METHODS="${METHODS:-dpsm,cube,dpsm+notw,cube+notw,exact}"
RESOLUTIONS="${RESOLUTIONS:-1024,2048}"
FRAMES="${FRAMES:-5}"
FLOOR_FRAMES="${FLOOR_FRAMES:-60}"
SIZE="${SIZE:-640x480}"
OUT="${OUT:-out/gpu_bench}"
export OMNIWARP_CACHE="${OMNIWARP_CACHE:-$REPO_ROOT/.cache/bench}"

if [[ "${1:-run}" == "prepare" ]]; then
    bash scripts/setup_env.sh >&2
    exec .venv/bin/python -m addon reference --preset "$PRESETS" --size "$SIZE" --samples 1
fi

pick_python() {
    if [[ -n "${OMNIWARP_PYTHON:-}" ]]; then echo "$OMNIWARP_PYTHON"
    elif [[ -x .venv/bin/python ]]; then echo .venv/bin/python
    else command -v python3
    fi
}
PY="$(pick_python)"
if ! "$PY" -c "import numpy, moderngl" 2>/dev/null; then
    if [[ -z "${OMNIWARP_WHEELS:-}" ]]; then
        echo "gpu_bench: $PY lacks numpy or moderngl; set OMNIWARP_WHEELS to a folder of wheels" >&2
        exit 2
    fi
    SITE="$(mktemp -d)"
    trap 'rm -rf "$SITE"' EXIT
    "$PY" -m pip install --quiet --no-index --find-links "$OMNIWARP_WHEELS" --target "$SITE" numpy moderngl >&2
    export PYTHONPATH="$SITE${PYTHONPATH:+:$PYTHONPATH}"
fi
echo "gpu_bench: $("$PY" --version) from $PY, references in $OMNIWARP_CACHE" >&2
"$PY" -m addon compare --preset "$PRESETS" --methods "$METHODS" --resolutions "$RESOLUTIONS" \
    --size "$SIZE" --repeats "$FRAMES" --no-images --out "$OUT" "$@"
"$PY" scripts/floor_bench.py --frames "$FLOOR_FRAMES" --out "$OUT/floor.md" >&2
"$PY" scripts/frame_traffic.py --presets "$PRESETS" --methods "$METHODS" --size "$SIZE" \
    --resolution "${RESOLUTIONS%%,*}" > "$OUT/traffic.md"
echo "gpu_bench: tables in $OUT/report.md, $OUT/floor.md and $OUT/traffic.md" >&2
