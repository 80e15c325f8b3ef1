#!/bin/sh
# Inside the real-Blender chroot: Blender's GUI on a fresh Xvfb screen, driven by a script
# (gui_preview.py unless GUI_SCRIPT names another of this folder; GUI_FLAGS are added to
# Blender's arguments; GUI_SCREEN the screen size, default 1600x1200). Usage: gui.sh BACKEND OUT_DIR [METHOD]. Blender's console goes to stdout.
set -u
backend="$1"; out="$2"; method="${3:-dpsm}"
script="${GUI_SCRIPT:-gui_preview.py}"
mkdir -p "$out"
display_file="$out/display"
: >"$display_file"
Xvfb -displayfd 3 -screen 0 "${GUI_SCREEN:-1600x1200}x24" -nolisten tcp 3>"$display_file" 2>/dev/null &
xvfb=$!
trap 'kill $xvfb 2>/dev/null' EXIT
for _ in $(seq 50); do [ -s "$display_file" ] && break; sleep 0.1; done
[ -s "$display_file" ] || { echo "gui.sh: Xvfb did not start"; exit 3; }
# shellcheck disable=SC2086 # GUI_FLAGS is a list of words
DISPLAY=":$(cat "$display_file")" timeout 900 blender --gpu-backend "$backend" ${GUI_FLAGS:-} /scratch/empty.blend \
    --python "/omniwarp/tests/real_blender/inside/$script" -- "$out" "$method" 2>&1
