# The Debian/Ubuntu packages the project needs, in one place, and the step that
# installs the missing ones. Sourced by scripts/run-session.sh and
# scripts/test.sh (and through test.sh by .ci/run):
#
#   . scripts/deps.sh
#   md_deps_install WHO build host-tests ...   # groups below; exits 1 when it cannot
#   md_venv_ready WHO                          # the project venv: made or refreshed when stale
#
# Packages are installed as root, or through sudo, after saying which and why;
# where neither works (or the system is not Debian/Ubuntu) it prints the
# command to run and stops.

# group -> packages, and what the group is for (said before installing)
MD_DEPS_build=(cmake ninja-build gcc make pkg-config python3-venv libyaml-dev libcjson-dev
               liblcm-dev liblcm-bin libglib2.0-dev)
MD_DEPS_WHY_build="build the firmware, the simulator and the host tools (CMake, Ninja, gcc, libyaml, cJSON, LCM) and make the Python venv"
MD_DEPS_host_tests=(cppcheck clang-tidy clang-format iproute2)
MD_DEPS_WHY_host_tests="run the static-analysis and layout tests (cppcheck, clang-tidy, clang-format) and the socket tests in a private network namespace (iproute2)"
MD_DEPS_fuzz=(clang libclang-rt-14-dev)
MD_DEPS_WHY_fuzz="build the libFuzzer targets (clang)"
MD_DEPS_target=(gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm)
MD_DEPS_WHY_target="cross-build for the Cortex-M7 and run its tests under QEMU"
MD_DEPS_vcan=(qemu-system-x86 linux-image-amd64 busybox-static can-utils cpio kmod xz-utils)
MD_DEPS_WHY_vcan="run the SocketCAN tests in a throwaway VM with a vcan0 (QEMU, a Debian kernel, busybox, can-utils)"

md_deps_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

# md_deps_missing GROUP...: the packages of the groups that are not installed
md_deps_missing() {
    local g p list
    for g in "$@"; do
        list="MD_DEPS_${g//-/_}[@]"
        for p in "${!list}"; do
            dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || echo "$p"
        done
    done
}

# md_deps_install WHO GROUP...: installs what the groups miss; returns 1 (with
# the command to run) when it cannot.
md_deps_install() {
    local who=$1 g all list
    shift
    all=()
    for g in "$@"; do
        list="MD_DEPS_${g//-/_}[@]"
        all+=("${!list}")
    done
    if ! command -v dpkg-query >/dev/null 2>&1 || ! command -v apt-get >/dev/null 2>&1; then
        echo "$who: not a Debian/Ubuntu system (no dpkg-query/apt-get): install the equivalents of these" \
             "Debian packages yourself, then run this again: ${all[*]}" >&2
        return 1
    fi
    # (no process substitution: the vcan VM that runs run-session.sh has no /dev/fd)
    local missing
    read -r -a missing <<<"$(md_deps_missing "$@" | tr '\n' ' ')"
    [ "${#missing[@]}" -eq 0 ] && return 0
    echo "$who: installing the missing Debian packages ${missing[*]}" >&2
    for g in "$@"; do
        local why="MD_DEPS_WHY_${g//-/_}" need
        need=$(md_deps_missing "$g" | tr '\n' ' ')
        [ -n "$need" ] && echo "$who:   ${need% }: to ${!why}" >&2
    done
    local sudo=()
    if [ "$(id -u)" -ne 0 ]; then
        if command -v sudo >/dev/null 2>&1; then
            echo "$who: not root: using sudo (it may ask for your password)" >&2
            sudo=(sudo)
        else
            echo "$who: cannot install: not root and no sudo. As root, run:" >&2
            echo "    apt-get update && apt-get install -y --no-install-recommends ${missing[*]}" >&2
            return 1
        fi
    fi
    if ! "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq ||
       ! "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
            "${missing[@]}" >/dev/null; then
        echo "$who: installing failed (see above). As root, run:" >&2
        echo "    apt-get update && apt-get install -y --no-install-recommends ${missing[*]}" >&2
        return 1
    fi
    echo "$who: installed ${missing[*]}" >&2
}

# md_venv_ready WHO: the project venv (.venv, or $MD_VENV) exists and matches
# requirements.txt and the python/ package; made or refreshed otherwise.
md_venv_ready() {
    local who=$1
    if "$md_deps_root/scripts/setup-venv.sh" --check >/dev/null 2>&1; then
        return 0
    fi
    echo "$who: the project venv ${MD_VENV:-$md_deps_root/.venv} is missing or stale: making it" \
         "(scripts/setup-venv.sh: requirements.txt and python/ from PyPI, a few minutes the first time)" >&2
    "$md_deps_root/scripts/setup-venv.sh" || {
        echo "$who: making the venv failed (see above); fix and run scripts/setup-venv.sh" >&2
        return 1
    }
}
