#!/usr/bin/env bash
# Self-test of scripts/with-vcan.sh.
#
#   scripts/with-vcan.sh tests/vcan/selftest.sh
#       Runs where vcan0 is up (host or VM): checks vcan0 has mtu 72, then
#       sends a classic frame (123#DEADBEEF) and a CAN FD frame (456##1 +
#       16 bytes) while `candump -L vcan0` logs to
#       $VCAN_SELFTEST_OUT/candump.log, and checks both frames were received.
#       VCAN_SELFTEST_OUT defaults to <first WITH_VCAN_OUT dir>/vcan-selftest,
#       else $PWD/build/vcan-selftest (a read-write share in the VM).
#
#   tests/vcan/selftest.sh --wrapper
#       Runs on the host and drives with-vcan.sh itself: the check above
#       (and that candump.log came back to the host through the read-write
#       share), that CMD's stdout reaches the caller, and that CMD's exit
#       status (7) propagates.
#
# Ends with a line "vcan selftest: N passed, N failed"; exit 0 iff none failed.

set -euo pipefail

HERE=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")" && pwd -P)
REPO=$(cd -- "$HERE/../.." && pwd -P)
readonly HERE REPO
readonly CLASSIC='123#DEADBEEF'
readonly FD_DATA='00112233445566778899AABBCCDDEEFF' # 16 bytes
readonly FD="456##1$FD_DATA"
# candump -L prints the FD flags nibble as received: BRS (1) must be set; newer
# kernels also report CANFD_FDF (4), giving 5.
readonly FD_RE=" vcan0 456##[13579BDF]$FD_DATA\$"

passed=0
failed=0
ok() { passed=$((passed + 1)); printf 'ok   %s\n' "$*"; }
not_ok() { failed=$((failed + 1)); printf 'FAIL %s\n' "$*"; }
check() { # check DESCRIPTION COMMAND...
    local what=$1
    shift
    if "$@" >/dev/null 2>&1; then ok "$what"; else not_ok "$what"; fi
}
summary() {
    printf 'vcan selftest: %d passed, %d failed\n' "$passed" "$failed"
    ((failed == 0))
}

# Both frames in a `candump -L` log ("(time) vcan0 123#DEADBEEF",
# "(time) vcan0 456##1<data>").
log_has_frames() {
    grep -qF " vcan0 $CLASSIC" "$1" && grep -qE "$FD_RE" "$1"
}

# Wait (up to ~5 s) until a CAN_RAW socket is bound to vcan0, so the frames
# we send are not missed by a candump that is still starting (slow under TCG).
wait_for_receiver() {
    local i
    for ((i = 0; i < 50; i++)); do
        # an entry line ("   vcan0  000  00000000 ..."), not the "(vcan0: no entry)" line
        # the list shows before any socket is bound
        grep -qsE '^ +vcan0 ' /proc/net/can/rcvlist_all && return 0
        sleep 0.1
    done
    return 1
}

inside() {
    local out=${VCAN_SELFTEST_OUT:-}
    if [[ -z $out ]]; then
        if [[ -n ${WITH_VCAN_OUT:-} ]]; then
            out=${WITH_VCAN_OUT%%:*}/vcan-selftest
        else
            out=$PWD/build/vcan-selftest
        fi
    fi
    mkdir -p "$out"
    local log=$out/candump.log dump_pid mtu
    rm -f "$log"

    check "vcan0 exists" ip link show dev vcan0
    mtu=$(cat /sys/class/net/vcan0/mtu 2>/dev/null || echo none)
    check "vcan0 mtu is 72 (CAN FD), got $mtu" test "$mtu" = 72
    check "cansend/candump/cangen installed" command -v cansend candump cangen

    candump -L vcan0 >"$log" 2>&1 &
    dump_pid=$!
    wait_for_receiver || sleep 1
    check "cansend classic $CLASSIC" cansend vcan0 "$CLASSIC"
    check "cansend FD $FD" cansend vcan0 "$FD"
    # Give candump (slow under TCG, on a busy host) up to ~10 s to log both.
    local i
    for ((i = 0; i < 100; i++)); do
        log_has_frames "$log" && break
        sleep 0.1
    done
    sleep 0.2
    kill "$dump_pid" 2>/dev/null || true
    wait "$dump_pid" 2>/dev/null || true

    check "candump saw the classic frame" grep -qF " vcan0 $CLASSIC" "$log"
    check "candump saw the FD frame (16 bytes)" grep -qE "$FD_RE" "$log"
    if ((failed)); then
        echo "--- $log:"
        cat "$log" || true
    fi
    summary
}

wrapper() {
    local wv=$REPO/scripts/with-vcan.sh rc t0 t1 stdout
    OUT=$(mktemp -d "${TMPDIR:-/tmp}/vcan-selftest.XXXXXX")
    trap 'rm -rf -- "$OUT"' EXIT
    cd "$REPO"

    t0=$(date +%s%N)
    rc=0
    WITH_VCAN_OUT=$OUT VCAN_SELFTEST_OUT=$OUT "$wv" "$HERE/selftest.sh" || rc=$?
    t1=$(date +%s%N)
    check "selftest inside with-vcan passed (exit $rc, $(((t1 - t0) / 1000000)) ms)" test "$rc" = 0
    check "candump.log came back to the host with both frames" log_has_frames "$OUT/candump.log"

    t0=$(date +%s%N)
    rc=0
    stdout=$("$wv" sh -c 'echo to-stdout; echo to-stderr >&2; exit 7' 2>/dev/null) || rc=$?
    t1=$(date +%s%N)
    check "exit status propagates: with-vcan sh -c 'exit 7' -> $rc ($(((t1 - t0) / 1000000)) ms)" test "$rc" = 7
    check "CMD stdout reaches the caller (got '$stdout')" test "$stdout" = to-stdout
    summary
}

case ${1:-} in
    --wrapper) wrapper ;;
    '') inside ;;
    *)
        echo "usage: scripts/with-vcan.sh $0 | $0 --wrapper" >&2
        exit 2
        ;;
esac
