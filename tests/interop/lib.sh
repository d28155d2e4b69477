# Sourced by the interop scripts (run.sh, setup.sh, workspace.sh, ros2cli.sh, cyclone.sh,
# sros2.sh, zenoh.sh, bond.sh, rosbag2.sh): what each of them does the same way.

# The clone's root; the cache of stock peers built from source, outside the clone
# (TRACER_CACHE, else ~/.cache/tracer_calib); how many jobs a build runs (ROS_SETUP_JOBS).
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
CACHE_TOP=${TRACER_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/tracer_calib}
JOBS=${ROS_SETUP_JOBS:-2}

# Milliseconds since the epoch; `took T0`: the time since T0 as "12.3s".
now_ms() { echo $(( $(date +%s%N) / 1000000 )); }
took() { local ms=$(( $(now_ms) - $1 )); printf '%d.%01ds' $(( ms / 1000 )) $(( (ms % 1000) / 100 )); }

# A clean environment for a build or an install, even when a target/ros/*/env.sh (and a
# cyclone_env.sh) is sourced in the calling shell.
clean_ros_env() {
    unset TRACER_ROS_ENV PYTHONPATH LD_LIBRARY_PATH LD_PRELOAD AMENT_PREFIX_PATH CMAKE_PREFIX_PATH \
        VIRTUAL_ENV PYTHONHOME _ROS_WHEELS_BOOTSTRAP_COMPLETE RMW_IMPLEMENTATION
}

# apt_install_missing WHO LOG PKG...: apt-get install those of the Debian packages PKG that
# are not installed (root only; else exit 1 saying what to install), apt's output to LOG.
# WHO names the calling script in its messages. Prints the time it took, if anything.
apt_install_missing() {
    local who=$1 log=$2 missing=() p t0
    shift 2
    for p in "$@"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
    done
    [ "${#missing[@]}" -gt 0 ] || return 0
    [ "$(id -u)" -eq 0 ] || { echo "$who: missing ${missing[*]} and not root: apt-get install -y ${missing[*]}" >&2; exit 1; }
    t0=$(now_ms)
    mkdir -p "$(dirname "$log")"
    if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"; } \
        >"$log" 2>&1; then
        tail -n 30 "$log" >&2
        echo "$who: apt-get install ${missing[*]} failed" >&2
        exit 1
    fi
    echo "$who: apt-get install ${missing[*]} $(took "$t0")"
}

# parse_peer_args HELP_END "$@": the arguments of a script that builds or installs a stock
# peer for distributions, `[--force] kilted|jazzy...`: sets FORCE (1 with --force, else 0)
# and the array DISTROS; --help prints the script's lines 2..HELP_END (its header); anything
# else, or no distribution, is a usage error (exit 2).
parse_peer_args() {
    local help_end=$1 a
    shift
    FORCE=0
    DISTROS=()
    for a in "$@"; do
        case "$a" in
            --force) FORCE=1 ;;
            kilted|jazzy) DISTROS+=("$a") ;;
            -h|--help) sed -n "2,${help_end}p" "$0"; exit 0 ;;
            *) echo "usage: $0 [--force] kilted|jazzy..." >&2; exit 2 ;;
        esac
    done
    [ "${#DISTROS[@]}" -gt 0 ] || { echo "usage: $0 [--force] kilted|jazzy..." >&2; exit 2; }
}

# prefix_env_lines VAR: the lines of an environment file that put the install prefix
# "$VAR/install" (VAR set earlier in the file) first on PYTHONPATH (its site-packages),
# LD_LIBRARY_PATH and AMENT_PREFIX_PATH, each once however often the file is sourced.
prefix_env_lines() {
    cat <<EOF
_p="\$$1/install"
case ":\${PYTHONPATH:-}:" in *":\$_p/lib/python3.11/site-packages:"*) ;;
    *) export PYTHONPATH="\$_p/lib/python3.11/site-packages\${PYTHONPATH:+:\$PYTHONPATH}" ;; esac
case ":\${LD_LIBRARY_PATH:-}:" in *":\$_p/lib:"*) ;;
    *) export LD_LIBRARY_PATH="\$_p/lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}" ;; esac
case ":\${AMENT_PREFIX_PATH:-}:" in *":\$_p:"*) ;;
    *) export AMENT_PREFIX_PATH="\$_p\${AMENT_PREFIX_PATH:+:\$AMENT_PREFIX_PATH}" ;; esac
unset _p
EOF
}

# write_if_changed FILE [CHANGED]: FILE's new text from stdin, written (through a temporary
# file beside it, renamed) only when it differs from what FILE holds, so that a rerun leaves
# it untouched; when it is written, the variable named CHANGED (if given) is set to 1.
write_if_changed() {
    local file=$1 tmp
    tmp=$(mktemp "$file.XXXXXX")
    cat >"$tmp"
    if [ -f "$file" ] && cmp -s "$tmp" "$file"; then
        rm -f "$tmp"
    else
        mv -f "$tmp" "$file"
        if [ -n "${2:-}" ]; then printf -v "$2" 1; fi
    fi
}

# cached_build WHO WHAT CACHE KEY LOG BUILD [ARTIFACT...]: a stock peer built once and kept
# in CACHE, a folder of the cache outside the clone. CACHE is locked while this runs
# (CACHE.lock: two runs never build it at once). It is used as it is when CACHE/key holds
# KEY, every ARTIFACT (a path below CACHE) is there and FORCE is not 1: BUILT=0. Otherwise
# the old build is removed and BUILD (a function) runs with WORK (CACHE.tmp, new and empty)
# as its argument, its output in LOG; BUILD leaves what it made in WORK and returns non-zero
# when a step fails (set -e does not apply inside it: each step says `|| return`). Then
# WORK's src/ and build/ are removed, KEY is written to WORK/key and WORK becomes CACHE:
# BUILT=1. A failed build says so with LOG's last lines, removes WORK and returns 1.
cached_build() {
    local who=$1 what=$2 cache=$3 key=$4 log=$5 build=$6 a ok
    shift 6
    BUILT=0
    mkdir -p "$(dirname "$cache")" "$(dirname "$log")"
    exec 8>"$cache.lock"
    flock 8
    if [ "${FORCE:-0}" != 1 ] && [ -f "$cache/key" ] && [ "$(cat "$cache/key")" = "$key" ]; then
        ok=1
        for a in "$@"; do [ -e "$cache/$a" ] || ok=0; done
        if [ "$ok" = 1 ]; then exec 8>&-; return 0; fi
    fi
    rm -rf "$cache" "$cache.tmp"
    mkdir -p "$cache.tmp"
    if ! "$build" "$cache.tmp" >"$log" 2>&1; then
        echo "$who: building $what failed; last lines of $log:" >&2
        tail -n 25 "$log" >&2
        rm -rf "$cache.tmp"
        exec 8>&-
        return 1
    fi
    rm -rf "$cache.tmp/src" "$cache.tmp/build"
    echo "$key" >"$cache.tmp/key"
    mv "$cache.tmp" "$cache"
    BUILT=1
    exec 8>&-
}

# venv_libdirs VENV: the venv's shared library folders, ':'-separated (VENV/lib and the
# wheels' vendored dependencies, site-packages/ros_*.libs), for LD_LIBRARY_PATH in a build.
venv_libdirs() {
    printf '%s' "$1/lib"
    (cd "$1/lib/python3.11/site-packages" && for x in ros_*.libs; do [ -d "$x" ] && printf ':%s' "$PWD/$x"; done; true)
}

# soname_shim WORK LIB: WORK/shim/librmw_fastrtps_cpp.so, a copy of WORK/install/lib/LIB (an
# RMW) given rmw_fastrtps_cpp's SONAME: the wheels' librcl*.so and rclpy link that library
# directly, so an LD_PRELOADed copy is how an rclpy process runs on another RMW.
soname_shim() {
    mkdir -p "$1/shim" \
        && cp "$1/install/lib/$2" "$1/shim/librmw_fastrtps_cpp.so" \
        && patchelf --set-soname librmw_fastrtps_cpp.so "$1/shim/librmw_fastrtps_cpp.so"
}
