#!/usr/bin/env bash
# Benchmarks of one electrode cycle, host and Cortex-M7, and the static
# memory, worst-case stack and simulator speed; writes docs/benchmarks.md.
#
#   scripts/bench.sh [--runs N] [--out FILE]
#
# Steps (raw outputs in build/bench-out/):
#   1. host Release build (build/bench-rel): md-bench, median wall time per
#      stage over N runs, and the measured interval's features;
#   2. scikit-learn GaussianMixture G = 1..4 + BIC on those features (venv
#      build/bench-venv from tools/bench/requirements.txt), right after 1;
#   3. valgrind callgrind: instructions per stage (md-bench --callgrind);
#   4. cortex-m7 build (build/bench-m7): md-bench-m7 under QEMU -icount
#      shift=0, instructions per stage; size report and stack budget of
#      microdrive-fw-m7;
#   5. sim-bench --minutes 100 (Release): simulator speed-up over real time;
#   6. tools/bench/profile_mhtc.sh HEAD: the MHTC step split per model class
#      (of the committed tree: run on a clean checkout).
# Needs: cmake, ninja, gcc, gcc-arm-none-eabi, qemu-system-arm, valgrind,
# python3-venv (and PyPI for scikit-learn). Times are reported, never judged;
# the script fails only if a tool fails. ~5-10 min on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=11
out_md=docs/benchmarks.md
while [ $# -gt 0 ]; do
    case "$1" in
        --runs) runs="$2"; shift 2 ;;
        --out) out_md="$2"; shift 2 ;;
        *) echo "usage: $0 [--runs N] [--out FILE]" >&2; exit 2 ;;
    esac
done
raw=build/bench-out
mkdir -p "$raw"
rm -f "$raw"/cg.out.*
log() { echo "bench: $*" >&2; }

log "host Release build"
cmake -S . -B build/bench-rel -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_C_FLAGS_RELEASE="-O2 -DNDEBUG" >/dev/null
cmake --build build/bench-rel --target md-bench sim-bench >/dev/null
log "cortex-m7 build"
cmake --no-warn-unused-cli -S . -B build/bench-m7 -G Ninja -DCMAKE_TOOLCHAIN_FILE=cmake/arm-none-eabi.cmake \
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_C_FLAGS_RELEASE="-O2 -DNDEBUG" >/dev/null
cmake --build build/bench-m7 --target md-bench-m7 microdrive-fw-m7 >/dev/null

if [ ! -x build/bench-venv/bin/python ]; then
    log "venv build/bench-venv"
    python3 -m venv build/bench-venv
fi
build/bench-venv/bin/pip install -q -r tools/bench/requirements.txt

# The MHTC step is single-threaded: give scikit-learn one thread as well, so
# the two are compared core for core on a shared 2-core machine.
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
if [ -n "${OPENBLAS_CORETYPE:-}" ]; then
    log "OPENBLAS_CORETYPE=$OPENBLAS_CORETYPE is set (see .library/env): unset for the sklearn timing only"
fi
log "host stages, $runs runs; then sklearn on the same features"
build/bench-rel/bin/md-bench --runs "$runs" --features "$raw/features.txt" >"$raw/host.txt"
env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE \
    build/bench-venv/bin/python tools/bench/sklearn_gmm.py "$raw/features.txt" --runs "$runs" >"$raw/sklearn.txt"

log "callgrind (one run per stage)"
valgrind --tool=callgrind --collect-atstart=no --callgrind-out-file="$raw/cg.out" \
    build/bench-rel/bin/md-bench --callgrind >"$raw/callgrind-stdout.txt" 2>"$raw/callgrind-stderr.txt"
: >"$raw/callgrind.txt"
for f in "$raw"/cg.out.*; do
    name=$(sed -n 's/^desc: Trigger: Client Request: stage://p' "$f")
    ir=$(sed -n 's/^summary: *\([0-9]*\).*/\1/p' "$f")
    [ -n "$ir" ] || ir=$(sed -n 's/^totals: *\([0-9]*\).*/\1/p' "$f")
    [ -n "$name" ] && echo "stage $name ir $ir" >>"$raw/callgrind.txt"
done

log "cortex-m7 stages under QEMU -icount shift=0"
timeout 900 qemu-system-arm -M mps2-an500 -nographic -monitor none -serial null -icount shift=0 \
    -semihosting-config enable=on,target=native -kernel build/bench-m7/bin/md-bench-m7.elf </dev/null >"$raw/m7.txt" 2>&1
scripts/size-report.sh build/bench-m7/bin/microdrive-fw-m7.elf >"$raw/size.txt"
scripts/stack-budget.py build/bench-m7/bin/microdrive-fw-m7.elf >"$raw/stack.txt" 2>&1 || true

log "simulator speed (sim-bench --minutes 100)"
build/bench-rel/bin/sim-bench --minutes 100 >"$raw/sim.txt"

log "MHTC step per model class (tools/bench/profile_mhtc.sh HEAD)"
tools/bench/profile_mhtc.sh HEAD "$raw/profile-mhtc" >"$raw/profile.txt"

python3 tools/bench/report.py "$raw" "$out_md" "$runs"
log "wrote $out_md"
