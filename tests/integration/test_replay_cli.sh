#!/bin/sh
# mhtc-replay end to end: a short simulator export is replayed with every
# tracker; outputs are checked for shape; bad sidecars give a clear error
# naming the file and field; a sampling-rate-only sidecar is cut by --interval;
# a sample rate the firmware's chain does not take is refused, and detections
# beyond an interval's window capacity are reported and counted.
# usage: test_replay_cli.sh SIM_EXPORT MHTC_REPLAY SCENARIO.yaml
set -eu
SIM=$1
REPLAY=$2
SCEN=$3
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$SIM" "$SCEN" "$W/rec" --seed 7 --intervals 4 --interval-s 4 > /dev/null

# sim-export refuses counts strtoul would wrap, and says which
for bad in "--intervals -1" "--intervals 0" "--intervals 4294967296" "--seed -3" "--interval-s inf"; do
    # shellcheck disable=SC2086
    if "$SIM" "$SCEN" "$W/never" $bad 2> "$W/msg"; then fail "sim-export accepted $bad"; fi
    grep -q -- "sim-export: $bad: not a valid value" "$W/msg" || fail "sim-export $bad: message"
done

for t in mhtc map-nn ml-nn gnn; do
    "$REPLAY" --recording "$W/rec/recording.json" --out "$W/out-$t" --tracker "$t" 2> "$W/err-$t"
    head -1 "$W/out-$t/labels.csv" | grep -qx 'sample_index,interval,cluster,track_id' || fail "$t: labels header"
    [ "$(wc -l < "$W/out-$t/intervals.jsonl")" -eq 4 ] || fail "$t: expected 4 interval lines"
    grep -q '"clusters":\[' "$W/out-$t/intervals.jsonl" || fail "$t: no clusters list"
    grep -q '"tracks":\[' "$W/out-$t/intervals.jsonl" || fail "$t: no tracks list"
    grep -q "\"tracker\": \"$t\"" "$W/out-$t/summary.json" || fail "$t: summary tracker"
    grep -q '^\[4/4\]' "$W/err-$t" || fail "$t: no progress on stderr"
    [ "$(wc -l < "$W/out-$t/labels.csv")" -gt 10 ] || fail "$t: too few labelled spikes"
done
python3 -c "import json,sys; [json.loads(l) for l in open('$W/out-mhtc/intervals.jsonl')]; json.load(open('$W/out-mhtc/summary.json'))" \
    || fail "outputs are not valid JSON"

# sampling rate only: consecutive intervals of --interval seconds
printf '{"sampling_frequency": 30000, "num_channels": 1, "dtype": "int16", "file": "../rec/recording.bin"}' \
    > "$W/plain.json"
mkdir -p "$W/plain"
mv "$W/plain.json" "$W/plain/recording.json"
"$REPLAY" --recording "$W/plain/recording.json" --out "$W/out-plain" --interval 8 --quiet
[ "$(wc -l < "$W/out-plain/intervals.jsonl")" -eq 2 ] || fail "sampling-rate-only sidecar: expected 2 intervals of 8 s"

# what the firmware's streaming chain cannot take is said, with file, interval and reason:
# a sample rate outside it (refused), more detections than the windows of an interval (kept
# as the controller keeps them, the rest reported and counted)
mkdir -p "$W/fast" "$W/busy"
printf '{"sampling_frequency": 40000, "num_channels": 1, "dtype": "int16", "file": "../rec/recording.bin"}' \
    > "$W/fast/recording.json"
if "$REPLAY" --recording "$W/fast/recording.json" --out "$W/out-fast" 2> "$W/msg"; then fail "40 kHz accepted"; fi
grep -q "$W/fast/recording.json: interval 0: sampling_frequency 40000 Hz is not supported by the firmware's streaming chain, which takes 7500..32768 Hz" "$W/msg" \
    || { cat "$W/msg" >&2; fail "40 kHz: message"; }
python3 - "$W/busy" <<'PY'
import array, json, math, random, sys
d = sys.argv[1]
rnd = random.Random(1)
n = 120000                                   # one 4 s interval at 30 kHz
x = [rnd.gauss(0.0, 20.0) for _ in range(n)]
for t in range(300, n - 300, 200):           # 150 Hz: ~600 spikes, more than MD_MAX_SPIKES (512)
    for j in range(-10, 11):
        x[t + j] -= 250.0 * math.exp(-0.5 * (j / 2.5) ** 2)
a = array.array("h", [max(-32768, min(32767, round(v))) for v in x])
if sys.byteorder == "big":
    a.byteswap()
open(d + "/recording.bin", "wb").write(a.tobytes())
json.dump({"sampling_frequency": 30000, "num_channels": 1, "dtype": "int16", "gain_uV": 0.195,
           "intervals": [{"start_sample": 0, "num_samples": n}]}, open(d + "/recording.json", "w"))
PY
"$REPLAY" --recording "$W/busy/recording.json" --out "$W/out-busy" --quiet 2> "$W/msg" || fail "busy: mhtc-replay failed"
grep -q "$W/busy/recording.json: interval 0: [0-9]* detection(s) not kept: [0-9]* beyond the capacity of 512 windows per interval" "$W/msg" \
    || { cat "$W/msg" >&2; fail "busy: no capacity report"; }
python3 -c "import json,sys; s=json.load(open(sys.argv[1])); assert s['spikes'] == 512 and s['detections_not_kept'] > 0, s" \
    "$W/out-busy/summary.json" || fail "busy: summary.json"

# bad input: exit status 1 or 2 and a message naming file and field
expect_err() { # $1 = pattern, rest = args
    pat=$1; shift
    if "$REPLAY" "$@" --out "$W/bad" 2> "$W/msg"; then fail "accepted: $*"; fi
    grep -q "$pat" "$W/msg" || { cat "$W/msg" >&2; fail "message lacks '$pat'"; }
}
expect_err 'cannot open' --recording "$W/none.json"
printf '{"sampling_frequency": 30000, "num_channels": 1, "dtype": "float64"}' > "$W/plain/recording.json"
expect_err 'field "dtype"' --recording "$W/plain/recording.json"
printf '{"num_channels": 1, "dtype": "int16"}' > "$W/plain/recording.json"
expect_err 'field "sampling_frequency": missing' --recording "$W/plain/recording.json"
printf '{"sampling_frequency": 30000, ' > "$W/plain/recording.json"
expect_err 'not a JSON object' --recording "$W/plain/recording.json"
expect_err 'channel' --recording "$W/rec/recording.json" --channel 3
expect_err 'invalid value' --recording "$W/rec/recording.json" --tracker kalman
expect_err 'required' --tracker mhtc
echo "test_replay_cli: OK"
