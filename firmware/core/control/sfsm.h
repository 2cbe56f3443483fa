/// @file sfsm.h
/// Supervisory finite state machine (SFSM) of one electrode (thesis §2.2.4,
/// Table 2.1), table-driven.
///
/// Once per recording interval the caller passes what the signal chain, the
/// tracker and the SNR-curve optimiser (snr_curve.h) found; the SFSM picks the
/// next state from a const transition table (sfsm_table(): from-states,
/// condition, WAIT rule, to-state, action; the first row that fires wins) and
/// returns the requested depth step (signed µm, |step| <= Δmax, zero in states
/// that must not move) with a reason. The depth servo executes it.
///
/// The table IS the specification: docs/sfsm.md prints it and
/// tests/unit/test_sfsm_doc.c checks the doc against it.
///
/// Depth convention: depth grows as the electrode advances; +step advances,
/// -step retracts. IQM is the isolation distance ID_g of §2.2.2.4 (Mahalanobis
/// units, NOT squared: qm_isolation_t.id).
#ifndef SFSM_H
#define SFSM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "control/snr_curve.h"

#define SFSM_R_MAX 8u      ///< largest WAIT length R
#define SFSM_ROWS_MAX 32u  ///< capacity of the per-row WAIT counters
/// Leash turns per anchor: out to one side, back through the anchor to the
/// other, then on in the first direction into tissue not yet searched.
#define SFSM_LEASH_TURNS 2u

/// States; the first six are the thesis' (Fig. 2.3), the last two ours.
typedef enum {
    SFSM_SPIKE_SEARCH = 0,
    SFSM_GRADIENT_SEARCH,
    SFSM_ISOLATE_NEURON,
    SFSM_NEURON_ISOLATED,
    SFSM_REESTIMATE_GRADIENT,
    SFSM_REISOLATE_NEURON,
    SFSM_WINDOW_LIMIT,  ///< stopped at the depth window, waits for the operator
    SFSM_HALTED,        ///< e-stop / fault / invalid input: never moves until resumed
    SFSM_STATE_COUNT
} sfsm_state_t;

/// Conditions a table row can test (evaluated once per cycle).
typedef enum {
    SFSM_C_HALT = 0,            ///< e-stop or fault flag, or invalid input
    SFSM_C_RESUME,              ///< operator resume, no e-stop/fault, valid input
    SFSM_C_OMEGA3,              ///< dominant track with IQM >= γ3 (Table 2.1 Ω3) or SNR >= snr_isolate (ours)
    SFSM_C_OMEGA3_OTHER,        ///< Ω3 on a louder track than the isolated one (SNR > reference)
    SFSM_C_LIMIT_ISOLATED,      ///< at the window edge, IQM >= γ2
    SFSM_C_LIMIT_FIRST,         ///< at the window edge, no reversal yet
    SFSM_C_LIMIT_AGAIN,         ///< at the window edge after a reversal
    SFSM_C_AT_LIMIT,            ///< the state's step points out of the window at its edge
    SFSM_C_NO_DOMINANT,         ///< no dominant track this cycle
    SFSM_C_SPIKES_SEEN,         ///< spikes above the minimum rate and a dominant track
    SFSM_C_CURVE_VIABLE,        ///< curve ready, m* >= 2, IQM >= γ1
    SFSM_C_CURVE_NOT_READY,     ///< the dominant track's curve has < k0 observations
    SFSM_C_CONVERGED_ISOLATED,  ///< eq. 2.1 converged and IQM >= γ2
    SFSM_C_IQM_LOW,             ///< IQM < γ1 (Ω0)
    SFSM_C_SNR_DROP,            ///< dominant SNR (any track) < drop fraction × the isolation SNR
    SFSM_C_SNR_RESTORED,        ///< dominant SNR (any track) >= the isolation SNR
    SFSM_C_OTHER_DOMINANT,      ///< the dominant track is not the isolated one
    SFSM_C_SNR_FALLING,         ///< dominant SNR < drop fraction × the best SNR of this Gradient Search
    SFSM_C_LEASH,               ///< Spike Search is search_span_um past the last depth with a dominant track
    SFSM_COND_COUNT
} sfsm_cond_t;

/// How long a row's condition must hold before it fires.
typedef enum {
    SFSM_W_NONE = 0,  ///< the first cycle
    SFSM_W_R,         ///< R consecutive cycles (thesis "WAIT")
    SFSM_W_LOST       ///< lost_cycles consecutive cycles
} sfsm_wait_t;

/// Transition actions (state entry actions are per state, see sfsm_state_info).
typedef enum {
    SFSM_A_NONE = 0,
    SFSM_A_RESTART,  ///< search direction back to the initial one, reversal count 0
    SFSM_A_REVERSE,  ///< reverse the search direction, count the reversal
    SFSM_A_DECLARE,  ///< isolation reference := dominant track, its recent mean SNR here, depth
    SFSM_A_RESTORE,  ///< keep the original isolation reference
    SFSM_A_ADOPT,    ///< reference track := dominant track; reference SNR and depth kept
    SFSM_A_TURN,     ///< reverse the search direction (not a window-edge reversal), best SNR := now
    SFSM_A_LEASH,    ///< reverse the search direction, count the leash turn
    SFSM_ACTION_COUNT
} sfsm_action_t;

/// Why this cycle's step is what it is.
typedef enum {
    SFSM_R_HALTED = 0,
    SFSM_R_BAD_INPUT,
    SFSM_R_WINDOW_HOLD,
    SFSM_R_ISOLATED_HOLD,
    SFSM_R_SEARCH,          ///< ±Δsearch
    SFSM_R_SAMPLE,          ///< ±Δsample
    SFSM_R_NEWTON,          ///< eq. 2.1 (m* >= 3)
    SFSM_R_LINE,            ///< ±Δmax along the slope (m* = 2)
    SFSM_R_FLAT,            ///< Δsample in the search direction (m* = 1)
    SFSM_R_CONVERGED_HOLD,  ///< eq. 2.1 converged, waiting for the isolation conditions
    SFSM_R_LOW_IQM_HOLD,    ///< Ω0: the gradient is not followed
    SFSM_R_NO_DOMINANT_HOLD,
    SFSM_R_RETRACT,        ///< -Δresample
    SFSM_R_APPROACH,       ///< Neuron Isolated, settled tissue: approach_um towards the neuron
    SFSM_R_APPROACH_BACK,  ///< the last approach step lowered the SNR: back to where it was
    SFSM_REASON_COUNT
} sfsm_reason_t;

/// One row of the transition table.
typedef struct {
    uint16_t from_mask;  ///< bit s set: the row applies in state s
    sfsm_cond_t cond;
    sfsm_wait_t wait;
    sfsm_state_t to;
    sfsm_action_t action;
} sfsm_row_t;

/// Documentation of one state (for docs/sfsm.md).
typedef struct {
    const char *name;    ///< "Spike Search", ...
    const char *mode;    ///< thesis mode: Isolate, Isolated, Re-Isolate, or ours
    const char *motion;  ///< step policy per cycle
    const char *entry;   ///< entry action
} sfsm_state_info_t;

/// Tunables; sfsm_config_default() gives the documented values.
typedef struct {
    double move_search_um;    ///< Δsearch (thesis ~20 µm)
    double move_sample_um;    ///< Δsample (thesis ~10 µm)
    double move_resample_um;  ///< Δresample, retracting (thesis ~5 µm)
    double move_max_um;       ///< Δmax: no step ever exceeds it (default 30 µm)
    double gamma1;            ///< γ1: IQM to follow the gradient (default 2)
    double gamma2;            ///< γ2: IQM to declare isolation at the peak (default 3)
    double gamma3;            ///< γ3: IQM to declare isolation at once (default 12)
    double snr_isolate;       ///< dominant SNR that declares isolation at once, whatever the IQM (default 24, ours)
    double snr_drop_frac;     ///< leave Neuron Isolated below this × isolation SNR (thesis 0.85)
    double snr_min;           ///< a track below this SNR is noise floor, never dominant (default 9, ours)
    uint8_t wait_r;           ///< R of WAIT transitions (default 3)
    uint8_t lost_cycles;      ///< cycles without a dominant track before Spike Search (default 5)
    double search_span_um;  ///< Spike Search turns this far past the last dominant track (default 100, 0: never; ours)
    int8_t initial_dir;     ///< first search direction: +1 advance (default), -1 retract
    double approach_um;     ///< settled approach step in Neuron Isolated (0: hold, as the thesis; ours)
    double approach_gain;   ///< relative SNR rise over one approach step that earns the next
} sfsm_config_t;

/// Inputs of one cycle.
typedef struct {
    bool has_dominant;           ///< a dominant track exists this interval (the SFSM
                                 ///< ignores it while snr < cfg.snr_min: noise floor)
    uint32_t dominant_track;     ///< its MHTC track ID
    double snr;                  ///< its SNR (finite when has_dominant)
    double iqm;                  ///< its isolation distance ID_g (finite when has_dominant)
    bool spikes_seen;            ///< detections above the minimum firing rate
    double depth_um;             ///< current depth
    double depth_min_um;         ///< window, shallow end (< depth_max_um)
    double depth_max_um;         ///< window, deep end
    bool estop;                  ///< e-stop latched
    bool fault;                  ///< any fault the application reports
    bool resume;                 ///< operator's resume request (HALTED / WINDOW_LIMIT)
    sc_suggestion_t suggestion;  ///< sc_curve_suggest() of the dominant track's curve at depth_um
    bool settled;                ///< the tissue has settled (approach_guard.h ag_settled): the settled
                                 ///< approach may step
} sfsm_input_t;

/// Result of one cycle.
typedef struct {
    sfsm_state_t state;  ///< state after this cycle
    sfsm_state_t from;   ///< state before it
    int16_t row;         ///< index of the row that fired, -1 if none
    double move_um;      ///< requested step, |move_um| <= Δmax, 0 in non-moving states
    sfsm_reason_t reason;
    bool clamped;      ///< the step was shortened to stay inside the depth window
    bool reset_curve;  ///< caller: sc_table_reset_track(reset_track) (Re-Estimate entry)
    uint32_t reset_track;
} sfsm_output_t;

/// The machine; caller-owned, initialise with sfsm_init().
typedef struct {
    sfsm_config_t cfg;
    sfsm_state_t state;
    int8_t search_dir;  ///< +1 / -1
    uint8_t reversals;  ///< window-edge reversals since the last progress
    bool has_ref;       ///< isolation reference held (only in the isolated modes)
    uint32_t ref_track;
    double ref_snr;  ///< SNR at isolation (mean over the last R cycles)
    double ref_depth_um;
    uint8_t wait[SFSM_ROWS_MAX];    ///< consecutive-cycle counters, one per table row
    double recent_snr[SFSM_R_MAX];  ///< last SNRs of recent_track, all at recent_depth_um
    double recent_iqm[SFSM_R_MAX];  ///< its IQMs of the same cycles
    uint8_t recent_n;
    uint8_t recent_head;
    uint32_t recent_track;
    double recent_depth_um;  ///< depth of those SNRs (a move restarts the window)
    uint32_t cycles;
    uint32_t transitions;
    uint32_t bad_inputs;       ///< cycles rejected by input validation
    double seek_best_snr;      ///< best dominant SNR since Gradient Search was entered / turned
    bool has_anchor;           ///< a dominant track has been seen
    double anchor_um;          ///< depth where a dominant track was last seen
    uint8_t leash_turns;       ///< leash turns since the anchor was set (at most SFSM_LEASH_TURNS)
    int8_t approach_dir;       ///< settled approach: direction of the search that found the neuron
    bool approach_done;        ///< settled approach ended for this isolation
    bool approach_has_last;    ///< an approach step was taken from approach_last_um
    double approach_last_um;   ///< depth the last approach step started from
    double approach_last_snr;  ///< the neuron's mean SNR there
    uint32_t approach_steps;   ///< settled approach steps taken (advances and steps back)
} sfsm_t;

/// Documented defaults.
void sfsm_config_default(sfsm_config_t *cfg);

/// MD_OK if 0 < steps <= Δmax (finite), 0 < γ1 < γ2 < γ3, 0 < drop < 1,
/// snr_min >= 0 (finite), 1 <= R <= SFSM_R_MAX, lost_cycles >= 1, search_span_um >= 0 (finite),
/// initial_dir = ±1, 0 <= approach_um <= Δmax, approach_gain >= 0 (finite); else MD_E_ARG.
md_status_t sfsm_config_check(const sfsm_config_t *cfg);

/// Starts in Spike Search. MD_E_ARG on NULL or an invalid config. O(1).
md_status_t sfsm_init(sfsm_t *sm, const sfsm_config_t *cfg);

/// One cycle. Invalid input (non-finite depth/window, min >= max, non-finite
/// SNR/IQM with a dominant track, non-finite suggestion) counts in bad_inputs,
/// drives the machine to HALTED (zero step) and returns MD_E_ARG. NULL
/// arguments: MD_E_ARG, nothing changed. O(table rows).
md_status_t sfsm_decide(sfsm_t *sm, const sfsm_input_t *in, sfsm_output_t *out);

/// True while Neuron Isolated holds a neuron whose mean IQM over the recent
/// R-cycle window reaches γ3 (isolated by its moat, not by loudness alone).
bool sfsm_holds_lone_neuron(const sfsm_t *sm);

/// The const transition table, in priority order; *n receives its length.
const sfsm_row_t *sfsm_table(size_t *n);

/// Documentation of a state; NULL if out of range.
const sfsm_state_info_t *sfsm_state_info(sfsm_state_t state);

/// Short names / one-line descriptions ("?" if out of range).
const char *sfsm_state_name(sfsm_state_t state);
const char *sfsm_cond_doc(sfsm_cond_t cond);
const char *sfsm_action_doc(sfsm_action_t action);
const char *sfsm_reason_name(sfsm_reason_t reason);

#endif
