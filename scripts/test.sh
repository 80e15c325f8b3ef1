#!/usr/bin/env bash
# Newcomer command #2: build each tested line's environment if needed, then run the tests.
#
# The whole suite runs on Blender 5.2 (bpy 5.2.3, Python 3.13); the tests that touch bpy
# (marker `blender`) run again on each LTS line (bpy 4.5.15 and 4.2.23, Python 3.11).
# Extra arguments go to pytest on every line, e.g. `bash scripts/test.sh -q -x`; a `-m`
# among them replaces the LTS lines' `-m blender`.
#   OMNIWARP_LINES="5.2"    test only these lines (default: "5.2 4.5 4.2")
#   OMNIWARP_SERIAL=1       run the LTS lines one after the other
# The LTS lines' environments are built while 5.2 tests, and the LTS lines then test side by
# side, each into a log printed whole when it ends (each waits on Cycles renders and child
# processes much of the time, so on 2 cores the pair takes about 60 % of one after the other).
# CI runs `bash .ci/run`, which is `bash scripts/test.sh -q`.
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO_ROOT"

LINES="${OMNIWARP_LINES:-5.2 4.5 4.2}"
LTS=()
for line in $LINES; do [[ "$line" == "5.2" ]] || LTS+=("$line"); done
WORK="$(mktemp -d "${TMPDIR:-/tmp}/omniwarp_test.XXXXXX")"
trap 'jobs -p | xargs -r kill 2>/dev/null || true; rm -rf "$WORK"' EXIT
failed=()

banner() {  # LINE VENV
    printf 'test: Blender %s (%s)\n' "$1" "$("$2/bin/python" -c 'import bpy; print("bpy", bpy.app.version_string)')" >&2
}

setup_lts() {
    for line in "${LTS[@]}"; do bash scripts/setup_env.sh "$line"; done
}
setup_pid=""
if [[ " $LINES " == *" 5.2 "* ]]; then
    bash scripts/setup_env.sh 5.2
    # The LTS environments are pip work only now (5.2's setup installed any system package).
    if ((${#LTS[@]})); then
        setup_lts >"$WORK/setup.log" 2>&1 &
        setup_pid=$!
    fi
elif ((${#LTS[@]})); then
    setup_lts  # in the foreground: it may ask for sudo
fi

if [[ " $LINES " == *" 5.2 "* ]]; then
    banner 5.2 .venv
    .venv/bin/python -m pytest tests "$@" || failed+=("5.2")
fi

if ((${#LTS[@]})); then
    if [[ -n "$setup_pid" ]]; then
        if ! wait "$setup_pid"; then
            cat "$WORK/setup.log" >&2
            printf 'test: could not build the environments of Blender %s\n' "${LTS[*]}" >&2
            exit 1
        fi
        cat "$WORK/setup.log" >&2
    fi
    run_lts() {  # LINE PYTEST_ARGS...: its selection, its own pytest temp folder, no shared pytest cache
        local line="$1"
        shift
        banner "$line" ".venv-bpy$line"
        ".venv-bpy$line/bin/python" -m pytest tests -m blender -p no:cacheprovider --basetemp "$WORK/tmp-$line" "$@"
    }
    if [[ -n "${OMNIWARP_SERIAL:-}" || ${#LTS[@]} -eq 1 ]]; then
        for line in "${LTS[@]}"; do
            run_lts "$line" "$@" || failed+=("$line")
        done
    else
        pids=()
        for line in "${LTS[@]}"; do
            # Timing checks read this: the two lines share the 2 cores.
            OMNIWARP_SIDE_BY_SIDE=1 run_lts "$line" "$@" >"$WORK/$line.log" 2>&1 &
            pids+=($!)
        done
        for i in "${!LTS[@]}"; do
            status=0
            wait "${pids[$i]}" || status=$?
            cat "$WORK/${LTS[$i]}.log"
            ((status == 0)) || failed+=("${LTS[$i]}")
        done
    fi
fi

if ((${#failed[@]})); then
    printf 'test: failed on Blender %s\n' "${failed[*]}" >&2
    exit 1
fi
printf 'test: passed on Blender %s\n' "$LINES" >&2
