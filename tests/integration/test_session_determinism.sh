#!/usr/bin/env bash
# The same scenario + seed gives the same report.json in-process (virtual
# clock) and over UDP (microdrive-sim and microdrive-fw as processes): the
# session's outcome cannot depend on the bus or on scheduling. Run inside
# scripts/netns-run.sh.
#   test_session_determinism.sh BIN_DIR SCENARIO OUT_DIR CYCLES [SEED]
# Exit 77 (skipped) while the controller completes no cycle at all.
set -uo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=${1:?usage: test_session_determinism.sh BIN_DIR SCENARIO OUT_DIR CYCLES [SEED]}
scenario=${2:?} out=${3:?} cycles=${4:?} seed=${5:-3}
rm -rf "$out" && mkdir -p "$out"
status=0
for bus in inproc udp; do
    "$bin/microdrive-session" --scenario "$scenario" --seed "$seed" --bus "$bus" --cycles "$cycles" \
        --idle-s 60 --out "$out/$bus" >"$out/$bus.txt" 2>&1
    rc=$?
    echo "session on $bus: exit $rc ($(tail -n 1 "$out/$bus.txt"))"
    if [ "$rc" -ne 0 ] && [ "$rc" -ne 4 ]; then
        cat "$out/$bus.txt"
        status=1
    fi
done
[ "$status" -eq 0 ] || exit 1
python3 "$root/tools/session/compare_reports.py" "$out/inproc/report.json" "$out/udp/report.json"
