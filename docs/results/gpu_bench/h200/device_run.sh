#!/usr/bin/env bash
# One device call: the GPU benchmark (scripts/gpu_bench.sh) and the soft presets' compare,
# run from .cache/src (a `git archive` of the commit in .cache/src/COMMIT), with the Cycles
# references in .cache/bench. Writes at most 8 files under $OUT.
#
# The copy that ran for docs/results/gpu_bench/h200 and h200_soft (as .cache/device_run.sh, with
# .cache, .whl and .gl carried; see docs/results/gpu_bench/README.md). LOCAL_TEST=1 skips the .deb
# and wheel installs and the NVIDIA check, for a dry run on llvmpipe.
set -uo pipefail
R="$(pwd)"
: "${OUT:?}"
BENCH_T="${BENCH_T:-300}"
SOFT_T="${SOFT_T:-150}"
echo "device_run: start $(date -u '+%F %T UTC'), commit $(cat .cache/src/COMMIT)"
if [[ "${LOCAL_TEST:-0}" != 1 ]]; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 3
fi
python3 --version
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
nvidia-smi -L
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem --format=csv

try_ctx() {
    python3 - > "$OUT/renderer.txt" 2>&1 <<'EOF'
import moderngl, numpy, os, subprocess
ctx = moderngl.create_standalone_context(backend="egl")
for k in ("GL_VENDOR", "GL_RENDERER", "GL_VERSION"):
    print(k, ctx.info[k])
print("numpy", numpy.__version__, "moderngl", moderngl.__version__)
for k in ("__EGL_VENDOR_LIBRARY_FILENAMES", "GLCONTEXT_LINUX_LIBGL"):
    print(k, os.environ.get(k, "(unset)"))
for cmd in (["nvidia-smi", "-L"], ["nvidia-smi", "--query-gpu=name,driver_version", "--format=csv,noheader"]):
    try:
        print(subprocess.run(cmd, capture_output=True, text=True).stdout.strip())
    except OSError as exc:
        print(cmd[0], exc)
EOF
    local rc=$?
    cat "$OUT/renderer.txt"
    [[ "${LOCAL_TEST:-0}" == 1 ]] && return $rc
    [[ $rc -eq 0 ]] && grep -qi nvidia "$OUT/renderer.txt" && ! grep -qi llvmpipe "$OUT/renderer.txt"
}
NV=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
if ! try_ctx; then
    echo "device_run: retrying with __EGL_VENDOR_LIBRARY_FILENAMES=$NV"
    export __EGL_VENDOR_LIBRARY_FILENAMES=$NV
    if ! try_ctx; then
        echo "device_run: retrying with GLCONTEXT_LINUX_LIBGL=libOpenGL.so.0"
        export GLCONTEXT_LINUX_LIBGL=libOpenGL.so.0
        try_ctx || { echo "device_run: no NVIDIA EGL context"; exit 4; }
    fi
fi

export OMNIWARP_CACHE="$R/.cache/bench"
cd "$R/.cache/src"
mkdir -p "$OUT/bench" "$OUT/soft"
t0=$(date +%s)
OMNIWARP_PYTHON=python3 OUT=/tmp/ow_bench timeout "$BENCH_T" bash scripts/gpu_bench.sh
echo "device_run: bench rc=$? in $(( $(date +%s) - t0 )) s"
for f in report.md results.json error_vs_time.png; do cp /tmp/ow_bench/$f "$OUT/bench/" 2>/dev/null; done
t0=$(date +%s)
timeout "$SOFT_T" python3 -m addon compare --preset "${SOFT_PRESETS:-soft_room,soft_softbox}" \
    --methods "${SOFT_METHODS:-dpsm+notw,cube+notw,exact}" --resolutions "${SOFT_RES:-1024}" \
    --size 640x480 --repeats "${SOFT_REPEATS:-3}" \
    --no-images --out /tmp/ow_soft
echo "device_run: soft rc=$? in $(( $(date +%s) - t0 )) s"
for f in report.md results.json error_vs_time.png; do cp /tmp/ow_soft/$f "$OUT/soft/" 2>/dev/null; done
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem --format=csv
echo "device_run: end $(date -u '+%F %T UTC')"
