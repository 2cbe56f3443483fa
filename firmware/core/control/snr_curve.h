/// @file snr_curve.h
/// The isolation control loop's SNR-curve optimiser (thesis §2.2.3), one curve
/// per tracked neuron.
///
/// A curve collects (depth_um, snr) observations of ONE neuron (one MHTC
/// track), one per recording interval, in a bounded history. From them it
/// keeps:
/// - a posterior over the model order m = 1..m_max of the regression
///   M(u) = Σ_{i=1..m} b_i u^(i-1) (eq. 2.2), with the coefficients and the
///   noise variance marginalised analytically (conjugate normal–inverse-gamma
///   prior, see docs/snr-curve.md), recursively: the posterior of one
///   observation is the prior of the next, uniform when the curve first holds
///   k0 observations;
/// - the least-squares coefficients of the most probable order m*;
/// - the stochastic Newton step u_{k+1} = u_k + C |H_k|^-1 ξ_k (eq. 2.1) with
///   ξ = M'(u_k), H = M''(u_k), capped at Δmax; converged when the uncapped
///   step is below ε; m* = 2 → Δmax along the sign of the slope (H = 0);
///   m* = 1 → Δsample in the caller's search direction.
///
/// Beyond the thesis (its §6.2): an sc_table_t keeps one curve per track ID,
/// SC_TABLE_SLOTS of them per electrode, evicting the least recently observed.
///
/// Depth convention: depth_um grows as the electrode advances; a positive step
/// advances, a negative one retracts. All state is caller-owned; no heap.
#ifndef SNR_CURVE_H
#define SNR_CURVE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_status.h"

#define SC_M_MAX 4u        ///< highest model order: cubic (m = 4 coefficients)
#define SC_HIST_MAX 32u    ///< observations kept per curve (oldest dropped first)
#define SC_TABLE_SLOTS 4u  ///< curves per electrode, one per tracked neuron

_Static_assert(SC_M_MAX >= 3u && SC_M_MAX <= 5u, "orders 1..m_max with m_max 3..5 (a peak needs m >= 3)");
_Static_assert(SC_HIST_MAX >= 8u && SC_HIST_MAX <= 255u, "history fits a uint8_t count");
_Static_assert(SC_TABLE_SLOTS >= 1u && SC_TABLE_SLOTS <= 16u, "a small fixed table");

/// Tunables of the optimiser; sc_config_default() gives the documented values.
typedef struct {
    uint8_t m_max;          ///< orders considered: 1..m_max (<= SC_M_MAX); default SC_M_MAX
    uint8_t k0;             ///< observations before the first model selection (thesis: 3)
    double gain_c;          ///< C of eq. 2.1 (> 0); default 1 (plain Newton)
    double tol_um;          ///< ε: converged when C|H|^-1|ξ| < ε; default 2.5 µm
    double move_max_um;     ///< Δmax: cap of every step; default 30 µm
    double move_sample_um;  ///< Δsample: the m* = 1 step; default 10 µm
    double depth_scale_um;  ///< L: depth unit of the coefficient prior, x = (u - ū)/L; default 50 µm
    double coef_prior_sd;   ///< τ: prior sd of b_2..b_m in units of the noise sd σ; default 5
    double noise_prior_sd;  ///< σ0: scale of the inverse-gamma prior on σ² (SNR units); default 0.5
    double noise_prior_a0;  ///< a0 (shape) of that prior, = half its pseudo-observations; default 1
    double model_floor;     ///< each order keeps >= floor/m_max of prior mass; default 0.01
} sc_config_t;

/// One curve: bounded history plus the recursive order posterior.
typedef struct {
    double depth_um[SC_HIST_MAX];  ///< ring buffer of observation depths
    double snr[SC_HIST_MAX];       ///< ring buffer of the matching SNR values
    uint8_t head;                  ///< next slot to write
    uint8_t count;                 ///< observations held (<= SC_HIST_MAX)
    bool posterior_valid;          ///< true once k0 observations have been seen
    uint32_t n_total;              ///< observations since the last reset (saturating)
    double post[SC_M_MAX];         ///< P(m | data) for m = 1..m_max (index m-1); uniform before k0
    double log_ev_prev[SC_M_MAX];  ///< log evidence of the previous history (predictive ratio)
    uint32_t errors;               ///< failed updates (numeric); the curve keeps its last good posterior
} sc_curve_t;

/// What the optimiser proposes for the current position.
typedef struct {
    bool ready;          ///< at least k0 observations: model selection ran
    uint8_t m_star;      ///< most probable admissible order (0 when not ready)
    double post_m_star;  ///< its posterior probability
    double xi;           ///< ξ: slope M'(u_k), SNR per µm (0 when m* = 1)
    double h;            ///< H: curvature M''(u_k), SNR per µm² (0 when m* <= 2)
    double newton_um;    ///< signed uncapped step of eq. 2.1 (0 unless m* >= 3)
    double move_um;      ///< signed proposed step, |step| <= Δmax
    bool converged;      ///< m* >= 3 and |newton_um| < ε (then move_um = 0)
    double peak_snr;     ///< fitted M(u_k) at the current position
} sc_suggestion_t;

/// Documented defaults (see the field comments and docs/snr-curve.md).
void sc_config_default(sc_config_t *cfg);

/// MD_OK if every field is in range: 1 <= m_max <= SC_M_MAX, 2 <= k0 <= SC_HIST_MAX,
/// positive finite steps with Δsample <= Δmax, ε > 0, L > 0, τ > 0, σ0 > 0,
/// a0 > 0, 0 <= floor < 1; MD_E_ARG otherwise. O(1).
md_status_t sc_config_check(const sc_config_t *cfg);

/// Empties a curve (history, posterior back to uniform, counters kept). O(SC_HIST_MAX).
void sc_curve_reset(sc_curve_t *curve);

/// Adds the observation (depth_um, snr) and, from k0 observations on, updates
/// the order posterior (eq. 2.2 recursion). The oldest observation is dropped
/// when the history is full. MD_E_ARG for NULL/invalid config or non-finite
/// values (nothing is changed); MD_E_NUMERIC if an evidence could not be
/// computed (observation kept, posterior unchanged, curve->errors counted).
/// O(SC_HIST_MAX · m_max³) — a few thousand flops.
md_status_t sc_curve_observe(sc_curve_t *curve, const sc_config_t *cfg, double depth_um, double snr);

/// Log evidence log p(snr | depths, m) of the curve's current history for
/// orders 1..m_max into log_ev[0..m_max-1], up to one additive constant shared
/// by all orders (the intercept and σ² are marginalised; see docs). Needs >= 2
/// observations (MD_E_DEGENERATE otherwise). O(SC_HIST_MAX · m_max³).
md_status_t sc_curve_log_evidence(const sc_curve_t *curve, const sc_config_t *cfg, double *log_ev);

/// Least-squares coefficients of order m about the centre depth: M(u) =
/// Σ coef[i] ((u - centre_um)/scale_um)^i, i = 0..m-1. MD_E_DEGENERATE if the
/// history has fewer than m distinct depths; MD_E_NUMERIC if the normal
/// equations are singular. O(SC_HIST_MAX · m²  + m³).
md_status_t sc_curve_fit(const sc_curve_t *curve, uint8_t m, double *coef, double *centre_um, double *scale_um);

/// The eq. 2.1 suggestion at depth_um (normally the latest observation's
/// depth). search_dir (+1 advance, -1 retract) orients the m* = 1 step.
/// Not ready (fewer than k0 observations) is MD_OK with out->ready = false and
/// a zero step. m* is the most probable order that the history can identify
/// (at most its number of distinct depths). O(SC_HIST_MAX · m_max²).
md_status_t sc_curve_suggest(const sc_curve_t *curve, const sc_config_t *cfg, double depth_um, int search_dir,
                             sc_suggestion_t *out);

/// One slot of the per-electrode table.
typedef struct {
    bool used;
    uint32_t track_id;    ///< MHTC track ID (stable, never reused)
    uint32_t last_stamp;  ///< table clock at the last observation (for LRU eviction)
    sc_curve_t curve;
} sc_slot_t;

/// Per-electrode table of curves keyed by track ID.
typedef struct {
    sc_slot_t slot[SC_TABLE_SLOTS];
    uint32_t clock;      ///< incremented by every observation
    uint32_t evictions;  ///< curves dropped to make room
    uint32_t errors;     ///< failed observations
} sc_table_t;

/// Empties the table and its counters. O(SC_TABLE_SLOTS · SC_HIST_MAX).
void sc_table_init(sc_table_t *table);

/// Curve of track_id, or NULL if the table has none. O(SC_TABLE_SLOTS).
sc_curve_t *sc_table_find(sc_table_t *table, uint32_t track_id);

/// Adds an observation to track_id's curve. A track without a curve gets a
/// free slot or, when all are used, the slot of the least recently observed
/// track (lowest last_stamp; ties to the lowest slot index), which is reset
/// and counted in `evictions`. *curve_out (may be NULL) receives the curve.
/// Errors as sc_curve_observe (counted in `errors`). O(SC_TABLE_SLOTS + observe).
md_status_t sc_table_observe(sc_table_t *table, const sc_config_t *cfg, uint32_t track_id, double depth_um, double snr,
                             sc_curve_t **curve_out);

/// Restarts track_id's curve (e.g. on Re-Estimate Gradient, when its old
/// observations no longer describe the drifted neuron). MD_E_STATE if the
/// table has no curve for it. O(SC_TABLE_SLOTS + SC_HIST_MAX).
md_status_t sc_table_reset_track(sc_table_t *table, uint32_t track_id);

#endif
