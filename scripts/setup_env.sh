#!/usr/bin/env bash
# Build (or check) the environment of one tested Blender line. Idempotent.
#
#   bash scripts/setup_env.sh [LINE]      LINE: 5.2 (default), 4.5 or 4.2
#
#   line  venv            Python  packages
#   5.2   .venv           3.13    -e .[blender,dask,dev] (bpy 5.2.3, Dask for the cluster tests)
#   4.5   .venv-bpy4.5    3.11    -e .[blender45,dev]    (bpy 4.5.15)
#   4.2   .venv-bpy4.2    3.11    -e .[blender42,dev]    (bpy 4.2.23)
#
# The bpy pins live in pyproject.toml's optional dependencies. Steps:
#  1. Mesa EGL system libraries (libegl1 libegl-mesa0 libgl1-mesa-dri):
#     installed with apt-get only when dpkg says they are missing.
#  2. The line's Python (PyPI publishes each bpy for one CPython minor only),
#     found on PATH, in pyenv, or in the usual prefixes.
#  3. The venv, created when missing (or when it is broken / the wrong Python).
#  4. `pip install -e .[EXTRA,dev]`, skipped while <venv>/.omniwarp-stamp still
#     matches (sha256 of pyproject.toml + the repo path + the line, since an
#     editable install points at this checkout).
#
# Environment overrides:
#   OMNIWARP_PYTHON=/path/to/python3.13     interpreter for the 5.2 line (no search)
#   OMNIWARP_PYTHON311=/path/to/python3.11  interpreter for the 4.x lines (no search)
#   OMNIWARP_PYTHON_PREFIXES="/a /b"        folders searched after pyenv (default: /usr/local/bin /usr/bin)
#   OMNIWARP_SKIP_APT=1                     do not check/install the apt packages
#   OMNIWARP_FORCE_INSTALL=1                reinstall even if the stamp matches
#
# Everything this script says goes to stderr; it exits non-zero on failure.
set -euo pipefail

REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO_ROOT"

LINE="${1:-5.2}"
APT_PACKAGES=(libegl1 libegl-mesa0 libgl1-mesa-dri)

say() { printf 'setup_env: %s\n' "$*" >&2; }
die() { printf 'setup_env: error: %s\n' "$*" >&2; exit 1; }

case "$LINE" in
    5.2) VENV="$REPO_ROOT/.venv";         PY_WANT="3.13"; EXTRA="blender,dask"; PY_OVERRIDE="${OMNIWARP_PYTHON:-}" ;;
    4.5) VENV="$REPO_ROOT/.venv-bpy4.5";  PY_WANT="3.11"; EXTRA="blender45"; PY_OVERRIDE="${OMNIWARP_PYTHON311:-}" ;;
    4.2) VENV="$REPO_ROOT/.venv-bpy4.2";  PY_WANT="3.11"; EXTRA="blender42"; PY_OVERRIDE="${OMNIWARP_PYTHON311:-}" ;;
    *) die "unknown Blender line '$LINE'; tested lines: 5.2 4.5 4.2" ;;
esac
STAMP="$VENV/.omniwarp-stamp"
PY_PREFIXES="${OMNIWARP_PYTHON_PREFIXES:-/usr/local/bin /usr/bin}"

# --- 1. Mesa EGL ------------------------------------------------------------
ensure_apt_packages() {
    if [[ "${OMNIWARP_SKIP_APT:-0}" == "1" ]]; then
        say "OMNIWARP_SKIP_APT=1: not checking ${APT_PACKAGES[*]}"
        return 0
    fi
    if ! command -v dpkg-query >/dev/null 2>&1; then
        say "warning: dpkg-query not found (not a Debian/Ubuntu system?); cannot check" \
            "for Mesa EGL (${APT_PACKAGES[*]}). Install Mesa's EGL + DRI drivers yourself" \
            "if the moderngl tests fail to create an EGL context."
        return 0
    fi
    local missing=() pkg status
    for pkg in "${APT_PACKAGES[@]}"; do
        status="$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null || true)"
        [[ "$status" == "install ok installed" ]] || missing+=("$pkg")
    done
    if ((${#missing[@]} == 0)); then
        say "Mesa EGL packages present (${APT_PACKAGES[*]})"
        return 0
    fi
    say "installing missing apt packages: ${missing[*]}"
    if ! command -v apt-get >/dev/null 2>&1; then
        die "packages ${missing[*]} are missing and apt-get is not available." \
            "Install Mesa EGL (libEGL + Mesa DRI drivers) by other means, then re-run" \
            "(or set OMNIWARP_SKIP_APT=1 to skip this check)."
    fi
    local sudo=()
    if [[ "$(id -u)" != "0" ]]; then
        command -v sudo >/dev/null 2>&1 || die "packages ${missing[*]} are missing; not root and" \
            "sudo is not available. Run as root: apt-get install -y ${missing[*]}"
        if [[ -t 0 ]]; then sudo=(sudo); else sudo=(sudo -n); fi
    fi
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq >&2 \
        || die "'apt-get update' failed; install ${missing[*]} manually and re-run."
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
        --no-install-recommends "${missing[@]}" >&2 \
        || die "'apt-get install ${missing[*]}' failed; install them manually and re-run."
}

# --- 2. the line's Python -----------------------------------------------------
# True when "$1" runs, is CPython $PY_WANT and can create a venv with pip.
is_good_python() {
    "$1" -c "import sys, venv, ensurepip; sys.exit(0 if sys.version_info[:2] == (${PY_WANT/./, }) else 1)" \
        >/dev/null 2>&1
}

find_python() {
    local c tried=()
    if [[ -n "$PY_OVERRIDE" ]]; then
        if is_good_python "$PY_OVERRIDE"; then
            printf '%s\n' "$PY_OVERRIDE"
            return 0
        fi
        die "$PY_OVERRIDE (from the environment) is not a working Python $PY_WANT with venv and ensurepip"
    fi

    local candidates=()
    command -v "python$PY_WANT" >/dev/null 2>&1 && candidates+=("$(command -v "python$PY_WANT")")
    if command -v pyenv >/dev/null 2>&1; then
        local v
        while IFS= read -r v; do
            [[ "$v" == "$PY_WANT"* ]] || continue
            c="$(PYENV_VERSION="$v" pyenv which "python$PY_WANT" 2>/dev/null || true)"
            [[ -n "$c" ]] && candidates+=("$c")
        done < <(pyenv versions --bare 2>/dev/null || true)
    fi
    local prefix
    for prefix in "${PYENV_ROOT:-${HOME:-/root}/.pyenv}"/versions/"$PY_WANT"*/bin $PY_PREFIXES; do
        c="$prefix/python$PY_WANT"
        [[ -x "$c" ]] && candidates+=("$c")
    done
    command -v python3 >/dev/null 2>&1 && candidates+=("$(command -v python3)")

    for c in "${candidates[@]}"; do
        if is_good_python "$c"; then
            printf '%s\n' "$c"
            return 0
        fi
        tried+=("$c")
    done
    python_missing "no usable Python $PY_WANT found (tried: ${tried[*]:-nothing on PATH or in pyenv})"
}

python_missing() {
    local var=OMNIWARP_PYTHON
    [[ "$PY_WANT" == "3.13" ]] || var=OMNIWARP_PYTHON311
    die "$* -- Blender $LINE's bpy needs Python $PY_WANT: run 'pyenv install $PY_WANT' (or 'uv python install $PY_WANT' and set $var=\$(uv python find $PY_WANT)), then re-run."
}

# --- 3. the virtual environment ---------------------------------------------
ensure_venv() {
    if [[ -e "$VENV" ]]; then
        if is_good_python "$VENV/bin/python"; then
            say "using existing $VENV ($("$VENV/bin/python" -V 2>&1))"
            return 0
        fi
        say "$VENV exists but its python is broken or not $PY_WANT: recreating it"
        rm -rf -- "$VENV"
    fi
    local py
    py="$(find_python)"
    say "creating $VENV with $py ($("$py" -V 2>&1))"
    "$py" -m venv "$VENV" || die "'$py -m venv $VENV' failed"
}

# --- 4. the packages --------------------------------------------------------
stamp_value() {
    { sha256sum pyproject.toml; printf '%s\n' "$REPO_ROOT" "$LINE"; } | sha256sum | cut -d' ' -f1
}

ensure_install() {
    local want
    want="$(stamp_value)"
    if [[ "${OMNIWARP_FORCE_INSTALL:-0}" != "1" && -f "$STAMP" \
          && "$(cat "$STAMP")" == "$want" && -x "$VENV/bin/omniwarp" ]]; then
        say "packages up to date (stamp matches pyproject.toml); skipping pip install"
        return 0
    fi
    say "installing -e .[$EXTRA,dev] into $VENV (the first install downloads bpy, ~1-2 min)"
    rm -f -- "$STAMP"
    "$VENV/bin/python" -m pip install --disable-pip-version-check -q -e ".[$EXTRA,dev]" >&2 \
        || die "pip install -e .[$EXTRA,dev] failed (see the pip output above)"
    local got
    got="$("$VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("bpy"))' 2>/dev/null || true)"
    [[ "$got" == "$LINE".* ]] || die "after the install $VENV has bpy '${got:-none}', not Blender $LINE's"
    printf '%s\n' "$want" >"$STAMP"
    say "environment ready: $VENV (Blender $LINE)"
}

ensure_apt_packages
ensure_venv
ensure_install
