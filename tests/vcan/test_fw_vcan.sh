#!/usr/bin/env bash
# microdrive-fw on a real vcan0, driven with can-utils (CANopenNode style):
#
#   scripts/with-vcan.sh tests/vcan/test_fw_vcan.sh FW DBC PYTHON OUTDIR
#
# Runs where vcan0 is up (host, or the with-vcan VM). Starts `candump -L vcan0`
# and microdrive-fw --bus auto (which must choose vcan0), then with cansend:
# a parameter get and set (answers checked byte for byte in the candump log),
# an e-stop (EMCY 0x6200 checked) and a clear. Finally the whole candump -L
# log of the session must decode with `cantools decode` and the project DBC,
# every line. OUTDIR (a read-write share in the VM) keeps candump.log,
# decoded.log and fw.err for inspection.
set -euo pipefail
FW=${1:?usage: test_fw_vcan.sh FW DBC PYTHON OUTDIR}
DBC=${2:?}
PYTHON=${3:?}
OUT=${4:?}
mkdir -p "$OUT"
LOG=$OUT/candump.log
pids=()
cleanup() {
    local p
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
}
trap cleanup EXIT

fail() {
    echo "FAIL: $*" >&2
    echo "--- fw.err" >&2; cat "$OUT/fw.err" >&2 || true
    echo "--- candump.log (last 20)" >&2; tail -n 20 "$LOG" >&2 || true
    exit 1
}
ok() { echo "ok: $*"; }

# mark: remember how many lines the log has; wait_log REGEX then looks only at
# lines after the last mark, for up to 30 s (TCG is slow).
MARK=0
mark() { MARK=$(wc -l <"$LOG"); }
wait_log() {
    local i
    for ((i = 0; i < 300; i++)); do
        tail -n +$((MARK + 1)) "$LOG" | grep -qE "$1" && return 0
        sleep 0.1
    done
    return 1
}

candump -L vcan0 >"$LOG" &
pids+=($!)
for ((i = 0; i < 100; i++)); do
    grep -qs vcan0 /proc/net/can/rcvlist_all && break
    sleep 0.1
done

"$FW" --bus auto --heartbeat-ms 100 2>"$OUT/fw.err" &
fw_pid=$!
pids+=("$fw_pid")
wait_log ' vcan0 701#00' || fail "no boot-up heartbeat"
ok "boot-up heartbeat (NodeState 0)"
grep -q 'bus vcan0' "$OUT/fw.err" || fail "--bus auto did not choose vcan0"
ok "--bus auto chose vcan0: $(grep 'bus vcan0' "$OUT/fw.err")"
wait_log ' vcan0 701#7F010003' || fail "no pre-operational heartbeat"
ok "pre-operational heartbeat, protocol 1, 3 electrodes"

mark
# get heartbeat_period_ms (0x1017): Op 1, Status 0, Value 100.0f = 0x42C80000
cansend vcan0 601#0100171000000000
wait_log ' vcan0 581#010017100000C842$' || fail "no answer to the parameter get"
ok "PARAM_REQ get 0x1017 -> 581#010017100000C842 (ok, 100.0)"
# set heartbeat_timeout_ms (0x1016) to 300.0f = 0x43960000
mark
cansend vcan0 601#0200161000009643
wait_log ' vcan0 581#0200161000009643$' || fail "no answer to the parameter set"
ok "PARAM_REQ set 0x1016 = 300 -> ok"
# set out of range: status 2, value unchanged (300)
mark
cansend vcan0 601#020016100000C07F   # NaN
wait_log ' vcan0 581#0202161000009643$' || fail "NaN set not refused with status 2"
ok "PARAM_REQ set NaN -> status 2, value unchanged"

mark
cansend vcan0 000#0501
wait_log ' vcan0 081#006281FF05000000$' || fail "no EMCY 0x6200 after the e-stop"
ok "ESTOP -> EMCY_CTRL 0x6200 Info 5"
wait_log ' vcan0 701#7F010103' || fail "no latched flag in the heartbeat"
ok "heartbeat flag e-stop latched"
mark
cansend vcan0 001#8301
wait_log ' vcan0 701#7F010003' || fail "clear-e-stop not reflected in the heartbeat"
ok "clear-e-stop -> flag cleared, still pre-operational"

kill -INT "$fw_pid"
wait "$fw_pid" || fail "microdrive-fw exited $? on SIGINT"
ok "microdrive-fw exits 0 on SIGINT: $(tail -n 1 "$OUT/fw.err")"
sleep 0.2
kill "${pids[0]}" 2>/dev/null || true
wait "${pids[0]}" 2>/dev/null || true
pids=()

# Every line of the session decodes with the DBC (cantools prints "::" + the
# message for a frame it knows, the bare line otherwise).
"$PYTHON" -m cantools decode --single-line "$DBC" <"$LOG" >"$OUT/decoded.log" || fail "cantools decode failed"
total=$(wc -l <"$LOG")
decoded=$(grep -c ' :: ' "$OUT/decoded.log" || true)
[ "$total" -ge 10 ] || fail "only $total frames logged"
[ "$decoded" -eq "$total" ] || fail "$decoded of $total candump lines decoded"
grep -q 'PARAM_RESP_CTRL(Op: 1, Status: ok, Index: 4119, Value: 100.0)' "$OUT/decoded.log" ||
    fail "decoded parameter answer not found"
ok "cantools decode: all $total lines of candump.log decode with microdrive.dbc"
echo "test_fw_vcan: OK"
