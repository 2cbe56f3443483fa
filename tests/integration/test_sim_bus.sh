#!/bin/sh
# Integration test of microdrive-sim on the UDP bus (run it inside a private
# network namespace: scripts/netns-run.sh tests/integration/test_sim_bus.sh
# SIM MDCAN SCENARIO). Checks, with `mdcan dump` as the observer and
# `mdcan send` as the controller:
#  1. heartbeats of nodes 2, 3, 4 (operational, protocol version, lockstep flag)
#     keep flowing on the wall clock while simulated time stands still;
#  2. a REC_REQ gets its stream: SIM_CLOCK(t0), REC_DATA Seq 0..19 in order
#     with 30 samples each, REC_END complete with the total, SIM_CLOCK(t1);
#  3. an ACT_CMD is acknowledged (CmdSeq echoed) and completes in lockstep;
#  4. determinism: a second simulator with the same scenario and seed, given
#     the same frames, sends the same plant frames, byte for byte (heartbeats
#     excluded: they follow the wall clock);
#  5. SIGTERM ends the process cleanly (exit 0).
set -eu
SIM=${1:?usage: test_sim_bus.sh SIM MDCAN SCENARIO}
MDCAN=${2:?usage: test_sim_bus.sh SIM MDCAN SCENARIO}
SCENARIO=${3:?usage: test_sim_bus.sh SIM MDCAN SCENARIO}
if [ ! -x "$MDCAN" ]; then
    echo "SKIP: $MDCAN not built (tools/ not in this build)" >&2
    exit 77
fi
tmp=$(mktemp -d)
pids=""
cleanup() {
    for p in $pids; do kill "$p" 2>/dev/null || true; done
    rm -rf "$tmp"
}
trap cleanup EXIT

fail() {
    echo "FAIL: $*" >&2
    for f in "$tmp"/*.err; do echo "--- $f" >&2; cat "$f" >&2; done
    exit 1
}

# wait_for FILE PATTERN: bounded (10 s) wait for a line in a log.
wait_for() {
    i=0
    until grep -q "$2" "$1" 2>/dev/null; do
        i=$((i + 1))
        [ "$i" -le 500 ] || fail "timeout waiting for '$2' in $1"
        sleep 0.02
    done
}

# run NAME: one simulator run observed by one dump; frames in $tmp/NAME.frames
run() {
    name=$1
    "$MDCAN" dump --bus udp --timeout-ms 1500 >"$tmp/$name.dump" 2>"$tmp/$name.dump.err" &
    dump_pid=$!
    pids="$pids $dump_pid"
    wait_for "$tmp/$name.dump.err" "listening on"
    "$SIM" --scenario "$SCENARIO" --seed 3 --bus udp >"$tmp/$name.out" 2>"$tmp/$name.err" &
    sim_pid=$!
    pids="$pids $sim_pid"
    wait_for "$tmp/$name.err" "nodes 2, 3, 4"
    sleep 0.5    # simulated time stands still; heartbeats must not
    # REC_REQ: electrode 0, interval 7, 600 samples
    "$MDCAN" send --bus udp 220#0007005802000000 || fail "send REC_REQ"
    sleep 0.3
    # ACT_CMD: electrode 0, step, advance, Seq 33, 50 steps at 1000 Hz
    "$MDCAN" send --bus udp 210#000100213200E803 || fail "send ACT_CMD"
    sleep 0.3
    kill -TERM "$sim_pid"
    rc=0
    wait "$sim_pid" || rc=$?
    [ "$rc" -eq 0 ] || fail "$name: microdrive-sim exit $rc after SIGTERM"
    grep -q "signal 15, exiting" "$tmp/$name.err" || fail "$name: no clean exit message"
    grep -q "bus udp:" "$tmp/$name.err" || fail "$name: bus choice not printed"
    wait "$dump_pid" || true
    pids=""
    cut -d' ' -f3 "$tmp/$name.dump" >"$tmp/$name.frames"
}

run a
f="$tmp/a.frames"

# 1. heartbeats: NodeState 5, version 1, flags lockstep, 1 electrode; >= 5 each in ~1 s
for id in 702 703 704; do
    n=$(grep -c "^$id#05010401" "$f" || true)
    [ "$n" -ge 5 ] || fail "heartbeat $id: $n frames"
done
# boot-up messages (NodeState 0) first
for id in 702 703 704; do
    grep -q "^$id#00010401" "$f" || fail "boot-up heartbeat $id missing"
done

# 2. the stream of interval 7, in order, framed by SIM_CLOCK
grep -v '^70[2-4]#' "$f" >"$tmp/plant.frames"
awk '/^220#/{go=1} go' "$tmp/plant.frames" | grep -v '^220#\|^210#' >"$tmp/after_req"
[ "$(head -n 1 "$tmp/after_req")" = "020#0000000000000000" ] || fail "stream not opened by SIM_CLOCK(0)"
grep '^400##' "$tmp/after_req" >"$tmp/rec_data" || fail "no REC_DATA"
[ "$(wc -l <"$tmp/rec_data")" -eq 20 ] || fail "REC_DATA frames: $(wc -l <"$tmp/rec_data"), want 20"
i=0
while read -r line; do
    # 400##<flags nibble><Electrode 00><SampleCount 1E><Seq little-endian>
    seq=$(printf '%02X00' "$i")
    case "$line" in
        "400##"?"001E$seq"*) ;;
        *) fail "REC_DATA $i out of order or malformed: $line" ;;
    esac
    i=$((i + 1))
done <"$tmp/rec_data"
grep -q '^410#0000070058020000$' "$tmp/after_req" || fail "REC_END (complete, interval 7, 600) missing"
# 600 samples at 30 kHz: the batch closes at 20000 us
grep -q '^020#204E000000000000$' "$tmp/after_req" || fail "closing SIM_CLOCK(20000 us) missing"

# 3. the motion: acknowledged with CmdSeq 33 (0x21), done with 50 steps (0x32)
grep -q '^290#0001210000003200$' "$tmp/plant.frames" || fail "ACT_STATUS moving, CmdSeq 33, 50 to go"
grep -q '^290#0000210032000000$' "$tmp/plant.frames" || fail "ACT_STATUS idle, 50 done"

# 4. a second run with the same seed and frames: the same plant frames
run b
grep -v '^70[2-4]#' "$tmp/b.frames" >"$tmp/plant_b.frames"
cmp -s "$tmp/plant.frames" "$tmp/plant_b.frames" || {
    diff "$tmp/plant.frames" "$tmp/plant_b.frames" | head -20 >&2
    fail "two runs with the same seed differ"
}
echo "test_sim_bus: OK ($(wc -l <"$tmp/plant.frames") plant frames identical in two runs)"
