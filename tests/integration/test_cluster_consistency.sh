#!/bin/sh
# Regression check of the clustering-consistency experiment
# (docs/clustering-consistency.md) on one short fixed recording:
# scenarios/drifting_pair.yaml, seed 1, 6 intervals, q = 8.5 uV.
#  1. the tool reads the export: a header and one row per interval, every
#     row with Ĝ in 0..4 for both methods and accuracies in [0, 1];
#  2. ground truth is joined to the detections: all three neurons of the
#     scenario are in range in every interval (n_true = 3, ids 0;1;2);
#  3. the MAP prior is built from the previous interval: no targets at k = 0,
#     at least one target in every later interval that follows a clustered one;
#  4. the figure itself, on this deterministic recording: MAP's Ψ is not
#     above ML's (a change to the clustering that breaks this shows here);
#  5. --drift gives one row per (interval, neuron) pair with dq2 >= 0;
#  6. errors: a missing directory exits 1, an unknown option exits 2.
set -eu
EXPORT=${1:?usage: test_cluster_consistency.sh SIM_EXPORT CLUSTER_CONSISTENCY SCENARIO}
TOOL=${2:?usage: test_cluster_consistency.sh SIM_EXPORT CLUSTER_CONSISTENCY SCENARIO}
SCENARIO=${3:?usage: test_cluster_consistency.sh SIM_EXPORT CLUSTER_CONSISTENCY SCENARIO}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$EXPORT" "$SCENARIO" "$tmp/rec" --seed 1 --intervals 6 >/dev/null
"$TOOL" "$tmp/rec" --q-uv 8.5 >"$tmp/out.csv" 2>"$tmp/err.txt"
cat "$tmp/out.csv"

# 1-4 in one pass over the CSV (columns: see the header check)
head -n 1 "$tmp/out.csv" | grep -q '^scenario,seed,channel,k,depth_um,n_spikes,n_false,n_noise,n_true,true_ids,n_targets,g_map,p_map,acc_map,g_ml,p_ml,acc_ml,det_overflow$' \
    || fail "unexpected header"
awk -F, 'NR == 1 { next }
    {
        rows++
        if ($4 != rows - 1) { print "row " rows ": interval " $4; bad = 1 }
        if ($12 < 0 || $12 > 4 || $15 < 0 || $15 > 4) { print "k=" $4 ": G out of range"; bad = 1 }
        if ($14 < 0 || $14 > 1 || $17 < 0 || $17 > 1) { print "k=" $4 ": accuracy out of range"; bad = 1 }
        if ($9 != 3 || $10 != "0;1;2") { print "k=" $4 ": n_true " $9 " ids " $10; bad = 1 }
        if ($4 == 0 && $11 != 0) { print "k=0 has targets"; bad = 1 }
        if ($4 > 0 && prev_g > 0 && $11 < 1) { print "k=" $4 ": no targets after a clustered interval"; bad = 1 }
        if ($4 > 0) { psi_map += ($12 > prev_g ? $12 - prev_g : prev_g - $12); psi_ml += ($15 > prev_ml ? $15 - prev_ml : prev_ml - $15) }
        prev_g = $12; prev_ml = $15
    }
    END {
        if (rows != 6) { print "rows: " rows; bad = 1 }
        printf "Psi MAP %d, ML %d\n", psi_map, psi_ml
        if (psi_map > psi_ml) { print "MAP is more inconsistent than ML"; bad = 1 }
        exit bad
    }' "$tmp/out.csv" || fail "interval table"

# 5
"$TOOL" "$tmp/rec" --drift >"$tmp/drift.csv"
awk -F, 'NR == 1 { if ($0 != "k,neuron,dq2_uv2") bad = 1; next }
    { rows++; if ($1 < 1 || $1 > 5 || $2 < 0 || $2 > 2 || !($3 >= 0)) bad = 1 }
    END { if (rows < 5) bad = 1; exit bad }' "$tmp/drift.csv" || fail "drift rows"

# 6
set +e
"$TOOL" "$tmp/missing" >/dev/null 2>&1; rc=$?
[ "$rc" -eq 1 ] || fail "missing directory exit $rc"
"$TOOL" "$tmp/rec" --bogus >/dev/null 2>&1; rc=$?
[ "$rc" -eq 2 ] || fail "unknown option exit $rc"
echo "PASS"
