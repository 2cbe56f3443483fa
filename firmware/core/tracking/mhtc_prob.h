/// @file mhtc_prob.h
/// The probability factors of MHTC (thesis §4.3, App. 4.A) that do not need
/// the tracker's state: the model-class prior P3 (eq. 4.32), the data
/// association matrix A and its assignment costs A* = -log A (eq. 4.25-4.28),
/// the normalisation of eq. 4.30 over the L best assignments (Remark 4.3),
/// and the detection-probability rule of §4.4.2.
///
/// Pure functions on caller-owned arrays; no state, no allocation.
#ifndef MHTC_PROB_H
#define MHTC_PROB_H

#include <stdbool.h>
#include <stddef.h>

#include "md_status.h"
#include "md_config.h"
#include "tracking/lap.h"

#define MHTC_PROB_NT_MAX MD_MAX_TARGETS  ///< targets N_t of one parent hypothesis

_Static_assert(MHTC_PROB_NT_MAX + 2u * MD_G_MAX <= LAP_MAX_COLS, "A has N_t + 2 G_m columns");

/// Rule of §4.4.2 for P_d from the firing rate: P_d' = ½(q(r) + P_d),
/// q(r) = pd_max - 1/(a r + b), the result clamped to [pd_min, pd_max].
typedef struct {
    double pd_max;  ///< Table 4.1: 0.98
    double pd_min;  ///< Table 4.1: 0.75
    double a;       ///< 0.6 (per Hz)
    double b;       ///< 4
} mhtc_pd_rule_t;

/// q(r) clamped to [pd_min, pd_max]: the P_d of a target first seen at rate r.
double mhtc_pd_first(const mhtc_pd_rule_t *rule, double rate_hz);

/// P_d^{k+1} = ½(q(r^k) + P_d^k), clamped (§4.4.2). A missed target has r = 0.
double mhtc_pd_next(const mhtc_pd_rule_t *rule, double pd_prev, double rate_hz);

/// log P3 = log P(M_m | parent) of eq. 4.32 for a model with g clusters,
/// given the parent's n_t detection probabilities (Poisson-binomial of N_τ by
/// an O(n_t^2) recursion, Poisson of N_ν + N_φ with λ0 = λν + λφ).
/// MD_E_ARG on bad input (pd outside (0, 1), λ0 ≤ 0, n_t > MHTC_PROB_NT_MAX).
md_status_t mhtc_log_p3(const double *pd, size_t n_t, size_t g, double lambda0, double *log_p3);

/// The count m_j a continuation of a track is compared with (mhtc_count_term_t):
/// the median of its last detected count n_last and the two before it
/// (prev[0] the later; a negative entry is a detection the track has not had),
/// n_last alone while the track has fewer than three. One interval's count is
/// not a neuron's rate: a model that splits the neuron's cluster in two, or a
/// neuron silent for part of the interval, gives a count that the next
/// interval's full cluster would otherwise be judged against.
double mhtc_count_reference(double n_last, const double prev[2]);

/// Assignment costs A* = -log A (eq. 4.25) of one model hypothesis with g
/// clusters and the parent's n_t targets: cost is g × (n_t + 2g), row-major.
/// zeta: row r holds ζ_{r,0..n_t} (eq. 4.26, column 0 the uniform component)
/// with row stride zeta_stride ≥ n_t + 1. Zero entries of A, and the
/// off-diagonal cells of its two diagonal blocks, get LAP_FORBIDDEN.
/// MD_E_ARG on bad sizes, pd outside (0, 1) or λ ≤ 0; MD_E_NUMERIC on NaN ζ.
/// The spike-count term of a continuation (ours, not the thesis'): a neuron
/// fires at about the same rate from one interval to the next, so cluster r
/// continuing target j is weighted by exp(-ln²((n_r + 1) / (m_j + 1)) / (2σ_j²)),
/// n_r the cluster's spike count, m_j the target's (mhtc_count_reference),
/// σ_j = σ·s_j. At most 1: it only penalises a continuation whose count
/// departs from the track's, such as a neuron's few attenuated burst spikes
/// taking over its track. Births and false alarms are not weighted.
typedef struct {
    const double *n_cluster;  ///< g soft counts n_r (cluster r + 1)
    const double *n_expect;   ///< n_t counts m_j (≤ 0: unknown, no term)
    const double *spread;     ///< n_t factors s_j ≥ 1 (NULL: all 1)
    double sigma;             ///< σ, ln-count spread; 0: no term
} mhtc_count_term_t;

/// As above; count NULL (or count->sigma 0) leaves eq. 4.25 unchanged.
md_status_t mhtc_assoc_costs(const double *zeta, size_t zeta_stride, size_t g, const double *pd, size_t n_t,
                             double lambda_new, double lambda_false, const mhtc_count_term_t *count, double *cost);

/// log Σ_l exp(-cost_l) over n costs (the denominator of eq. 4.30 restricted
/// to the L best, Remark 4.3). n ≥ 1.
double mhtc_log_norm(const double *cost, size_t n);

#endif
