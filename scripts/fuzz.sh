#!/usr/bin/env bash
# Builds the libFuzzer configuration (clang, ASan + UBSan) and runs fuzz targets.
# docs/fuzzing.md describes the targets, their invariants and the figures.
#
#   scripts/fuzz.sh [options] [TARGET...]        (default: every target)
#     --seconds N      fuzz each target for N seconds (default 30)
#     --runs N         fuzz each target for N executions instead (e.g. 10000000)
#     --max-seconds S  with --runs: stop a target after S seconds all the same
#                      (a shared machine may not reach N in the time there is)
#     --timeout S      an execution longer than S seconds is a hang (default 10; a
#                      loaded shared machine can stall a process that long)
#     --jobs N         parallel libFuzzer workers per target (-fork=N; default 1)
#     --build-dir DIR  fuzz build directory (default build/fuzz)
#     --no-build       use the binaries already in DIR
#     --replay-only    only re-run the committed corpus and crash reproducers
#     --merge          afterwards, merge new coverage into tests/fuzz/corpus/<target>
#     --list           print the target names and exit
#
# Prints one summary line per target (executions, wall time, cov, ft, result)
# and appends it to DIR/fuzz-summary.txt. Exit status non-zero if any target
# crashed, hung, leaked or reported a sanitizer error; the reproducer is in
# DIR/fuzz-artifacts/<target>/ (run the binary on it to see the report).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
TARGETS_ALL=(fuzz_node fuzz_node_stream fuzz_protocol fuzz_bus_wire fuzz_bus_text fuzz_cluster fuzz_pca fuzz_murty
    fuzz_recording fuzz_scenario fuzz_truth fuzz_cli fuzz_ground_truth_csv)

seconds=30
runs=""
max_seconds=""
timeout=10
jobs=1
build_dir="$ROOT/build/fuzz"
do_build=1
replay_only=0
merge=0
targets=()

while [[ $# -gt 0 ]]; do
    case "$1" in
        --seconds) seconds="$2"; shift 2 ;;
        --runs) runs="$2"; shift 2 ;;
        --max-seconds) max_seconds="$2"; shift 2 ;;
        --timeout) timeout="$2"; shift 2 ;;
        --jobs) jobs="$2"; shift 2 ;;
        --build-dir) build_dir="$2"; shift 2 ;;
        --no-build) do_build=0; shift ;;
        --replay-only) replay_only=1; do_build=0; shift ;;
        --merge) merge=1; shift ;;
        --list) printf '%s\n' "${TARGETS_ALL[@]}"; exit 0 ;;
        -h|--help) sed -n '2,22p' "$0"; exit 0 ;;
        fuzz_*) targets+=("$1"); shift ;;
        *) echo "fuzz.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done
[[ ${#targets[@]} -eq 0 ]] && targets=("${TARGETS_ALL[@]}")

# Longest input worth trying per target: enough for the largest structure the
# harness decodes, short enough to keep executions fast.
max_len_of() {
    case "$1" in
        fuzz_protocol) echo 72 ;;
        fuzz_bus_wire) echo 180 ;;
        fuzz_bus_text) echo 300 ;;
        fuzz_murty) echo 160 ;;
        fuzz_node|fuzz_node_stream) echo 2048 ;;
        fuzz_cluster) echo 600 ;;
        fuzz_pca) echo 2048 ;;
        fuzz_recording|fuzz_scenario) echo 2048 ;;  # the shipped seeds are below 1.5 kB
        fuzz_truth) echo 1200 ;;                     # four or five truth lines
        fuzz_cli) echo 512 ;;
        fuzz_ground_truth_csv) echo 1024 ;;
        *) echo 1024 ;;
    esac
}

if [[ $do_build -eq 1 ]]; then
    command -v clang >/dev/null || { echo "fuzz.sh: clang not found (apt-get install clang libclang-rt-14-dev)" >&2; exit 2; }
    CC=clang cmake -S "$ROOT" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
        -DMD_FUZZ=ON -DMD_SANITIZE=ON >/dev/null
    cmake --build "$build_dir" --target fuzz_all
fi

export ASAN_OPTIONS="${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:strict_string_checks=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"

status=0
for t in "${targets[@]}"; do
    bin="$build_dir/bin/$t"
    [[ -x "$bin" ]] || { echo "fuzz.sh: $bin not built" >&2; exit 2; }
    seeds="$ROOT/tests/fuzz/corpus/$t"
    crashes="$ROOT/tests/fuzz/crashes/$t"
    max_len="$(max_len_of "$t")"

    # Regression: every committed input must run clean.
    shopt -s nullglob
    replay=("$seeds"/* "$crashes"/*)
    shopt -u nullglob
    if [[ ${#replay[@]} -gt 0 ]]; then
        if ! "$bin" -runs=0 "${replay[@]}" >"$build_dir/$t.replay.log" 2>&1; then
            echo "$t: REPLAY FAILED (see $build_dir/$t.replay.log)"; status=1; continue
        fi
    fi
    if [[ $replay_only -eq 1 ]]; then
        echo "$t: replay ok (${#replay[@]} inputs)"; continue
    fi

    work="$build_dir/fuzz-corpus/$t"
    artifacts="$build_dir/fuzz-artifacts/$t"
    mkdir -p "$work" "$artifacts"
    limit=(-max_total_time="$seconds")
    [[ -n "$runs" ]] && limit=(-runs="$runs")
    [[ -n "$runs" && -n "$max_seconds" ]] && limit+=(-max_total_time="$max_seconds")
    par=()
    [[ "$jobs" -gt 1 ]] && par=(-fork="$jobs" -ignore_crashes=0)
    # Text formats get a dictionary of their keys and keywords (tests/fuzz/dict/).
    [[ -f "$ROOT/tests/fuzz/dict/$t.dict" ]] && par+=(-dict="$ROOT/tests/fuzz/dict/$t.dict")
    log="$build_dir/$t.fuzz.log"
    start=$(date +%s)
    rc=0
    dirs=("$work")
    [[ -d "$seeds" ]] && dirs+=("$seeds")  # new inputs go to the first directory only
    "$bin" "${limit[@]}" "${par[@]}" -max_len="$max_len" -timeout="$timeout" -rss_limit_mb=2048 \
        -print_final_stats=1 -artifact_prefix="$artifacts/" "${dirs[@]}" >"$log" 2>&1 || rc=$?
    wall=$(( $(date +%s) - start ))
    execs=$( (grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" || true) | awk '{s+=$2} END {print s+0}')
    if [[ "$execs" -eq 0 ]]; then  # fork mode prints no final stats: take the last progress line
        execs=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#' || true)
    fi
    cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -1 | awk '{print $2}' || true)
    ft=$(grep -oE 'ft: [0-9]+' "$log" | tail -1 | awk '{print $2}' || true)
    result="ok"
    if [[ $rc -eq 72 ]]; then
        result="interrupted (SIGINT; figures up to that point)"  # libFuzzer's interrupt exit code
    elif [[ $rc -ne 0 ]]; then
        result="FAILED rc=$rc (log $log, reproducer in $artifacts/)"; status=1
    fi
    line="$(date -u +%FT%TZ) $t execs=${execs:-0} wall_s=$wall cov=${cov:-?} ft=${ft:-?} corpus=$(ls "$work" | wc -l) $result"
    echo "$line"
    echo "$line" >>"$build_dir/fuzz-summary.txt"
    if [[ $merge -eq 1 && $rc -eq 0 ]]; then
        mkdir -p "$seeds"
        "$bin" -merge=1 -max_len="$max_len" "$seeds" "$work" >"$build_dir/$t.merge.log" 2>&1
    fi
done
exit $status
