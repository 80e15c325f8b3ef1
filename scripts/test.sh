#!/usr/bin/env bash
# Newcomer command #2: build each tested line's environment if needed, then run the tests.
#
# The whole suite runs on Blender 5.2 (bpy 5.2.3, Python 3.13); the tests that touch bpy
# (marker `blender`) run again on each LTS line (bpy 4.5.15 and 4.2.23, Python 3.11).
# Extra arguments go to pytest on every line, e.g. `bash scripts/test.sh -q -x`; a `-m`
# among them replaces the LTS lines' `-m blender`.
#   OMNIWARP_LINES="5.2"   test only these lines (default: "5.2 4.5 4.2")
# CI runs `bash .ci/run`, which is `bash scripts/test.sh -q`.
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO_ROOT"

LINES="${OMNIWARP_LINES:-5.2 4.5 4.2}"
failed=()
for line in $LINES; do
    bash scripts/setup_env.sh "$line"
    if [[ "$line" == "5.2" ]]; then
        venv=.venv
        select=()
    else
        venv=".venv-bpy$line"
        select=(-m blender)
    fi
    printf 'test: Blender %s (%s)\n' "$line" "$("$venv/bin/python" -c 'import bpy; print("bpy", bpy.app.version_string)')" >&2
    "$venv/bin/python" -m pytest tests "${select[@]}" "$@" || failed+=("$line")
done
if ((${#failed[@]})); then
    printf 'test: failed on Blender %s\n' "${failed[*]}" >&2
    exit 1
fi
printf 'test: passed on Blender %s\n' "$LINES" >&2
