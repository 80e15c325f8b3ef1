#!/usr/bin/env bash
# A real Blender binary for the tests: Debian unstable's `blender` package in a chroot.
#
#   bash scripts/real_blender.sh setup            # build it (idempotent, cached), print its root
#   bash scripts/real_blender.sh run ARGS...      # run `blender ARGS...` inside it
#   bash scripts/real_blender.sh exec CMD ARGS... # run any command inside it
#   bash scripts/real_blender.sh root             # print its root if it is built (status 3 if not)
#
# Why a chroot: the machines here reach Debian's package registry but not blender.org, and
# Debian's unstable suite packages Blender 5.2 (on the system's Python 3.14, with numpy but
# no OpenEXR, OpenImageIO or matplotlib module), the binary artists install from their
# distribution. The chroot also brings
# Xvfb for the GUI, Mesa's llvmpipe (OpenGL) and lavapipe (Vulkan), and ImageMagick for
# screenshots.
#
# Inside, the repository is bound read-only at /omniwarp, and /scratch is <root>/scratch (or
# OMNIWARP_REAL_BLENDER_SCRATCH). Every call runs in a mount namespace of its own (`unshare
# --mount`): /proc, /dev, /sys and those binds exist for that call only, so nothing stays
# mounted on the host and removing the chroot's folder can never reach the host's /dev.
#
# Needs root (debootstrap, mount and chroot). Without root it says so in one line and exits 3;
# the tests then skip with that line as their reason.
#
# Environment:
#   OMNIWARP_REAL_BLENDER_ROOT=/path   where the chroot lives (default ~/.cache/omniwarp/real-blender,
#                                      outside the repository: tools that walk the repository
#                                      never see it)
#   OMNIWARP_REAL_BLENDER_SCRATCH=/dir a host folder to see as /scratch inside
#   OMNIWARP_REAL_BLENDER_USER=/path   Blender's user folder inside (BLENDER_USER_RESOURCES: its
#                                      config and installed extensions), e.g. /scratch/user
#   OMNIWARP_DEBIAN_MIRROR=URL         Debian mirror (default http://deb.debian.org/debian)
set -euo pipefail

REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
ROOT="${OMNIWARP_REAL_BLENDER_ROOT:-${XDG_CACHE_HOME:-$HOME/.cache}/omniwarp/real-blender}"
MIRROR="${OMNIWARP_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
STAMP="$ROOT/.omniwarp-ready"
# The packages, one list: bump STAMP_KEY when it changes so an older chroot is completed.
PACKAGES=(blender xvfb xauth mesa-vulkan-drivers libgl1-mesa-dri libegl1 libegl-mesa0 libglx-mesa0
          python3-numpy python3-attr python3-typing-extensions python3-requests x11-apps imagemagick)
# Blender's extension system (bl_pkg) imports cattrs and requests at registration; Debian has no
# cattrs, so without it every start prints a traceback. Pure Python, from PyPI.
PYPI_PACKAGES=(cattrs==26.2.1)
STAMP_KEY="4 ${PACKAGES[*]} ${PYPI_PACKAGES[*]}"
APT_OPTS=(-o Acquire::Check-Valid-Until=false -o APT::Install-Recommends=false -o Dpkg::Use-Pty=0 -q -y)

say() { printf 'real_blender: %s\n' "$*" >&2; }
die() { printf 'real_blender: error: %s\n' "$1" >&2; exit "${2:-1}"; }  # MESSAGE [STATUS]

need_root() {
    if [[ "$(id -u)" != 0 ]]; then
        printf 'real_blender: needs root (debootstrap, mount and chroot); run it as root, as CI does\n' >&2
        exit 3
    fi
}

is_ready() { [[ -f "$STAMP" && "$(cat "$STAMP")" == "$STAMP_KEY" ]]; }

# The namespace's mounts, as one shell snippet run by `unshare --mount` before the command.
MOUNTS='set -e
mount --make-rprivate /
for d in proc sys dev; do mount --rbind "/$d" "$ROOT/$d"; done
mkdir -p "$ROOT/omniwarp" "$ROOT/scratch"
mount --bind "$REPO_ROOT" "$ROOT/omniwarp"
mount -o remount,bind,ro "$ROOT/omniwarp"
if [ -n "$SCRATCH" ]; then mount --bind "$SCRATCH" "$ROOT/scratch"; fi
exec "$@"'

in_namespace() {  # CMD ARGS...: run CMD (a host path) with the chroot's mounts in a private namespace
    [[ -z "${OMNIWARP_REAL_BLENDER_SCRATCH:-}" ]] || mkdir -p -- "$OMNIWARP_REAL_BLENDER_SCRATCH"
    ROOT="$ROOT" REPO_ROOT="$REPO_ROOT" SCRATCH="${OMNIWARP_REAL_BLENDER_SCRATCH:-}" \
        unshare --mount --propagation private -- /bin/sh -c "$MOUNTS" sh "$@"
}

setup() {
    need_root
    if is_ready; then
        printf '%s\n' "$ROOT"
        return 0
    fi
    if [[ ! -x "$ROOT/usr/bin/apt-get" ]]; then
        if ! command -v debootstrap >/dev/null 2>&1; then
            say "installing debootstrap on the host"
            DEBIAN_FRONTEND=noninteractive apt-get "${APT_OPTS[@]}" install debootstrap >&2 \
                || die "could not install debootstrap with apt-get"
        fi
        say "debootstrap --variant=minbase sid into $ROOT (a few minutes)"
        case "$(realpath -m -- "$ROOT")" in
            / | /root | /home | "$HOME" | "$REPO_ROOT" | "$REPO_ROOT"/*)
                die "OMNIWARP_REAL_BLENDER_ROOT=$ROOT is not a folder this script may build into (and remove)" 2 ;;
        esac
        rm -rf -- "$ROOT"
        mkdir -p -- "$(dirname "$ROOT")"
        debootstrap --variant=minbase sid "$ROOT" "$MIRROR" >&2 \
            || die "debootstrap of Debian sid from $MIRROR failed (see above)"
    fi
    say "installing ${PACKAGES[*]} in the chroot"
    # The suite's Release file can be past its Valid-Until date on the mirrors here.
    in_namespace chroot "$ROOT" env DEBIAN_FRONTEND=noninteractive apt-get "${APT_OPTS[@]}" update >&2 \
        || die "apt-get update in the chroot failed (see above)"
    in_namespace chroot "$ROOT" env DEBIAN_FRONTEND=noninteractive apt-get "${APT_OPTS[@]}" install "${PACKAGES[@]}" >&2 \
        || die "apt-get install in the chroot failed (see above)"
    chroot "$ROOT" apt-get clean >&2 || true
    local site
    site="$(chroot "$ROOT" python3 -c 'import sys; print(f"/usr/local/lib/python3.{sys.version_info[1]}/dist-packages")')"
    say "installing ${PYPI_PACKAGES[*]} into the chroot's $site"
    local pip=(python3 -m pip)
    python3 -m pip --version >/dev/null 2>&1 || pip=("$REPO_ROOT/.venv/bin/python" -m pip)
    "${pip[@]}" install -q --disable-pip-version-check --no-deps --no-compile --upgrade \
        --target "$ROOT$site" "${PYPI_PACKAGES[@]}" >&2 \
        || die "pip could not install ${PYPI_PACKAGES[*]} into the chroot"
    in_namespace chroot "$ROOT" blender --version >&2 || die "blender does not start in the chroot"
    printf '%s\n' "$STAMP_KEY" >"$STAMP"
    printf '%s\n' "$ROOT"
}

in_chroot() {  # CMD ARGS...: run inside, with the binds in place and a clean environment
    need_root
    is_ready || die "the chroot at $ROOT is not built; run: bash scripts/real_blender.sh setup" 3
    in_namespace chroot "$ROOT" /usr/bin/env -i HOME=/root PATH=/usr/sbin:/usr/bin:/sbin:/bin \
        LANG=C.UTF-8 TERM=dumb ${DISPLAY:+DISPLAY=$DISPLAY} \
        ${OMNIWARP_REAL_BLENDER_USER:+BLENDER_USER_RESOURCES=$OMNIWARP_REAL_BLENDER_USER} "$@"
}

case "${1:-}" in
    setup) setup ;;
    root) need_root; is_ready || die "the chroot at $ROOT is not built; run: bash scripts/real_blender.sh setup" 3; printf '%s\n' "$ROOT" ;;
    run) shift; in_chroot /usr/bin/blender "$@" ;;
    exec) shift; in_chroot "$@" ;;
    *) die "usage: $0 setup | root | run BLENDER_ARGS... | exec CMD..." 2 ;;
esac
