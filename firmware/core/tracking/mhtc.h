/// @file mhtc.h
/// Multiple hypothesis tracking of clusters (thesis ch. 4) for one electrode,
/// plus three single-hypothesis baselines behind the same interface.
///
/// One call of mhtc_update() processes one recording interval T_k (§4.2.3):
///  1. predict every track of every parent hypothesis (kalman.h, eq. 4.7-4.9,
///     S_j of eq. 4.13 with the track's last R_j = Σ_j/n_j mapped into B^k);
///  2. per parent, model classes G = 1..g_max pruned by P3 > β (eq. 4.11, 4.32);
///  3-6. MAP-EM of each surviving model under the parent's mean prior
///     (eq. 4.12-4.14), seeds from the predicted targets, Laplace (or BIC) evidence P4;
///  7. A* = -log A (eq. 4.25) and the L best assignments by murty_best();
///  8. eq. 4.30 (normalised over the L best of the same model, Remark 4.3) ×
///     P3 × P4 × P5; the best L children survive, duplicates pruned (§4.4.1);
///  9. Kalman update of detected tracks (eq. 4.15-4.17), new tracks started,
///     tracks with K_miss consecutive misses deleted, P_d from the firing rate.
///
/// Memory (why it scales): hypotheses do not own tracks. A track record lives
/// once in a per-electrode pool and hypotheses hold indices with reference
/// counts; a record is copied only when an interval changes it (copy on
/// write), and children that make the same change (same parent record, same
/// model, same cluster) share the copy. The new generation is staged in the
/// shared workspace and then replaces the old one. If the pool cannot hold the
/// generation, the least probable surviving hypotheses are dropped until it
/// can (counted in mhtc_stats_t.pool_drops).
///
/// Baselines (mhtc_tracker_t): the same track records and Kalman filter, one
/// hypothesis, the best-evidence model of cluster.h, and:
/// - MAP-NN: MAP clusters, each cluster to argmax_j ζ_gj (j = 0: new track),
///   greedily in decreasing ζ so a track takes at most one cluster (§3.4);
/// - ML-NN: ML clusters (HAC seeds, BIC), nearest predicted track within
///   nn_gate_sigma standard deviations (squared Mahalanobis under S_j),
///   greedily by distance (§3.5 footnote 12);
/// - GNN: MAP clusters, one lap_solve on A* with pairs outside the gate
///   (squared Mahalanobis > gnn_gate_chi2) forbidden.
/// The NN baselines keep tracks only K_miss = nn_k_miss intervals (thesis
/// ch. 3: the prior of T_k is the clusters of T_{k-1}, so 1 by default).
///
/// No heap, no recursion, every loop bounded by the capacities below.
#ifndef MHTC_H
#define MHTC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "cluster/cluster.h"
#include "md_status.h"
#include "features/pca.h"
#include "md_config.h"
#include "tracking/kalman.h"
#include "tracking/mhtc_prob.h"
#include "tracking/murty.h"

#define MHTC_L_MAX MD_L_MAX                        ///< global hypotheses kept
#define MHTC_TARGETS_MAX MD_MAX_TARGETS            ///< tracks in one hypothesis
#define MHTC_POOL MD_TRACK_POOL                    ///< track records per electrode
#define MHTC_G_MAX MD_G_MAX                        ///< clusters per model
#define MHTC_HIST_MAX 8u                           ///< intervals of assignment/rank history (≥ K_miss)
#define MHTC_MODELS_MAX (MHTC_L_MAX * MHTC_G_MAX)  ///< model hypotheses of one interval
#ifndef MHTC_SHARE_JEFFREYS_DEFAULT
#define MHTC_SHARE_JEFFREYS_DEFAULT 0.01  ///< default of mhtc_config_t.share_jeffreys (docs/mhtc.md)
#endif
#ifndef MHTC_Q_MOVE_PER_UM_DEFAULT
#define MHTC_Q_MOVE_PER_UM_DEFAULT 0.02  ///< default of mhtc_config_t.q_move_per_um (docs/mhtc.md)
#endif
#ifndef MHTC_N_SCAN_DEFAULT
#define MHTC_N_SCAN_DEFAULT 3u  ///< default of mhtc_config_t.n_scan (docs/mhtc.md)
#endif
#ifndef MHTC_LAMBDA_FIRST_DEFAULT
#define MHTC_LAMBDA_FIRST_DEFAULT 0.03  ///< default of mhtc_config_t.lambda_first (docs/mhtc.md)
#endif
#ifndef MHTC_MISSED_SPREAD
/// One-mode test of a missed track and a track new in this interval: the missed one is spread by
/// its predicted state (docs/mhtc.md); 0 = its cluster alone.
#define MHTC_MISSED_SPREAD 1
#endif
#ifndef MHTC_COUNT_MEDIAN
/// The spike-count term's reference m_j is the median of the track's last three detected counts
/// (mhtc_count_reference, docs/mhtc.md); 0 = its last count alone.
#define MHTC_COUNT_MEDIAN 1
#endif
#ifndef MHTC_COUNT_SIGMA_DEFAULT
#define MHTC_COUNT_SIGMA_DEFAULT 0.5  ///< default of mhtc_config_t.count_sigma (docs/mhtc.md)
#endif
#ifndef MHTC_UNIMODAL_RATIO_DEFAULT
#define MHTC_UNIMODAL_RATIO_DEFAULT 0.9  ///< default of mhtc_config_t.unimodal_ratio (docs/mhtc.md)
#endif
#ifndef MHTC_WARM_JEFFREYS_DEFAULT
#define MHTC_WARM_JEFFREYS_DEFAULT HUGE_VAL  ///< default of mhtc_config_t.warm_jeffreys (docs/mhtc.md)
#endif
#define MHTC_SHARE_PD 0.05  ///< largest |ΔP_d| of a shared target (enters ω_j, eq. 3.9)
#define MHTC_ID_FALSE (-1)  ///< "false cluster" in assignment lists and labels
/// Q = q·I default for waveforms in µV: (10 µV)² per sample and interval, calibrated on
/// held-out simulator seeds (docs/tracking-eval.md). Also the default new-track variance.
#define MHTC_Q_DEFAULT_UV2 100.0

_Static_assert(MHTC_POOL >= MHTC_TARGETS_MAX, "one hypothesis must fit in the pool");
_Static_assert(MHTC_POOL <= 255u, "pool indices are uint8_t");
_Static_assert(MHTC_TARGETS_MAX <= MHTC_PROB_NT_MAX, "A must hold every target");
_Static_assert(MHTC_MODELS_MAX <= 255u, "model slots are uint8_t");
_Static_assert(MHTC_HIST_MAX <= 16u, "history is shifted, keep it short");

typedef enum {
    MHTC_TRACKER_MHTC = 0,  ///< the full multiple hypothesis tracker
    MHTC_TRACKER_MAP_NN,    ///< MAP clusters + argmax ζ
    MHTC_TRACKER_ML_NN,     ///< ML clusters + nearest neighbour within 2 σ
    MHTC_TRACKER_GNN        ///< MAP clusters + gated global nearest neighbour
} mhtc_tracker_t;

/// Parameters (Table 4.1 defaults from mhtc_config_default; all settable).
typedef struct {
    mhtc_tracker_t tracker;
    size_t L;                     ///< hypotheses kept, 1..MHTC_L_MAX (8)
    size_t g_max;                 ///< largest model, 1..MHTC_G_MAX (4)
    double lambda_new;            ///< λν (0.01)
    double lambda_false;          ///< λφ (0.015)
    double lambda_first;          ///< λν of the first interval, where every neuron present is seen for the
                                  ///< first time (MHTC_LAMBDA_FIRST_DEFAULT; = lambda_new: no exception)
    mhtc_pd_rule_t pd;            ///< P_d,max 0.98, P_d,min 0.75, a 0.6, b 4
    double beta;                  ///< model-class pruning threshold on P3 (0.001)
    uint32_t k_miss;              ///< consecutive misses before deletion, 1..MHTC_HIST_MAX (5)
    uint32_t n_scan;              ///< N-scan pruning: the hypotheses of interval k share their ancestor of
                                  ///< interval k − n_scan, the leading one's; 0 = off, 1..MHTC_HIST_MAX − 1
    uint32_t nn_k_miss;           ///< the same for MAP-NN / ML-NN (1)
    double q_process;             ///< Q = q·I, waveform units² per interval (> 0)
    double init_var;              ///< variance of unmeasured waveform directions of a new track (> 0)
    double q_move_per_um;         ///< electrode travel adds (κ·travel)²·x̂x̂ᵀ to Q: an uncertain gain of the
                                  ///< whole waveform (κ = this, relative amplitude change per µm, 1 σ;
                                  ///< thesis §4.6); 0 = Q independent of travel
    double count_sigma;           ///< spike-count term of a continuation (mhtc_count_term_t): ln-count spread σ;
                                  ///< 0 = eq. 4.25 alone
    cluster_evidence_t evidence;  ///< P4: Laplace (thesis) or BIC
    em_options_t em;              ///< EM iteration bound/tolerance
    double shape_prior_width;     ///< see em_evidence.h
    double nn_gate_sigma;         ///< ML-NN gate in standard deviations (2)
    double gnn_gate_chi2;         ///< GNN gate on the squared Mahalanobis distance (9.21: χ²₂ 99 %)
    double share_jeffreys;        ///< thesis §4.6: a parent whose targets are each within this symmetric KL
                                  ///< divergence (nats) of an earlier parent's (and P_d within
                                  ///< MHTC_SHARE_PD) reuses that parent's EM fits, re-evaluated under its
                                  ///< own prior (ζ, log-posterior, evidence, associations); 0 = exact
                                  ///< sharing only (MHTC_SHARE_JEFFREYS_DEFAULT)
    double unimodal_ratio;        ///< a model class whose clusters include a pair with one mode (ridgeline ratio
                                  ///< ≥ this, em_modes.h) splits one neuron: not a hypothesis; and a missed track
                                  ///< that forms one mode with a detected track of its hypothesis is dropped from
                                  ///< it (a second track of the same neuron); 0 = neither
    double warm_jeffreys;         ///< warm start (docs/mhtc.md): a parent's model class G > J (its tracks) that
                                  ///< is fitted starts EM from the fit of class G of an earlier parent whose
                                  ///< targets each match one of its own within this symmetric KL divergence
                                  ///< (nats), then converges under its own prior; else (or if that fit
                                  ///< fails) from the §3.3.4 seeds. 0 = off, HUGE_VAL = any parent with as
                                  ///< many tracks (MHTC_WARM_JEFFREYS_DEFAULT)
    bool provisional_ids;         ///< the report labels a cluster the leading hypothesis calls false with the new
                                  ///< track ID the most probable other hypothesis of the same model gives it
                                  ///< (the delayed decision's likely outcome, docs/mhtc.md); false = as called
    bool seed_from_others;        ///< a model class G > J fitted without a warm start is seeded from the
                                  ///< targets of the most probable other parent with G tracks, when there
                                  ///< is one (docs/mhtc.md); false = the §3.3.4 split of its own targets
} mhtc_config_t;

/// One track record (shared by every hypothesis that references it).
typedef struct {
    kf_state_t kf;                         ///< mean waveform and its covariance
    float sigma_vec[KF_D_MAX][KF_DW_MAX];  ///< last Σ_j in waveform space: Σ s_i u_i u_iᵀ
    double sigma_val[KF_D_MAX];
    double n_last;     ///< spikes n_j of the last detection
    double n_prev[2];  ///< spikes of the two detections before it, latest first (−1: none yet)
    double p_detect;   ///< P_d,j for the next interval
    double rate_hz;    ///< firing rate in the latest interval (0 if missed)
    uint32_t id;       ///< stable ID, never reused on this electrode
    uint32_t born;     ///< interval of the first detection
    uint16_t refs;     ///< hypotheses referencing this record
    uint8_t misses;    ///< consecutive missed detections
    uint8_t sigma_rank;
    uint8_t cluster;  ///< cluster (1..G) of the latest interval, 0 = missed
} mhtc_track_t;

/// One global hypothesis H_l^{1:k}.
typedef struct {
    double log_prob;        ///< log P(H|Y^{1:k}), normalised over the survivors
    double log_assoc;       ///< log of eq. 4.30's assignment ratio at k
    double log_p3, log_p4;  ///< P3, P4 of the model chosen at k
    uint8_t n_tracks;
    uint8_t track[MHTC_TARGETS_MAX];             ///< pool indices
    uint8_t g;                                   ///< clusters of its model at k
    uint8_t hist_len;                            ///< valid history entries
    uint8_t hist_g[MHTC_HIST_MAX];               ///< G per interval, newest first
    int32_t hist_id[MHTC_HIST_MAX][MHTC_G_MAX];  ///< track ID of each cluster (MHTC_ID_FALSE), newest first
    uint8_t rank_hist[MHTC_HIST_MAX];            ///< rank (1 = leading) of this lineage, newest first
    uint8_t parent;                              ///< index of its parent in the previous generation
    uint8_t model;                               ///< workspace model slot of the latest step
} mhtc_hyp_t;

/// Counters: every failure or forced decision is counted, nothing is silent.
typedef struct {
    uint32_t steps;                ///< intervals processed
    uint32_t update_errors;        ///< mhtc_update calls that returned an error
    uint32_t models_pruned;        ///< model classes with P3 ≤ β (eq. 4.11)
    uint32_t models_failed;        ///< EM/evidence failures of surviving model classes
    uint32_t evidence_fallbacks;   ///< models whose Laplace evidence failed and used BIC/2
    uint32_t empty_intervals;      ///< intervals where no model was usable (all tracks missed)
    uint32_t dup_pruned;           ///< children dropped as duplicates (§4.4.1)
    uint32_t target_overflow;      ///< children dropped: more than MHTC_TARGETS_MAX tracks
    uint32_t pool_drops;           ///< hypotheses dropped because the track pool was full
    uint32_t kf_failures;          ///< Kalman updates rejected (track kept with its prediction)
    uint32_t tracks_deleted;       ///< records retired after K_miss misses
    uint32_t murty_solves;         ///< LAP solves inside Murty (benchmark figure)
    uint32_t models_shared;        ///< model hypotheses copied from a parent with the same track records (no EM)
    uint32_t models_reused;        ///< model hypotheses reusing a similar parent's EM fit (share_jeffreys)
    uint32_t models_oversplit;     ///< fits dropped: two clusters with one mode between them (unimodal_ratio)
    uint32_t nscan_pruned;         ///< hypotheses dropped by N-scan pruning (another ancestor than the leader's)
    uint32_t tracks_merged;        ///< missed tracks dropped from a hypothesis: one mode with a detected track of it
    uint32_t models_warm;          ///< EM fits started from another parent's fit (warm_jeffreys)
    uint32_t models_seeded_other;  ///< split-class fits seeded from another parent's targets
} mhtc_stats_t;

/// Tracker state of one electrode (persistent between intervals).
typedef struct {
    mhtc_config_t cfg;
    mhtc_track_t pool[MHTC_POOL];
    mhtc_hyp_t hyp[MHTC_L_MAX];  ///< sorted, hyp[0] leading
    size_t n_hyp;                ///< 0 before the first interval
    uint32_t next_id;            ///< next track ID (monotonic, starts at 1)
    uint32_t interval;           ///< intervals processed
    size_t d_w;                  ///< waveform length fixed by the first interval
    mhtc_stats_t stats;
} mhtc_state_t;

/// The data of one interval (borrowed).
typedef struct {
    const double *y;     ///< n × d features (pca_project_all)
    size_t n;            ///< spikes, ≤ EM_N_MAX
    const double *wave;  ///< n waveforms, row i at wave[i*stride], d_w samples; or NULL and:
    size_t stride;
    const pca_basis_t *basis;  ///< B^k = H^k, d × d_w
    const double *noise_cov;   ///< Ξ, d × d (qm_noise_feature_cov)
    double duration_s;         ///< interval length for firing rates (> 0)
    const int16_t *wave_i16;   ///< the same waveforms in ADC units (used when wave is NULL): saves
                               ///< the MCU a double copy of every window
    double wave_gain;          ///< waveform units (µV) per ADC unit of wave_i16 (> 0)
    double move_um;            ///< electrode travel since the previous interval, µm (≥ 0; 0 if unknown)
} mhtc_input_t;

/// Sample q of waveform i of an interval, in waveform units, whichever form it came in.
static inline double mhtc_input_wave(const mhtc_input_t *in, size_t i, size_t q)
{
    return (in->wave != NULL) ? in->wave[i * in->stride + q] : in->wave_gain * (double)in->wave_i16[i * in->stride + q];
}

/// A model hypothesis fitted in this interval (workspace, valid until the next step).
typedef struct {
    em_fit_t fit;
    double log_ev;    ///< P4
    double log_p3;    ///< P3
    double log_norm;  ///< log Σ over its L best of Π A (eq. 4.30 denominator)
    size_t n_sol;
    lap_solution_t sol[MHTC_L_MAX];
    uint8_t parent;  ///< parent hypothesis index (0 for the root)
    uint8_t g;
    bool usable;
    uint8_t ev_src;            ///< slot of the model that ran the EM fit evaluated here (itself, or its donor)
    uint8_t labels[EM_N_MAX];  ///< argmax_g z_ig, 0 = outlier
} mhtc_model_t;

/// A child hypothesis under evaluation.
typedef struct {
    double score;  ///< unnormalised log P of eq. 4.30
    double log_assoc;
    uint8_t model;
    uint8_t sol;
    int32_t tag[MHTC_G_MAX];  ///< per cluster: track ID, MHTC_ID_FALSE, or a provisional new-track tag
} mhtc_cand_t;

/// Shared per-interval workspace (one electrode at a time; no state kept).
typedef struct {
    cluster_workspace_t cl;  ///< EM scratch, outlier, prior, seeds, Hessian
    cluster_result_t clr;    ///< baselines' model classes
    mhtc_model_t model[MHTC_MODELS_MAX];
    size_t n_models;
    double pred_mu[MHTC_POOL][EM_D_MAX];            ///< μ̂_j^{k|k-1} per pool record (eq. 4.9)
    double pred_s[MHTC_POOL][EM_D_MAX * EM_D_MAX];  ///< S_j (eq. 4.13)
    double pred_c[MHTC_POOL][EM_D_MAX * EM_D_MAX];  ///< Σ_j mapped into B^k (seeding)
    em_target_t targets[EM_J_MAX];
    double n_expect[EM_J_MAX];      ///< per target, its spikes at its last detection (count term)
    double count_spread[EM_J_MAX];  ///< per target, the count term's σ in units of cfg.count_sigma
    mhtc_count_term_t count;        ///< the count term of the model being associated
    double cost[LAP_MAX_ROWS * LAP_MAX_COLS];
    murty_workspace_t murty;
    mhtc_cand_t cand[MHTC_L_MAX];
    size_t n_cand;
    mhtc_track_t staged[MHTC_POOL];   ///< the next generation of records
    int16_t staged_src[MHTC_POOL];    ///< key: source record (-1 new)
    int16_t staged_model[MHTC_POOL];  ///< key: model slot (-1 missed)
    uint8_t staged_g[MHTC_POOL];      ///< key: cluster 1..G (0 missed)
    size_t n_staged;
    mhtc_hyp_t next[MHTC_L_MAX];
    kf_work_t kf;
    double wsum[KF_DW_MAX];
    em_params_t one_mode[MHTC_G_MAX];            ///< per class G: the interval's latest fit dropped as one mode,
    uint8_t one_mode_parent[MHTC_G_MAX];         ///< its parent, and
    bool one_mode_ok[MHTC_G_MAX];                ///< whether there is one: a warm start for the same class of a
                                                 ///< later parent (dropped fits are no models, so no donors)
    int key_src[MHTC_TARGETS_MAX + MHTC_G_MAX];  ///< record keys of the candidate being staged (step 9)
    int key_model[MHTC_TARGETS_MAX + MHTC_G_MAX];
    uint8_t key_g[MHTC_TARGETS_MAX + MHTC_G_MAX];
    double pair_mean[2][EM_D_MAX];            ///< two records seen through B^k (one-mode test of a track pair):
    double pair_cov[2][EM_D_MAX * EM_D_MAX];  ///< here, not on the stack of step 9's deepest path
    uint8_t parent_first[MHTC_L_MAX];         ///< per parent of the interval: its first model slot,
    uint8_t parent_count[MHTC_L_MAX];         ///< its model count,
    uint8_t parent_pruned[MHTC_L_MAX];        ///< its classes pruned by eq. 4.11 and
    uint8_t parent_failed[MHTC_L_MAX];        ///< failed (steps 3-6; here, not on mhtc_update's frame, which
    bool parent_fitted[MHTC_L_MAX];           ///< lies on the firmware's deepest path), whether its own fits
} mhtc_workspace_t;

/// Per-track report of the leading hypothesis.
typedef struct {
    uint32_t id;
    uint8_t cluster;  ///< 1..G in this interval's model, 0 = missed
    uint8_t misses;
    double p_detect;
    double rate_hz;
    double mean_feat[EM_D_MAX];  ///< posterior mean waveform projected on B^k
} mhtc_track_report_t;

/// Outcome of one interval (the leading hypothesis, plus every survivor's rank/probability).
typedef struct {
    size_t n_hyp;
    double hyp_prob[MHTC_L_MAX];                       ///< P(H_l|Y^{1:k}) of each survivor, descending
    uint8_t hyp_rank_hist[MHTC_L_MAX][MHTC_HIST_MAX];  ///< each survivor's lineage ranks, newest first
    uint8_t hyp_hist_len;
    size_t g;            ///< clusters of the leading hypothesis' model
    em_params_t params;  ///< its Θ̂ (mean, shape, λ, π)
    double n_soft[EM_G_MAX + 1u];
    int32_t cluster_track[MHTC_G_MAX];  ///< track ID per cluster, MHTC_ID_FALSE = false cluster
    uint8_t labels[EM_N_MAX];           ///< cluster per spike (0 = outlier)
    size_t n_tracks;
    mhtc_track_report_t track[MHTC_TARGETS_MAX];
    double log_p3, log_p4, log_assoc;
    size_t models_fitted;  ///< model hypotheses clustered this interval
} mhtc_result_t;

/// Table 4.1 defaults for `tracker`; q_process and init_var default to
/// MHTC_Q_DEFAULT_UV2 (waveforms in µV; rescale for other units).
void mhtc_config_default(mhtc_config_t *cfg, mhtc_tracker_t tracker);

/// MD_OK if every field is in range (see mhtc_config_t), else MD_E_ARG.
md_status_t mhtc_config_check(const mhtc_config_t *cfg);

/// Resets st (no hypotheses, IDs from 1) with a copy of cfg. MD_E_ARG on a bad cfg.
md_status_t mhtc_init(mhtc_state_t *st, const mhtc_config_t *cfg);

/// Processes one interval (steps 1-9 above, or the configured baseline) and
/// fills out with the leading hypothesis. On an error nothing in st changes
/// except stats.update_errors. n = 0 or too few spikes for any model is not an
/// error: every track is missed. MD_E_ARG on bad input (d, d_w mismatch with
/// earlier intervals, NULLs, non-finite values). Worst case
/// O(L · g_max · EM + L² g_max · Murty); ws is the shared workspace.
md_status_t mhtc_update(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws, mhtc_result_t *out);

/// Spike labels and cluster→track IDs of surviving hypothesis h (0 = leading)
/// as of the latest successful mhtc_update with this ws (valid until the next
/// step). labels: n values (the step's n), 0 = outlier; cluster_track:
/// MHTC_G_MAX values, MHTC_ID_FALSE for false clusters; *g: clusters of its
/// model. Lets an offline caller relabel intervals by the final best lineage
/// (follow mhtc_hyp_t.parent back). MD_E_ARG if h or n is out of range.
md_status_t mhtc_hyp_labels(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t h, size_t n, uint8_t *labels,
                            int32_t *cluster_track, size_t *g);

/// Short name of a tracker ("mhtc", "map-nn", "ml-nn", "gnn").
const char *mhtc_tracker_name(mhtc_tracker_t tracker);

/// Parses a name of mhtc_tracker_name(); MD_E_ARG if unknown.
md_status_t mhtc_tracker_parse(const char *name, mhtc_tracker_t *tracker);

#endif
