#!/usr/bin/env bash
# The project's whole test suite, as the README and CI run it:
#   0. the Debian packages the chosen stages need, installed when missing as
#      root or through sudo (scripts/deps.sh)
#   1. Python venv (requirements.txt, the python/ package), made when missing or stale
#   2. host build (preset dev): unit, integration (private netns) and vcan (VM) tests
#   3. sanitizers (preset dev-asan: ASan + UBSan): the unit tests again
#   4. fuzzing (clang libFuzzer, ASan + UBSan): a short run of every target
#   5. Cortex-M7 build (preset cortex-m7): the unit tests again, under QEMU,
#      and processor in the loop: the image under QEMU against the simulator
#      (label pil of the dev build)
# Options: --skip-target --skip-vcan --skip-asan --skip-fuzz (quick local runs;
# CI runs everything). MD_FUZZ_SECONDS sets the fuzz time per target (20).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

skip_target=0
skip_vcan=0
skip_asan=0
skip_fuzz=0
for arg in "$@"; do
    case "$arg" in
        --skip-target) skip_target=1 ;;
        --skip-vcan) skip_vcan=1 ;;
        --skip-asan) skip_asan=1 ;;
        --skip-fuzz) skip_fuzz=1 ;;
        *) echo "test.sh: unknown option $arg" >&2; exit 2 ;;
    esac
done

step() { printf '\n==== %s ====\n' "$*"; }
jobs=$(nproc)

step "dependencies (Debian packages: scripts/deps.sh)"
. scripts/deps.sh
groups=(build host-tests)
[ "$skip_fuzz" -eq 0 ] && groups+=(fuzz)
[ "$skip_target" -eq 0 ] && groups+=(target)
[ "$skip_vcan" -eq 0 ] && groups+=(vcan)
md_deps_install test.sh "${groups[@]}"
echo "all Debian packages of ${groups[*]} present"

step "python venv"
md_venv_ready test.sh
echo "venv ${MD_VENV:-$root/.venv} ready"

step "host build (preset dev)"
cmake --preset dev
cmake --build --preset dev -j "$jobs"

step "host tests: unit + integration"
exclude="vcan|pil"   # pil needs the cortex-m7 image: stage 5
ctest --preset dev -j "$jobs" -LE "$exclude"

if [ "$skip_vcan" -eq 0 ]; then
    step "vcan tests (real SocketCAN: host vcan0 or a QEMU VM)"
    ctest --preset dev -L vcan
fi

if [ "$skip_asan" -eq 0 ]; then
    step "sanitizer build (preset dev-asan: ASan + UBSan) and unit tests"
    cmake --preset dev-asan
    cmake --build --preset dev-asan -j "$jobs"
    ctest --preset dev-asan -j "$jobs" -L unit
fi

if [ "$skip_fuzz" -eq 0 ]; then
    step "short fuzz run of every target (docs/fuzzing.md has the long runs)"
    scripts/fuzz.sh --seconds "${MD_FUZZ_SECONDS:-20}"
fi

if [ "$skip_target" -eq 0 ]; then
    step "Cortex-M7 build (preset cortex-m7) and target tests under QEMU"
    cmake --preset cortex-m7
    cmake --build --preset cortex-m7 -j "$jobs"
    ctest --preset cortex-m7 -j "$jobs"
    step "processor in the loop: the Cortex-M7 image under QEMU against the simulator (label pil)"
    ctest --preset dev -L pil
fi

step "all test stages passed"
