#!/usr/bin/env bash
# Every shipped scenario runs end to end against the controller firmware on one
# bus: the simulator's three plant nodes and microdrive-fw exchange heartbeats
# and plant frames for a few seconds, and the controller reports no lost node
# and no rejected frame (scripts/run-session.sh decides, per scenario).
#   test_scenarios_session.sh BUILD_DIR BUS OUT_DIR [SECONDS]
# Run it inside scripts/netns-run.sh (udp) or scripts/with-vcan.sh (vcan0).
# --no-lcm: the LCM log and plots have their own tests (test_lcm_*); inside
# the ~20x slower VM, matplotlib alone took minutes per session.
set -uo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$1 bus=$2 out=$3 seconds=${4:-2}
passed=0 failed=0
for scenario in "$root"/scenarios/*.yaml; do
    name=$(basename "$scenario" .yaml)
    if "$root/scripts/run-session.sh" --scenario "$scenario" --bus "$bus" --seconds "$seconds" \
        --build-dir "$build" --out "$out/$name" --no-lcm >"$out.$name.txt" 2>&1; then
        passed=$((passed + 1))
        echo "PASS $name"
    else
        failed=$((failed + 1))
        echo "FAIL $name (output below; logs in $out/$name)"
        cat "$out.$name.txt"
    fi
done
echo "scenario sessions on $bus: $passed passed, $failed failed"
[ "$failed" -eq 0 ] && [ "$passed" -gt 0 ]
