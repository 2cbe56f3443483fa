#!/usr/bin/env bash
# Measures whether a whole session over the UDP bus, run by an ordinary user,
# equals the in-process session (docs/bus.md, "Flow control"). One scenario and
# seed, three runs one after another:
#   inproc      the reference (one process, virtual clock);
#   udp-root    real root in a private network namespace (SO_RCVBUFFORCE allowed);
#   udp-user    `netns-run.sh --unprivileged`: a user namespace, so the stock
#               212992-byte buffers only, as for any non-root user.
# Controller parameters are the defaults (heartbeat timeout included). Prints
# one Markdown table row: wall times, frames lost (recorder / sim / fw), flow
# waits, and whether each UDP session equals the in-process one
# (compare_sessions.py: every decision and telemetry frame, then report.json).
# Exit 0 when the unprivileged run lost nothing and its report is equal.
#   udp_equality.sh BIN_DIR SCENARIO SEED OUT_DIR
set -uo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=${1:?usage: udp_equality.sh BIN_DIR SCENARIO SEED OUT_DIR}
scenario=${2:?} seed=${3:?} out=${4:?}
[ "$(id -u)" -eq 0 ] || { echo "udp_equality: the root comparison run needs root" >&2; exit 2; }
python=${MD_PYTHON:-$root/.venv/bin/python}
[ -x "$python" ] || { echo "udp_equality: no Python with cantools at $python (scripts/setup-venv.sh)" >&2; exit 2; }
rm -rf "$out" && mkdir -p "$out"

run() {  # NAME BUS [PREFIX...]: one session, wall time in $out/NAME.wall
    local name=$1 bus=$2; shift 2
    local t0 t1 rc
    t0=$(date +%s.%N)
    "$@" "$bin/microdrive-session" --scenario "$scenario" --seed "$seed" --bus "$bus" \
        --no-lcm --no-plots --quiet --out "$out/$name" >"$out/$name.txt" 2>&1
    rc=$?
    t1=$(date +%s.%N)
    echo "$t0 $t1" | awk '{ printf "%.0f\n", $2 - $1 }' >"$out/$name.wall"
    echo "udp_equality: $name exit $rc, $(cat "$out/$name.wall") s: $(tail -n 1 "$out/$name.txt")" >&2
    return "$rc"
}
losses() {  # NAME: "recorder / sim / fw" frames lost, and the flow waits
    sed -n 's/.*frames lost: recorder \([0-9]*\).*microdrive-sim \([0-9]*\) (malformed [0-9]*; flow waits \([0-9]*\), timeouts \([0-9]*\)), microdrive-fw \([0-9]*\).*/\1 \/ \2 \/ \5 (sim waited \3 times, timeouts \4)/p' \
        "$out/$1.txt" | head -n 1
}
equal() {  # NAME: yes, or the first difference from the in-process session (frames, then report.json)
    if "$python" "$root/tools/session/compare_sessions.py" "$out/inproc" "$out/$1" >"$out/$1.compare" 2>&1; then
        echo yes
    else
        echo "no: $(grep -o 'FIRST DIFFERENCE.*\|report.json DIFFERENT.*' "$out/$1.compare" | head -n 1)"
    fi
}

run inproc inproc || exit 1
run udp-root udp "$root/scripts/netns-run.sh"
run udp-user udp "$root/scripts/netns-run.sh" --unprivileged
user_loss=$(losses udp-user)
printf '| %s seed %s | %s s | %s s | %s | %s | %s | %s s |\n' \
    "$(basename "$scenario" .yaml)" "$seed" "$(cat "$out/udp-user.wall")" "$(cat "$out/udp-root.wall")" \
    "${user_loss:-no loss report}" "$(equal udp-user)" "$(equal udp-root)" "$(cat "$out/inproc.wall")"
case "$user_loss" in "0 / 0 / 0 "*) ;; *) exit 1 ;; esac
[ "$(equal udp-user)" = yes ]
