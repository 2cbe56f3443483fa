#!/usr/bin/env bash
# microdrive-session in-process, twice with the same scenario + seed: exit 0
# (goal of N cycles reached), progress lines, the frame log byte-identical
# between the runs (virtual clock: time stamps included), truth.jsonl and the
# recording (recording.bin/.json) identical, no REC_DATA in the frame log,
# report.json with every interface field, and a third run with another seed
# that differs.
#   test_session_inproc.sh BIN_DIR SCENARIO OUT_DIR CYCLES
set -uo pipefail
bin=${1:?usage: test_session_inproc.sh BIN_DIR SCENARIO OUT_DIR CYCLES}
scenario=${2:?} out=${3:?} cycles=${4:?}
rm -rf "$out" && mkdir -p "$out"
fail() { echo "FAIL: $*"; exit 1; }
for run in a b; do
    "$bin/microdrive-session" --scenario "$scenario" --seed 7 --bus inproc --cycles "$cycles" --out "$out/$run" \
        >"$out/$run.txt" 2>&1 || { cat "$out/$run.txt"; fail "run $run exited $?"; }
done
"$bin/microdrive-session" --scenario "$scenario" --seed 8 --bus inproc --cycles "$cycles" --out "$out/c" \
    >"$out/c.txt" 2>&1 || { cat "$out/c.txt"; fail "run c exited $?"; }
[ "$(grep -c '^e0 cycle' "$out/a.txt")" -eq "$cycles" ] || fail "expected $cycles progress lines of e0"
cmp -s "$out/a/candump.log" "$out/b/candump.log" || fail "frame logs of the same seed differ"
cmp -s "$out/a/truth.jsonl" "$out/b/truth.jsonl" || fail "ground truth of the same seed differs"
cmp -s "$out/a/report.json" "$out/b/report.json" || fail "reports of the same seed differ"
cmp -s "$out/a/recording.bin" "$out/b/recording.bin" || fail "recordings of the same seed differ"
cmp -s "$out/a/recording.json" "$out/b/recording.json" || fail "recording sidecars of the same seed differ"
[ "$(stat -c %s "$out/a/recording.bin")" -gt 0 ] || fail "empty recording.bin"
grep -q ' 400##' "$out/a/candump.log" && fail "REC_DATA in candump.log without --candump-samples"
cmp -s "$out/a/candump.log" "$out/c/candump.log" && fail "another seed gave the same frames"
grep -q '"type":"interval"' "$out/a/truth.jsonl" || fail "no interval record in the truth"
python3 - "$out/a/report.json" "$cycles" <<'PY' || fail "report.json lacks interface fields"
import json, sys
r = json.load(open(sys.argv[1]))
assert r["scenario"] and r["seed"] == 7 and r["bus"] == "inproc" and r["end"] == "goal" and r["complete"]
keys = ["isolated", "cycles_to_isolation", "time_to_isolation_s", "final_peak_distance_um", "neurons_damaged",
        "held_fraction", "reisolations", "tracking"]
for e in r["electrodes"]:
    assert all(k in e for k in keys), e
    assert e["cycles"] == int(sys.argv[2]), e["cycles"]
    assert all(k in e["tracking"] for k in ("accuracy", "id_consistency", "id_switches", "spurious_tracks", "psi"))
    assert e["final_peak_distance_um"] is not None
PY
lines=$(wc -l <"$out/a/candump.log")
echo "in-process session: $cycles cycles, $lines frames, identical logs, truth and reports for seed 7; seed 8 differs"
echo "1 passed, 0 failed"
