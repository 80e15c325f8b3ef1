#!/usr/bin/env bash
# Newcomer command #1: build .venv if needed, then run the comparison report.
#   bash scripts/report.sh                         # room_omni -> out/report/
#   PRESET=courtyard OUT=out/courtyard bash scripts/report.sh --methods dpsm,cube
# By default it measures EEVEE (Blender's own shadows, the anchor row), the plain and
# warped maps side by side, and `exact` (the irregular z-buffer, the project's headline:
# 0.000 % against Cycles); METHODS changes the list. Extra arguments go to
# `omniwarp compare`; a --methods among them wins. Relative paths are relative to the repo root.
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO_ROOT"
bash scripts/setup_env.sh
exec .venv/bin/omniwarp compare --preset "${PRESET:-room_omni}" --out "${OUT:-out/report}" \
    --methods "${METHODS:-eevee,dpsm,cube,dpsm+notw,cube+notw,exact}" "$@"
