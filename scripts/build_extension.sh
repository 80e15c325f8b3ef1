#!/usr/bin/env bash
# Build the installable Blender extension zip into dist/ (no Blender install needed).
#
#   bash scripts/build_extension.sh          # prints e.g. /repo/dist/omniwarp_shadows-0.1.0.zip
#
# Steps:
#  1. scripts/setup_env.sh (idempotent) so .venv has bpy==5.2.3.
#  2. Blender's own extension tool, `blender_ext.py`, which the PyPI bpy package
#     ships under bpy/<version>/scripts/addons_core/bl_pkg/cli/. It is the code
#     behind `blender --command extension validate|build`; like Blender, it is
#     given Blender's tag list (_bpy_internal/extensions/tags.py).
#  3. `validate` the source tree, `build` the zip, then `validate` the zip.
#
# Only the zip's absolute path goes to stdout (so `ZIP=$(bash scripts/build_extension.sh)`
# works); the tool's chatter and this script's messages go to stderr.
#
# Environment overrides:
#   OMNIWARP_DIST_DIR=/path     write the zip there instead of <repo>/dist
#   OMNIWARP_SKIP_SETUP=1       do not run scripts/setup_env.sh (the tests use this)
#   OMNIWARP_EXT_PYTHON=/path   interpreter that has bpy (default: <repo>/.venv/bin/python)
set -euo pipefail

REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO_ROOT"

say() { printf 'build_extension: %s\n' "$*" >&2; }
die() { printf 'build_extension: error: %s\n' "$*" >&2; exit 1; }

if [[ "${OMNIWARP_SKIP_SETUP:-0}" == "1" ]]; then
    say "OMNIWARP_SKIP_SETUP=1: not running scripts/setup_env.sh"
else
    bash "$REPO_ROOT/scripts/setup_env.sh" || die "scripts/setup_env.sh failed (see above)"
fi

PYTHON="${OMNIWARP_EXT_PYTHON:-$REPO_ROOT/.venv/bin/python}"
[[ -x "$PYTHON" ]] || die "no Python at $PYTHON; run scripts/setup_env.sh (or set OMNIWARP_EXT_PYTHON)"

DIST="${OMNIWARP_DIST_DIR:-$REPO_ROOT/dist}"
mkdir -p -- "$DIST" || die "cannot create the output folder $DIST"
DIST="$(cd "$DIST" && pwd)"

# Locate the tool and the tag list without importing bpy (find_spec only reads
# the package's location), and read id/version from the manifest so the zip's
# name is known up front. Prints four lines: tool, tags, id, version.
# Exit code 3: no tool in this bpy.
LOCATE_RC=0
INFO="$("$PYTHON" - "$REPO_ROOT/blender_manifest.toml" <<'PY'
import importlib.util
import sys
import tomllib
from pathlib import Path

spec = importlib.util.find_spec("bpy")
if spec is None or not spec.submodule_search_locations:
    print("the bpy package is not installed in " + sys.executable, file=sys.stderr)
    sys.exit(3)
for location in spec.submodule_search_locations:
    for tool in sorted(Path(location).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py")):
        tags = tool.parents[3] / "modules" / "_bpy_internal" / "extensions" / "tags.py"
        if tags.is_file():
            break
    else:
        continue
    break
else:
    print("bpy in " + ", ".join(spec.submodule_search_locations) + " has no "
          "<version>/scripts/addons_core/bl_pkg/cli/blender_ext.py (with "
          "modules/_bpy_internal/extensions/tags.py)", file=sys.stderr)
    sys.exit(3)
with open(sys.argv[1], "rb") as fh:
    manifest = tomllib.load(fh)
print(tool, tags, manifest["id"], manifest["version"], sep="\n")
PY
)" || LOCATE_RC=$?
if ((LOCATE_RC == 3)); then
    die "Blender's extension tool (blender_ext.py) was not found with $PYTHON.
  It comes with bpy==5.2.3 from PyPI: run scripts/setup_env.sh (or point
  OMNIWARP_EXT_PYTHON at a Python 3.13 that has bpy). With a full Blender install
  you can instead run: blender --command extension build --output-dir dist/"
elif ((LOCATE_RC != 0)); then
    die "could not locate the tool or read blender_manifest.toml with $PYTHON (exit $LOCATE_RC, see above)"
fi
{ read -r TOOL; read -r TAGS; read -r EXT_ID; read -r EXT_VERSION; } <<<"$INFO"
[[ -f "$TOOL" && -f "$TAGS" && -n "$EXT_ID" && -n "$EXT_VERSION" ]] \
    || die "could not read the tool path or the manifest's id/version (got: $INFO)"

ZIP="$DIST/$EXT_ID-$EXT_VERSION.zip"
ext() { "$PYTHON" "$TOOL" "$@" >&2; }

say "tool: $TOOL"
say "validating $REPO_ROOT/blender_manifest.toml"
ext validate "$REPO_ROOT" --valid-tags "$TAGS" || die "the manifest does not validate (see above)"

# Remove an older zip first: the tool would overwrite it, but a failed build must
# not leave a stale zip that looks like this build's.
rm -f -- "$ZIP"
say "building $ZIP"
ext build --source-dir "$REPO_ROOT" --output-filepath "$ZIP" --valid-tags "$TAGS" \
    || die "the extension build failed (see above)"
[[ -f "$ZIP" ]] || die "the tool reported success but $ZIP does not exist"
ext validate "$ZIP" --valid-tags "$TAGS" || die "the built zip does not validate (see above)"

printf '%s\n' "$ZIP"
