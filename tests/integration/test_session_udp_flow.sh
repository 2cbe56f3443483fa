#!/usr/bin/env bash
# A UDP session loses no frame with the stock socket buffers. Run through
# `scripts/netns-run.sh --unprivileged` (a user namespace: no CAP_NET_ADMIN in
# the initial namespace, so no SO_RCVBUFFORCE, as for any ordinary user).
# The same scenario + seed over UDP and in-process: the UDP session must end
# with status 0, every endpoint (recorder, microdrive-sim, microdrive-fw) must
# report flow control on, a receive buffer of at most 2 x 212992 bytes (the
# stock net.core.rmem_max, doubled by the kernel) and 0 frames lost, and
# report.json must equal the in-process one. The controller's heartbeat
# timeout is 10 s in both runs: on a loaded machine a process starved for
# more than the default 500 ms makes the controller count a node lost and
# change its decisions whatever the bus (the unchanged bus as root did too);
# that is not what this test is about. In-process nothing is ever lost, so
# the parameter changes nothing there.
#   test_session_udp_flow.sh BIN_DIR SCENARIO OUT_DIR CYCLES [SEED]
set -uo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=${1:?usage: test_session_udp_flow.sh BIN_DIR SCENARIO OUT_DIR CYCLES [SEED]}
scenario=${2:?} out=${3:?} cycles=${4:?} seed=${5:-1}
stock_max=$((2 * 212992))
rm -rf "$out" && mkdir -p "$out"
fail() { echo "FAIL: $*"; exit 1; }
for bus in inproc udp; do
    "$bin/microdrive-session" --scenario "$scenario" --seed "$seed" --bus "$bus" --cycles "$cycles" \
        --param heartbeat_timeout_ms=10000 --no-lcm --no-plots --quiet --out "$out/$bus" >"$out/$bus.txt" 2>&1
    rc=$?
    echo "session on $bus: exit $rc ($(tail -n 1 "$out/$bus.txt"))"
    [ "$rc" -eq 0 ] || { cat "$out/$bus.txt"; fail "session on $bus exited $rc"; }
done
# Each endpoint says at open which buffer it got and whether flow control is on.
for log in "$out/udp.txt" "$out/udp/sim.log" "$out/udp/fw.log"; do
    line=$(grep -m1 -o 'UDP multicast[^)]*), [^)]*rcvbuf [0-9]* B' "$log") || fail "no bus line in $log"
    echo "$(basename "$log"): $line"
    case "$line" in *"NO flow control"*) fail "no flow control in $log" ;; esac
    buf=$(echo "$line" | sed -n 's/.*rcvbuf \([0-9]*\) B.*/\1/p')
    [ -n "$buf" ] && [ "$buf" -le "$stock_max" ] || fail "$log: receive buffer '$buf' above $stock_max bytes"
done
# 0 lost by the recorder and by both processes (their bus counters at exit).
losses=$(grep -m1 'frames lost:' "$out/udp.txt") || fail "no loss report"
echo "$losses"
echo "$losses" | grep -Eq 'recorder 0 \(malformed 0\), microdrive-sim 0 \(malformed 0; flow waits [0-9]+, timeouts 0\), microdrive-fw 0 \(malformed 0; flow waits [0-9]+, timeouts 0\)$' \
    || fail "frames lost or not reported"
python3 "$root/tools/session/compare_reports.py" "$out/inproc/report.json" "$out/udp/report.json" \
    || fail "report.json over UDP differs from the in-process one"
echo "PASS"
