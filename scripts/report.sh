#!/usr/bin/env bash
# Newcomer command #1: build .venv if needed, then run the comparison report.
#   bash scripts/report.sh                         # room_omni -> out/report/
#   PRESET=courtyard OUT=out/courtyard bash scripts/report.sh --methods dpsm,cube
# Extra arguments go to `omniwarp compare`. Relative paths are relative to the repo root.
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO_ROOT"
bash scripts/setup_env.sh
exec .venv/bin/omniwarp compare --preset "${PRESET:-room_omni}" --out "${OUT:-out/report}" "$@"
