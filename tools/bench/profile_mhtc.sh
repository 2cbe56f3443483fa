#!/usr/bin/env bash
# Where one MHTC step's instructions go, per model class G: host callgrind
# (inclusive Ir) of md-bench's mhtc stage, with em_fit and the Laplace evidence
# called through one non-inlined wrapper per G. The wrappers exist only in a
# throw-away copy of the tree (git archive of REV, default HEAD), so the
# firmware is unchanged; -fno-ipa-icf keeps gcc from merging them.
#
#   tools/bench/profile_mhtc.sh [REV] [WORKDIR]     (~2 min; needs valgrind)
set -euo pipefail
cd "$(dirname "$0")/../.."
rev="${1:-HEAD}"
work="${2:-/tmp/md-profile-mhtc}"
mkdir -p "$work" && work="$(cd "$work" && pwd)" # absolute: the build below runs from $work/src
rm -rf "$work"
mkdir -p "$work/src"
git archive "$rev" | tar -x -C "$work/src"
python3 - "$work/src/firmware/core/tracking/mhtc.c" <<'PY'
import sys
p = sys.argv[1]
s = open(p).read()
wr = r'''
#define PG(N) __attribute__((noinline)) static md_status_t em_fit_G##N(const em_data_t *a, const em_outlier_t *b, \
    const em_prior_t *c, const uint8_t *d, size_t e, const em_options_t *f, double *g, em_fit_t *h) \
    { return em_fit(a, b, c, d, e, f, g, h); } \
    __attribute__((noinline)) static md_status_t em_fit_from_G##N(const em_data_t *a, const em_outlier_t *b, \
    const em_prior_t *c, const em_params_t *d, const em_options_t *f, double *g, em_fit_t *h) \
    { return em_fit_from(a, b, c, d, f, g, h); } \
    __attribute__((noinline)) static md_status_t evidence_G##N(const em_data_t *a, const em_outlier_t *b, \
    const em_params_t *d, em_evidence_work_t *f) \
    { return em_evidence_data(a, b, d, f); }
PG(1) PG(2) PG(3) PG(4)
static md_status_t em_fit_by_g(const em_data_t *a, const em_outlier_t *b, const em_prior_t *c, const uint8_t *d,
    size_t e, const em_options_t *f, double *g, em_fit_t *h)
{
    return (e == 1u) ? em_fit_G1(a, b, c, d, e, f, g, h) : (e == 2u) ? em_fit_G2(a, b, c, d, e, f, g, h)
         : (e == 3u) ? em_fit_G3(a, b, c, d, e, f, g, h) : em_fit_G4(a, b, c, d, e, f, g, h);
}
static md_status_t em_fit_from_by_g(const em_data_t *a, const em_outlier_t *b, const em_prior_t *c,
    const em_params_t *d, const em_options_t *f, double *g, em_fit_t *h)
{
    return (d->g == 1u) ? em_fit_from_G1(a, b, c, d, f, g, h) : (d->g == 2u) ? em_fit_from_G2(a, b, c, d, f, g, h)
         : (d->g == 3u) ? em_fit_from_G3(a, b, c, d, f, g, h) : em_fit_from_G4(a, b, c, d, f, g, h);
}
static md_status_t evidence_by_g(const em_data_t *a, const em_outlier_t *b, const em_params_t *d,
    em_evidence_work_t *f)
{
    return (d->g == 1u) ? evidence_G1(a, b, d, f) : (d->g == 2u) ? evidence_G2(a, b, d, f)
         : (d->g == 3u) ? evidence_G3(a, b, d, f) : evidence_G4(a, b, d, f);
}
'''
anchor = 'static size_t mhtc_warm_donor('
assert anchor in s
s = s.replace(anchor, wr + anchor, 1)
for old, new in (('fs = em_fit_from(data,', 'fs = em_fit_from_by_g(data,'),
                 ('fs = em_fit(data,', 'fs = em_fit_by_g(data,'),
                 ('(em_evidence_data(data, &ws->cl.outlier', '(evidence_by_g(data, &ws->cl.outlier')):
    assert old in s, old
    s = s.replace(old, new)
open(p, 'w').write(s)
PY
# the copy lives in the build tree, away from the vendored Unity beside this checkout
# (cmake/md_unity.cmake): hand the configure step the checkout's copy when there is one
unity=()
vendor="$PWD/../shared/vendor/Unity-2.6.1" # the working directory is the checkout (above)
if [ -f "$vendor/src/unity.c" ]; then
    unity=(-DFETCHCONTENT_SOURCE_DIR_UNITY="$(cd "$vendor" && pwd)")
fi
(cd "$work/src" && cmake -S . -B "$work/build" -G Ninja -DCMAKE_BUILD_TYPE=Release "${unity[@]}" \
    -DCMAKE_C_FLAGS_RELEASE="-O2 -DNDEBUG -Wno-error -fno-ipa-icf" >/dev/null &&
    cmake --build "$work/build" -j2 --target md-bench >/dev/null)
valgrind --tool=callgrind --collect-atstart=no --compress-strings=no --callgrind-out-file="$work/cg" \
    "$work/build/bin/md-bench" --callgrind >"$work/stdout.txt" 2>"$work/stderr.txt"
f=$(grep -l "stage:mhtc" "$work"/cg.*)
echo "mhtc stage of $rev: $(sed -n 's/^summary: *\([0-9]*\).*/\1/p' "$f") Ir (host callgrind, inclusive per function)"
callgrind_annotate --inclusive=yes --threshold=100 "$f" 2>/dev/null |
    grep -E "em_fit_G|em_fit_from_G|evidence_G|em_evidence_finish|em_seed_from_targets|mhtc_commit|kf_update|mhtc_associate|murty_best|mhtc_predict_pool|em_outlier_tabulate|em_labels|mhtc_update \[" |
    sed -e 's/\.constprop\.[0-9]*//' -e 's/ \[.*//' -e 's/???://'
