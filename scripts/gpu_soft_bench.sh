#!/usr/bin/env bash
# Soft shadows on a GPU machine (issue 27): scripts/gpu_bench.sh on the four soft presets
# against their sized Cycles references, and each method's cost against its hard version.
#
#   bash scripts/gpu_soft_bench.sh prepare   # here, with .venv and bpy: render the references
#   bash scripts/gpu_soft_bench.sh           # anywhere with numpy and moderngl: measure into $OUT
#
# `prepare` renders soft_room, soft_softbox, soft_spot and soft_sun (256 samples each) into
# .cache/softbench/ (about 15 MB). The measuring step writes, under OUT (default
# out/gpu_soft_bench): compare/ (every fitting method of dpsm+notw, cube+notw, sm, psm, exact
# at 1024, exact with its default 256 points), compare64/ (exact with 64 points), and
# cost.md (scripts/soft_cost.py on each reference: the filter's and exact's frames against
# the hard light's). OMNIWARP_PYTHON picks the interpreter, FRAMES (5) the timed frames,
# PRESETS (all four) the presets.
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO_ROOT"

export PRESETS="${PRESETS:-soft_room,soft_softbox,soft_spot,soft_sun}" RESOLUTIONS=1024
export FRAMES="${FRAMES:-5}" OMNIWARP_CACHE="${OMNIWARP_CACHE:-$REPO_ROOT/.cache/softbench}"
OUT="${OUT:-out/gpu_soft_bench}"

if [[ "${1:-run}" == "prepare" ]]; then
    exec bash scripts/gpu_bench.sh prepare
fi

METHODS=dpsm+notw,cube+notw,sm,psm,exact OUT="$OUT/compare" bash scripts/gpu_bench.sh
METHODS=exact OUT="$OUT/compare64" bash scripts/gpu_bench.sh --exact-samples 64
PY="${OMNIWARP_PYTHON:-$( [[ -x .venv/bin/python ]] && echo .venv/bin/python || command -v python3 )}"
: > "$OUT/cost.md"
for preset in ${PRESETS//,/ }; do
    ref="$(ls -t "$OMNIWARP_CACHE/${preset}"_640x480_*.npz | head -n 1)"  # the newest
    case "$preset" in
        soft_spot | soft_sun) methods=sm,psm,exact ;;
        *) methods=dpsm+notw,cube+notw,exact ;;
    esac
    printf '\n## %s\n\n' "$preset" >> "$OUT/cost.md"
    "$PY" scripts/soft_cost.py "$ref" --methods "$methods" --frames "$FRAMES" >> "$OUT/cost.md"
done
echo "gpu_soft_bench: tables in $OUT" >&2
