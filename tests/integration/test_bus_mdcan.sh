#!/bin/sh
# Integration test of mdcan on the UDP bus, in the manner of CANopenNode's
# cansend/candump tests: two `mdcan dump` processes and `mdcan send` in
# another, exact candump -L output checked. Run it inside a private network
# namespace: scripts/netns-run.sh tests/integration/test_bus_mdcan.sh MDCAN
set -eu
MDCAN=${1:?usage: test_bus_mdcan.sh PATH/TO/mdcan}
tmp=$(mktemp -d)
pids=""
cleanup() {
    for p in $pids; do kill "$p" 2>/dev/null || true; done
    rm -rf "$tmp"
}
trap cleanup EXIT

fail() {
    echo "FAIL: $*" >&2
    for f in "$tmp"/*; do [ -f "$f" ] && { echo "--- $f" >&2; cat "$f" >&2; }; done
    exit 1
}

[ -x "$MDCAN" ] || fail "no executable mdcan at '$MDCAN'"

# Starts a dump in the background; waits (bounded, 10 s) until it has joined.
start_dump() {
    name=$1
    shift
    "$MDCAN" dump "$@" >"$tmp/$name.out" 2>"$tmp/$name.err" &
    pids="$pids $!"
    eval "${name}_pid=$!"
    i=0
    until grep -qs "listening on" "$tmp/$name.err"; do
        i=$((i + 1))
        [ "$i" -le 500 ] || fail "$name did not start"
        kill -0 "$!" 2>/dev/null || grep -qs "listening on" "$tmp/$name.err" || fail "$name exited at start"
        sleep 0.02
    done
}

# 1. Two listeners, one sender: classic, extended, FD with BRS, FD padded.
start_dump d1 --bus udp --count 5 --timeout-ms 5000
start_dump d2 --bus udp:57731 --count 5 --timeout-ms 5000 --iface vcan9
"$MDCAN" send --bus udp 123#DEADBEEF 1ABCDEF0#00.11.22 7FF# 321##1000102030405060708090A0B \
    456##0112233 || fail "send returned $?"
wait "$d1_pid" || fail "dump 1 exited $?"
wait "$d2_pid" || fail "dump 2 exited $?"
pids=""

cat >"$tmp/expected" <<'EOT'
123#DEADBEEF
1ABCDEF0#001122
7FF#
321##5000102030405060708090A0B
456##4112233
EOT
for d in d1 d2; do
    # candump -L line shape: (10 digits.6 digits) LABEL FRAME
    grep -Evq '^\([0-9]{10}\.[0-9]{6}\) [A-Za-z0-9]+ [0-9A-F#]+$' "$tmp/$d.out" && fail "$d: bad line shape"
    cut -d' ' -f3 "$tmp/$d.out" >"$tmp/$d.frames"
    cmp -s "$tmp/expected" "$tmp/$d.frames" || fail "$d: frames differ"
    grep -q "malformed 0, overflow 0" "$tmp/$d.err" || fail "$d: stats"
done
[ "$(cut -d' ' -f2 "$tmp/d1.out" | sort -u)" = "udp57731" ] || fail "d1 label"
[ "$(cut -d' ' -f2 "$tmp/d2.out" | sort -u)" = "vcan9" ] || fail "d2 label"

# 2. A bad frame sends nothing (exit 2), even when good ones precede it.
start_dump d3 --bus udp --count 1 --timeout-ms 700
rc=0
"$MDCAN" send --bus udp 100#01 123#R 2>"$tmp/send.err" || rc=$?
[ "$rc" -eq 2 ] || fail "bad frame: exit $rc, want 2"
grep -q "RTR" "$tmp/send.err" || fail "bad frame: no reason given"
rc=0
wait "$d3_pid" || rc=$?
pids=""
[ "$rc" -eq 1 ] || fail "dump with no traffic: exit $rc, want 1 (count not reached)"
[ ! -s "$tmp/d3.out" ] || fail "a frame was sent despite the syntax error"

# 3. Usage and bus errors are distinct exit codes.
rc=0; "$MDCAN" send --bus udp 2>/dev/null || rc=$?
[ "$rc" -eq 2 ] || fail "send without frame: exit $rc"
rc=0; "$MDCAN" dump --bus tcp:1 --count 1 2>"$tmp/bus.err" || rc=$?
[ "$rc" -eq 3 ] || fail "unknown bus: exit $rc"
grep -q "unknown bus spec" "$tmp/bus.err" || fail "unknown bus: message"
echo "test_bus_mdcan: OK"
