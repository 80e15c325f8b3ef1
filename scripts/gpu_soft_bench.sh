#!/usr/bin/env bash
# Soft shadows on a GPU machine (issue 27): the four soft presets against their sized Cycles
# references, and each method's cost against its hard version.
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

PRESETS="${PRESETS:-soft_room,soft_softbox,soft_spot,soft_sun}"
OUT="${OUT:-out/gpu_soft_bench}"
FRAMES="${FRAMES:-5}"
export OMNIWARP_CACHE="${OMNIWARP_CACHE:-$REPO_ROOT/.cache/softbench}"

if [[ "${1:-run}" == "prepare" ]]; then
    bash scripts/setup_env.sh >&2
    exec .venv/bin/python -m addon reference --preset "$PRESETS" --size 640x480
fi

PY="${OMNIWARP_PYTHON:-$( [[ -x .venv/bin/python ]] && echo .venv/bin/python || command -v python3 )}"
echo "gpu_soft_bench: $("$PY" --version) from $PY, references in $OMNIWARP_CACHE" >&2
mkdir -p "$OUT"
"$PY" -m addon compare --preset "$PRESETS" --methods dpsm+notw,cube+notw,sm,psm,exact --resolutions 1024 \
    --size 640x480 --repeats "$FRAMES" --no-images --out "$OUT/compare"
"$PY" -m addon compare --preset "$PRESETS" --methods exact --exact-samples 64 --resolutions 1024 \
    --size 640x480 --repeats "$FRAMES" --no-images --out "$OUT/compare64"
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
