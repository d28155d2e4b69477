# Sourced by the interop scripts (run.sh, setup.sh, workspace.sh, ros2cli.sh, cyclone.sh,
# sros2.sh, zenoh.sh, bond.sh, rosbag2.sh): what each of them does the same way.

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
