#!/bin/sh
# float32 recordings through the host tools (tools/recording: a float32 value
# v is v * gain_uV uV, delivered as int16 counts of min(gain_uV, 1) uV).
# From one int16 simulator export (gain_uV 0.195):
#  A. the same counts stored as float32, same gain_uV: mhtc-replay's labels,
#     online labels and per-interval output, and cluster-consistency's rows,
#     equal the int16 recording's;
#  B. the signal in uV as float32 without gain_uV: labels equal those of the
#     int16 recording B would be converted to (counts of 1 uV, rounded half
#     away from zero, gain_uV 1), written independently here;
#  D. the same in volts as float32 with gain_uV 1e6: the int16 recording of
#     1 uV counts it stands for (the chain must be given 1 uV per count, not
#     gain_uV);
#  C. B with samples beyond the int16 range and NaNs: the tool still runs,
#     reports them per interval on stderr and counts them in summary.json.
# usage: test_float32_recording.sh SIM_EXPORT MHTC_REPLAY SCENARIO.yaml [CLUSTER_CONSISTENCY]
set -eu
SIM=${1:?usage: test_float32_recording.sh SIM_EXPORT MHTC_REPLAY SCENARIO.yaml [CLUSTER_CONSISTENCY]}
REPLAY=${2:?}
SCEN=${3:?}
CC=${4:-}
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$SIM" "$SCEN" "$W/i16" --seed 7 --intervals 4 --interval-s 4 > /dev/null

python3 - "$W" <<'EOF'
import array, json, math, os, sys

w = sys.argv[1]
side = json.load(open(os.path.join(w, "i16", "recording.json")))
assert side["dtype"] == "int16" and side["num_channels"] == 1
g = side["gain_uV"]
c = array.array("h")
c.frombytes(open(os.path.join(w, "i16", "recording.bin"), "rb").read())
if sys.byteorder == "big":
    c.byteswap()

def write(name, sidecar, typecode, values):
    d = os.path.join(w, name)
    os.makedirs(d)
    a = array.array(typecode, values)
    if sys.byteorder == "big":
        a.byteswap()
    with open(os.path.join(d, "recording.bin"), "wb") as f:
        f.write(a.tobytes())
    with open(os.path.join(d, "recording.json"), "w") as f:
        json.dump(sidecar, f, indent=1)
    return a

def f32(x):  # the float32 nearest x, as Python's float
    return array.array("f", [x])[0]

def round_half_away(v):
    return int(math.copysign(math.floor(abs(v) + 0.5), v))

# A: counts as float32, same sidecar but the dtype
write("f32_counts", dict(side, dtype="float32"), "f", [float(x) for x in c])

# B: uV as float32, no gain_uV; B16: what the reader must turn it into
uv = [f32(x * g) for x in c]
plain = {k: v for k, v in side.items() if k != "gain_uV"}
write("f32_uv", dict(plain, dtype="float32"), "f", uv)
counts = [round_half_away(v) for v in uv]
assert all(-32768 <= x <= 32767 for x in counts)
write("i16_uv", dict(plain, gain_uV=1.0), "h", counts)

# D: volts as float32, gain_uV 1e6; D16: counts of 1 uV
volts = [f32(x * g * 1e-6) for x in c]
write("f32_volts", dict(plain, dtype="float32", gain_uV=1e6), "f", volts)
write("i16_volts", dict(plain, gain_uV=1.0), "h", [round_half_away(v * 1e6) for v in volts])

# C: B with 3 samples beyond +-32.8 mV and 2 NaNs, all in interval 1
s1 = side["intervals"][1]["start_sample"]
assert side["intervals"][1]["num_samples"] > 5000
bad = list(uv)
for i, v in ((100, 1.0e6), (101, -1.0e6), (4000, 40000.0), (2000, float("nan")), (2001, float("nan"))):
    bad[s1 + i] = v
write("f32_bad", dict(plain, dtype="float32"), "f", bad)
EOF
[ -s "$W/f32_counts/recording.bin" ] || fail "no float32 recording written"

replay() { # NAME: replays W/NAME into W/out-NAME
    "$REPLAY" --recording "$W/$1/recording.json" --out "$W/out-$1" --quiet 2> "$W/err-$1" \
        || { cat "$W/err-$1" >&2; fail "$1: mhtc-replay failed"; }
}
same() { # A B: the outputs of two replays that must be equal
    for f in labels.csv labels_online.csv; do
        cmp -s "$W/out-$1/$f" "$W/out-$2/$f" || fail "$f of $1 and $2 differ"
    done
    # intervals.jsonl less the step times
    sed 's/"step_ms":[0-9.]*//' "$W/out-$1/intervals.jsonl" > "$W/iv-$1"
    sed 's/"step_ms":[0-9.]*//' "$W/out-$2/intervals.jsonl" > "$W/iv-$2"
    cmp -s "$W/iv-$1" "$W/iv-$2" || fail "intervals.jsonl of $1 and $2 differ"
    [ "$(wc -l < "$W/out-$1/labels.csv")" -gt 10 ] || fail "$1: too few labelled spikes to compare"
    echo "ok $1 = $2 ($(($(wc -l < "$W/out-$1/labels.csv") - 1)) labelled spikes)"
}
field() { # NAME KEY: a number of W/out-NAME/summary.json
    python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])" "$W/out-$1/summary.json" "$2"
}

for r in i16 f32_counts f32_uv i16_uv f32_volts i16_volts f32_bad; do replay "$r"; done
same i16 f32_counts
same i16_uv f32_uv
same i16_volts f32_volts
[ "$(field f32_volts count_uV)" = "1" ] || fail "f32_volts: count_uV $(field f32_volts count_uV)"
[ "$(field f32_counts count_uV)" = "0.195" ] || fail "f32_counts: count_uV $(field f32_counts count_uV)"
[ "$(field f32_uv count_uV)" = "1" ] || fail "f32_uv: count_uV $(field f32_uv count_uV)"
[ "$(field f32_uv dtype)" = "float32" ] || fail "f32_uv: dtype"
for r in i16 f32_counts f32_uv f32_volts; do
    [ "$(field $r samples_clipped)" = "0" ] && [ "$(field $r samples_non_finite)" = "0" ] || fail "$r: conversion counts"
    [ ! -s "$W/err-$r" ] || { cat "$W/err-$r" >&2; fail "$r: unexpected stderr"; }
done

# C: counted and reported, the recording still replayed
[ "$(field f32_bad samples_clipped)" = "3" ] || fail "f32_bad: samples_clipped $(field f32_bad samples_clipped)"
[ "$(field f32_bad samples_non_finite)" = "2" ] || fail "f32_bad: samples_non_finite"
[ "$(wc -l < "$W/err-f32_bad")" -eq 1 ] || { cat "$W/err-f32_bad" >&2; fail "f32_bad: expected one report line"; }
grep -qF "mhtc-replay: $W/f32_bad/recording.bin: interval 1, channel 0: 3 float32 sample(s) clipped to int16 counts of 1 uV, 2 NaN/inf set to 0" \
    "$W/err-f32_bad" || { cat "$W/err-f32_bad" >&2; fail "f32_bad: report line"; }
[ "$(wc -l < "$W/out-f32_bad/intervals.jsonl")" -eq 4 ] || fail "f32_bad: not every interval replayed"
echo "ok f32_bad: $(cat "$W/err-f32_bad")"

if [ -n "$CC" ]; then
    cp "$W/i16/ground_truth.csv" "$W/f32_counts/"
    "$CC" "$W/i16" > "$W/cc-i16.csv" 2> /dev/null
    "$CC" "$W/f32_counts" > "$W/cc-f32.csv" 2> /dev/null
    cmp -s "$W/cc-i16.csv" "$W/cc-f32.csv" || { diff "$W/cc-i16.csv" "$W/cc-f32.csv" >&2; fail "cluster-consistency rows differ"; }
    [ "$(wc -l < "$W/cc-f32.csv")" -eq 5 ] || fail "cluster-consistency: expected a header and 4 rows"
    echo "ok cluster-consistency: i16 = f32_counts"
fi
echo "test_float32_recording: OK"
