#!/bin/sh
# Inside the real-Blender chroot: Blender's GUI on a fresh Xvfb screen, driven by
# gui_preview.py. Usage: gui.sh BACKEND OUT_DIR [METHOD]. Blender's console goes to stdout.
set -u
backend="$1"; out="$2"; method="${3:-dpsm}"
mkdir -p "$out"
display_file="$out/display"
: >"$display_file"
Xvfb -displayfd 3 -screen 0 1600x1200x24 -nolisten tcp 3>"$display_file" 2>/dev/null &
xvfb=$!
trap 'kill $xvfb 2>/dev/null' EXIT
for _ in $(seq 50); do [ -s "$display_file" ] && break; sleep 0.1; done
[ -s "$display_file" ] || { echo "gui.sh: Xvfb did not start"; exit 3; }
DISPLAY=":$(cat "$display_file")" timeout 300 blender --gpu-backend "$backend" /scratch/empty.blend \
    --python /omniwarp/tests/real_blender/inside/gui_preview.py -- "$out" "$method" 2>&1
