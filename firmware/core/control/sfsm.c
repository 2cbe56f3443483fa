/// @file sfsm.c
/// Supervisory finite state machine (thesis §2.2.4, Table 2.1); see sfsm.h
/// and docs/sfsm.md (printed from SFSM_TABLE and SFSM_INFO below).
#include "control/sfsm.h"

#include <math.h>
#include <string.h>

/* A step shortened below this by the depth window counts as blocked. */
#define SFSM_EDGE_UM 0.5
/* SNRs within this depth count as taken at one position (servo tolerance 2 µm). */
#define SFSM_SAME_DEPTH_UM 2.5

#define B(s) ((uint16_t)(1u << (unsigned)(s)))
#define SFSM_ALL ((uint16_t)((1u << (unsigned)SFSM_STATE_COUNT) - 1u))
#define SFSM_RUNNING ((uint16_t)(SFSM_ALL & (uint16_t)~B(SFSM_HALTED)))
/* Isolated and Re-Isolate modes: a reference neuron is held. */
#define SFSM_ISOLATED_MODES \
    ((uint16_t)(B(SFSM_NEURON_ISOLATED) | B(SFSM_REESTIMATE_GRADIENT) | B(SFSM_REISOLATE_NEURON)))
/* Running states without a reference: Ω3 declares a first isolation there. */
#define SFSM_SEEKING ((uint16_t)(SFSM_RUNNING & (uint16_t)~SFSM_ISOLATED_MODES))

/* The transition table, in priority order: each cycle the first row whose
 * from-state matches and whose condition has held for its WAIT length fires.
 * Safety first (halt, Ω3 stop, window edge), then losing the neuron, then the
 * thesis' prototypical path (§2.2.4). */
static const sfsm_row_t SFSM_TABLE[] = {
    {SFSM_RUNNING, SFSM_C_HALT, SFSM_W_NONE, SFSM_HALTED, SFSM_A_NONE},
    {B(SFSM_HALTED) | B(SFSM_WINDOW_LIMIT), SFSM_C_RESUME, SFSM_W_NONE, SFSM_SPIKE_SEARCH, SFSM_A_RESTART},
    {SFSM_SEEKING, SFSM_C_OMEGA3, SFSM_W_NONE, SFSM_NEURON_ISOLATED, SFSM_A_DECLARE},
    {SFSM_ISOLATED_MODES, SFSM_C_OMEGA3_OTHER, SFSM_W_NONE, SFSM_NEURON_ISOLATED, SFSM_A_DECLARE},
    {B(SFSM_ISOLATE_NEURON) | B(SFSM_REISOLATE_NEURON), SFSM_C_LIMIT_ISOLATED, SFSM_W_NONE, SFSM_NEURON_ISOLATED,
     SFSM_A_DECLARE},
    {B(SFSM_SPIKE_SEARCH) | B(SFSM_GRADIENT_SEARCH), SFSM_C_LIMIT_FIRST, SFSM_W_NONE, SFSM_SPIKE_SEARCH,
     SFSM_A_REVERSE},
    {B(SFSM_SPIKE_SEARCH) | B(SFSM_GRADIENT_SEARCH), SFSM_C_LIMIT_AGAIN, SFSM_W_NONE, SFSM_WINDOW_LIMIT, SFSM_A_NONE},
    {B(SFSM_ISOLATE_NEURON) | B(SFSM_REESTIMATE_GRADIENT) | B(SFSM_REISOLATE_NEURON), SFSM_C_AT_LIMIT, SFSM_W_NONE,
     SFSM_WINDOW_LIMIT, SFSM_A_NONE},
    {B(SFSM_GRADIENT_SEARCH) | B(SFSM_ISOLATE_NEURON) | B(SFSM_NEURON_ISOLATED) | B(SFSM_REESTIMATE_GRADIENT) |
         B(SFSM_REISOLATE_NEURON),
     SFSM_C_NO_DOMINANT, SFSM_W_LOST, SFSM_SPIKE_SEARCH, SFSM_A_NONE},
    {B(SFSM_SPIKE_SEARCH), SFSM_C_SPIKES_SEEN, SFSM_W_NONE, SFSM_GRADIENT_SEARCH, SFSM_A_NONE},
    {B(SFSM_GRADIENT_SEARCH), SFSM_C_CURVE_VIABLE, SFSM_W_R, SFSM_ISOLATE_NEURON, SFSM_A_NONE},
    {B(SFSM_ISOLATE_NEURON), SFSM_C_CONVERGED_ISOLATED, SFSM_W_R, SFSM_NEURON_ISOLATED, SFSM_A_DECLARE},
    {B(SFSM_ISOLATE_NEURON), SFSM_C_CURVE_NOT_READY, SFSM_W_NONE, SFSM_GRADIENT_SEARCH, SFSM_A_NONE},
    {B(SFSM_ISOLATE_NEURON), SFSM_C_IQM_LOW, SFSM_W_R, SFSM_GRADIENT_SEARCH, SFSM_A_NONE},
    {B(SFSM_NEURON_ISOLATED), SFSM_C_SNR_DROP, SFSM_W_R, SFSM_REESTIMATE_GRADIENT, SFSM_A_NONE},
    {B(SFSM_NEURON_ISOLATED), SFSM_C_OTHER_DOMINANT, SFSM_W_R, SFSM_NEURON_ISOLATED, SFSM_A_ADOPT},
    {B(SFSM_REESTIMATE_GRADIENT), SFSM_C_OTHER_DOMINANT, SFSM_W_R, SFSM_REESTIMATE_GRADIENT, SFSM_A_ADOPT},
    {B(SFSM_REISOLATE_NEURON), SFSM_C_OTHER_DOMINANT, SFSM_W_R, SFSM_REISOLATE_NEURON, SFSM_A_ADOPT},
    {B(SFSM_REESTIMATE_GRADIENT) | B(SFSM_REISOLATE_NEURON), SFSM_C_SNR_RESTORED, SFSM_W_NONE, SFSM_NEURON_ISOLATED,
     SFSM_A_RESTORE},
    {B(SFSM_REESTIMATE_GRADIENT), SFSM_C_CURVE_VIABLE, SFSM_W_NONE, SFSM_REISOLATE_NEURON, SFSM_A_NONE},
    {B(SFSM_REISOLATE_NEURON), SFSM_C_CONVERGED_ISOLATED, SFSM_W_R, SFSM_NEURON_ISOLATED, SFSM_A_DECLARE},
    {B(SFSM_REISOLATE_NEURON), SFSM_C_CURVE_NOT_READY, SFSM_W_NONE, SFSM_REESTIMATE_GRADIENT, SFSM_A_NONE},
    {B(SFSM_REISOLATE_NEURON), SFSM_C_IQM_LOW, SFSM_W_R, SFSM_REESTIMATE_GRADIENT, SFSM_A_NONE},
    {B(SFSM_GRADIENT_SEARCH), SFSM_C_SNR_FALLING, SFSM_W_R, SFSM_GRADIENT_SEARCH, SFSM_A_TURN},
    {B(SFSM_SPIKE_SEARCH), SFSM_C_LEASH, SFSM_W_NONE, SFSM_SPIKE_SEARCH, SFSM_A_LEASH},
};

#define SFSM_ROWS (sizeof SFSM_TABLE / sizeof SFSM_TABLE[0])
_Static_assert(SFSM_ROWS <= SFSM_ROWS_MAX, "one WAIT counter per row");
_Static_assert(SFSM_STATE_COUNT <= 16u, "from_mask is 16 bits");

static const sfsm_state_info_t SFSM_INFO[SFSM_STATE_COUNT] = {
    [SFSM_SPIKE_SEARCH] = {"Spike Search", "Isolate", "search direction × Δsearch", "drop the isolation reference"},
    [SFSM_GRADIENT_SEARCH] = {"Gradient Search", "Isolate", "search direction × Δsample (hold while no dominant track)",
                              "drop the isolation reference; best SNR := this SNR"},
    [SFSM_ISOLATE_NEURON] = {"Isolate Neuron", "Isolate",
                             "optimiser step (eq. 2.1; m*=2: ±Δmax; m*=1: Δsample); hold if converged, "
                             "if IQM < γ1 or no dominant track",
                             "drop the isolation reference; reversal count := 0"},
    [SFSM_NEURON_ISOLATED] = {"Neuron Isolated", "Isolated",
                              "hold; settled approach (ours): once the tissue has settled, approach_um towards "
                              "the neuron while each step raises its SNR by approach_gain, one step back if "
                              "the last lowered it",
                              "none (the transition's action sets the reference)"},
    [SFSM_REESTIMATE_GRADIENT] = {"Re-Estimate Gradient", "Re-Isolate",
                                  "-Δresample (retract); hold while no dominant track",
                                  "ask the caller to restart the isolated track's SNR curve"},
    [SFSM_REISOLATE_NEURON] = {"Re-Isolate Neuron", "Re-Isolate", "as Isolate Neuron", "none"},
    [SFSM_WINDOW_LIMIT] = {"Window Limit", "ours", "none (hold)", "drop the isolation reference"},
    [SFSM_HALTED] = {"Halted", "ours", "none, ever, until resumed", "drop the isolation reference"},
};

static const char *const SFSM_COND_DOC[SFSM_COND_COUNT] = {
    [SFSM_C_HALT] = "e-stop or fault flag, or invalid input",
    [SFSM_C_RESUME] = "operator resume, no e-stop, no fault, valid input",
    [SFSM_C_OMEGA3] = "IQM >= γ3 (Ω3), or SNR >= isolation-at-once SNR",
    [SFSM_C_OMEGA3_OTHER] = "another track dominant with IQM >= γ3 and SNR > isolation SNR",
    [SFSM_C_LIMIT_ISOLATED] = "step blocked by the window edge, IQM >= γ2",
    [SFSM_C_LIMIT_FIRST] = "step blocked by the window edge, no reversal yet",
    [SFSM_C_LIMIT_AGAIN] = "step blocked by the window edge after a reversal",
    [SFSM_C_AT_LIMIT] = "step blocked by the window edge",
    [SFSM_C_NO_DOMINANT] = "no dominant track",
    [SFSM_C_SPIKES_SEEN] = "spikes above the minimum rate and a dominant track",
    [SFSM_C_CURVE_VIABLE] = "curve ready (>= k0 obs.), m* >= 2, IQM >= γ1",
    [SFSM_C_CURVE_NOT_READY] = "curve has < k0 observations",
    [SFSM_C_CONVERGED_ISOLATED] = "eq. 2.1 converged and IQM >= γ2",
    [SFSM_C_IQM_LOW] = "IQM < γ1 (Ω0)",
    [SFSM_C_SNR_DROP] = "dominant SNR (any track) < drop fraction × isolation SNR",
    [SFSM_C_SNR_RESTORED] = "dominant SNR (any track) >= isolation SNR",
    [SFSM_C_OTHER_DOMINANT] = "another track is dominant",
    [SFSM_C_SNR_FALLING] = "dominant SNR (any track) < drop fraction × best SNR since entry or turn",
    [SFSM_C_LEASH] = "search span or more past the last depth with a dominant track, < 2 leash turns since",
};

static const char *const SFSM_ACTION_DOC[SFSM_ACTION_COUNT] = {
    [SFSM_A_NONE] = "-",
    [SFSM_A_RESTART] = "search direction := initial; reversals := 0",
    [SFSM_A_REVERSE] = "reverse the search direction; reversals += 1",
    [SFSM_A_DECLARE] = "reference := dominant track, mean SNR of its last R cycles at this depth, depth",
    [SFSM_A_RESTORE] = "keep the original reference",
    [SFSM_A_ADOPT] = "reference track := dominant track (same reference SNR and depth)",
    [SFSM_A_TURN] = "reverse the search direction (no edge reversal counted); best SNR := this SNR",
    [SFSM_A_LEASH] = "reverse the search direction (no edge reversal counted); leash turns += 1",
};

static const char *const SFSM_REASON_NAME[SFSM_REASON_COUNT] = {
    [SFSM_R_HALTED] = "halted",
    [SFSM_R_BAD_INPUT] = "bad_input",
    [SFSM_R_WINDOW_HOLD] = "window_hold",
    [SFSM_R_ISOLATED_HOLD] = "isolated_hold",
    [SFSM_R_SEARCH] = "search",
    [SFSM_R_SAMPLE] = "sample",
    [SFSM_R_NEWTON] = "newton",
    [SFSM_R_LINE] = "line",
    [SFSM_R_FLAT] = "flat",
    [SFSM_R_CONVERGED_HOLD] = "converged_hold",
    [SFSM_R_LOW_IQM_HOLD] = "low_iqm_hold",
    [SFSM_R_NO_DOMINANT_HOLD] = "no_dominant_hold",
    [SFSM_R_RETRACT] = "retract",
    [SFSM_R_APPROACH] = "approach",
    [SFSM_R_APPROACH_BACK] = "approach_back",
};

const sfsm_row_t *sfsm_table(size_t *n)
{
    if (n != NULL) {
        *n = SFSM_ROWS;
    }
    return SFSM_TABLE;
}

const sfsm_state_info_t *sfsm_state_info(sfsm_state_t state)
{
    return ((unsigned)state < (unsigned)SFSM_STATE_COUNT) ? &SFSM_INFO[state] : NULL;
}

const char *sfsm_state_name(sfsm_state_t state)
{
    return ((unsigned)state < (unsigned)SFSM_STATE_COUNT) ? SFSM_INFO[state].name : "?";
}

const char *sfsm_cond_doc(sfsm_cond_t cond)
{
    return ((unsigned)cond < (unsigned)SFSM_COND_COUNT) ? SFSM_COND_DOC[cond] : "?";
}

const char *sfsm_action_doc(sfsm_action_t action)
{
    return ((unsigned)action < (unsigned)SFSM_ACTION_COUNT) ? SFSM_ACTION_DOC[action] : "?";
}

const char *sfsm_reason_name(sfsm_reason_t reason)
{
    return ((unsigned)reason < (unsigned)SFSM_REASON_COUNT) ? SFSM_REASON_NAME[reason] : "?";
}

void sfsm_config_default(sfsm_config_t *cfg)
{
    if (cfg == NULL) {
        return;
    }
    cfg->move_search_um = 20.0;
    cfg->move_sample_um = 10.0;
    cfg->move_resample_um = 5.0;
    cfg->move_max_um = 30.0;
    cfg->gamma1 = 2.0;
    cfg->gamma2 = 3.0;
    cfg->gamma3 = 12.0;
    cfg->snr_isolate = 24.0;
    cfg->snr_drop_frac = 0.85;
    cfg->snr_min = 9.0;
    cfg->wait_r = 3u;
    cfg->lost_cycles = 5u;
    cfg->search_span_um = 100.0;
    cfg->initial_dir = 1;
    cfg->approach_um = 0.0;
    cfg->approach_gain = 0.03;
}

static bool sfsm_step_ok(double v, double cap)
{
    return isfinite(v) && (v > 0.0) && (v <= cap);
}

md_status_t sfsm_config_check(const sfsm_config_t *cfg)
{
    if (cfg == NULL) {
        return MD_E_ARG;
    }
    const double cap = cfg->move_max_um;
    const bool ok = isfinite(cap) && (cap > 0.0) && sfsm_step_ok(cfg->move_search_um, cap) &&
                    sfsm_step_ok(cfg->move_sample_um, cap) && sfsm_step_ok(cfg->move_resample_um, cap) &&
                    isfinite(cfg->gamma3) && (cfg->gamma1 > 0.0) && (cfg->gamma1 < cfg->gamma2) &&
                    (cfg->gamma2 < cfg->gamma3) && isfinite(cfg->snr_isolate) && (cfg->snr_isolate > 0.0) &&
                    (cfg->snr_drop_frac > 0.0) && (cfg->snr_drop_frac < 1.0) && isfinite(cfg->snr_min) &&
                    (cfg->snr_min >= 0.0) && (cfg->wait_r >= 1u) && (cfg->wait_r <= SFSM_R_MAX) &&
                    (cfg->lost_cycles >= 1u) && isfinite(cfg->search_span_um) && (cfg->search_span_um >= 0.0) &&
                    ((cfg->initial_dir == 1) || (cfg->initial_dir == -1)) && isfinite(cfg->approach_um) &&
                    (cfg->approach_um >= 0.0) && (cfg->approach_um <= cap) && isfinite(cfg->approach_gain) &&
                    (cfg->approach_gain >= 0.0);
    return ok ? MD_OK : MD_E_ARG;
}

md_status_t sfsm_init(sfsm_t *sm, const sfsm_config_t *cfg)
{
    if ((sm == NULL) || (sfsm_config_check(cfg) != MD_OK)) {
        return MD_E_ARG;
    }
    (void)memset(sm, 0, sizeof *sm);
    sm->cfg = *cfg;
    sm->state = SFSM_SPIKE_SEARCH;
    sm->search_dir = cfg->initial_dir;
    return MD_OK;
}

static bool sfsm_input_valid(const sfsm_input_t *in)
{
    const sc_suggestion_t *s = &in->suggestion;
    const bool window = isfinite(in->depth_um) && isfinite(in->depth_min_um) && isfinite(in->depth_max_um) &&
                        (in->depth_min_um < in->depth_max_um);
    const bool metrics = !in->has_dominant || (isfinite(in->snr) && isfinite(in->iqm));
    const bool sugg = isfinite(s->move_um) && isfinite(s->xi) && isfinite(s->h) && isfinite(s->newton_um);
    return window && metrics && sugg;
}

/* Per-cycle facts the conditions read. */
typedef struct {
    bool valid;
    bool dom;      /* a dominant track exists */
    bool ours;     /* ... and it is the isolated one, or none is isolated */
    bool at_limit; /* the current state's step is blocked by the window */
} sfsm_facts_t;

/* The search leash (ours, docs/sfsm.md): a neuron that falls silent, or a
 * weak one the tracker loses, is still where it was; Spike Search looks on
 * both sides of the last depth with a dominant track before it walks on into
 * new tissue. */
static bool sfsm_leash_reached(const sfsm_t *sm, const sfsm_input_t *in)
{
    const double span = sm->cfg.search_span_um;
    const double past = (double)sm->search_dir * (in->depth_um - sm->anchor_um);
    return sm->has_anchor && (span > 0.0) && (sm->leash_turns < SFSM_LEASH_TURNS) && (past >= span);
}

static bool sfsm_cond_holds(const sfsm_t *sm, const sfsm_input_t *in, const sfsm_facts_t *f, sfsm_cond_t c)
{
    const sfsm_config_t *k = &sm->cfg;
    const sc_suggestion_t *s = &in->suggestion;
    const bool v = f->valid;
    switch (c) {
    case SFSM_C_HALT: return !v || in->estop || in->fault;
    case SFSM_C_RESUME: return v && in->resume && !in->estop && !in->fault;
    /* Ω3 means "advancing further risks the neuron". A lone neuron's IQM grows
     * with its SNR (~0.5 SNR, docs/sfsm.md), so γ3 stops the tip at SNR ~24; in
     * crowded tissue the IQM stays low while the tip closes in, and the SNR
     * alone keeps that meaning. */
    case SFSM_C_OMEGA3: return v && f->dom && ((in->iqm >= k->gamma3) || (in->snr >= k->snr_isolate));
    case SFSM_C_OMEGA3_OTHER: return v && f->dom && !f->ours && (in->iqm >= k->gamma3) && (in->snr > sm->ref_snr);
    case SFSM_C_LIMIT_ISOLATED: return v && f->at_limit && f->ours && (in->iqm >= k->gamma2);
    case SFSM_C_LIMIT_FIRST: return v && f->at_limit && (sm->reversals == 0u);
    case SFSM_C_LIMIT_AGAIN: return v && f->at_limit && (sm->reversals > 0u);
    case SFSM_C_AT_LIMIT: return v && f->at_limit;
    case SFSM_C_NO_DOMINANT: return v && !f->dom;
    case SFSM_C_SPIKES_SEEN: return v && f->dom && in->spikes_seen;
    case SFSM_C_CURVE_VIABLE: return v && f->ours && s->ready && (s->m_star >= 2u) && (in->iqm >= k->gamma1);
    case SFSM_C_CURVE_NOT_READY: return v && f->ours && !s->ready;
    case SFSM_C_CONVERGED_ISOLATED: return v && f->ours && s->ready && s->converged && (in->iqm >= k->gamma2);
    case SFSM_C_IQM_LOW: return v && f->ours && (in->iqm < k->gamma1);
    /* Identity-free on purpose (thesis: "the dominant neuron's SNR"): the
     * tracker may split one neuron into two alternating IDs, which must not
     * hide a drop; a louder other neuron never counts as one. */
    case SFSM_C_SNR_DROP: return v && sm->has_ref && f->dom && (in->snr < k->snr_drop_frac * sm->ref_snr);
    case SFSM_C_SNR_RESTORED: return v && sm->has_ref && f->dom && (in->snr >= sm->ref_snr);
    case SFSM_C_OTHER_DOMINANT: return v && f->dom && !f->ours;
    /* Identity-free like the 85 % rule: the tracker may give the neuron a new
     * ID every interval, so no per-track curve gets ready while Gradient
     * Search walks away from a neuron it has passed. */
    case SFSM_C_SNR_FALLING: return v && f->dom && (in->snr < k->snr_drop_frac * sm->seek_best_snr);
    case SFSM_C_LEASH: return v && sfsm_leash_reached(sm, in);
    case SFSM_COND_COUNT: /* MISRA 16.4 default; -Wswitch-enum still checks every enumerator */
    default: return false;
    }
    return false;
}

/* Step the optimiser proposes, for Isolate / Re-Isolate Neuron (§2.2.3). */
static double sfsm_optimiser_step(const sfsm_t *sm, const sfsm_input_t *in, const sfsm_facts_t *f, sfsm_reason_t *why)
{
    const sc_suggestion_t *s = &in->suggestion;
    if (!f->ours) {
        *why = SFSM_R_NO_DOMINANT_HOLD;
        return 0.0;
    }
    if (in->iqm < sm->cfg.gamma1) { /* Table 2.1 Ω0: do not follow the gradient */
        *why = SFSM_R_LOW_IQM_HOLD;
        return 0.0;
    }
    if (!s->ready) {
        *why = SFSM_R_SAMPLE;
        return (double)sm->search_dir * sm->cfg.move_sample_um;
    }
    if (s->converged) {
        *why = SFSM_R_CONVERGED_HOLD;
        return 0.0;
    }
    *why = (s->m_star >= 3u) ? SFSM_R_NEWTON : ((s->m_star == 2u) ? SFSM_R_LINE : SFSM_R_FLAT);
    return s->move_um;
}

/* Unclamped step of the current state (motion column of docs/sfsm.md). */
static double sfsm_policy(const sfsm_t *sm, const sfsm_input_t *in, const sfsm_facts_t *f, sfsm_reason_t *why)
{
    const double dir = (double)sm->search_dir;
    switch (sm->state) {
    case SFSM_SPIKE_SEARCH: *why = SFSM_R_SEARCH; return dir * sm->cfg.move_search_um;
    case SFSM_GRADIENT_SEARCH:
        *why = f->dom ? SFSM_R_SAMPLE : SFSM_R_NO_DOMINANT_HOLD;
        return f->dom ? dir * sm->cfg.move_sample_um : 0.0;
    case SFSM_ISOLATE_NEURON:
    case SFSM_REISOLATE_NEURON: return sfsm_optimiser_step(sm, in, f, why);
    case SFSM_REESTIMATE_GRADIENT: /* retract: decompression moves neurons up (§2.2.4) */
        *why = f->dom ? SFSM_R_RETRACT : SFSM_R_NO_DOMINANT_HOLD;
        return f->dom ? -sm->cfg.move_resample_um : 0.0;
    case SFSM_NEURON_ISOLATED: *why = SFSM_R_ISOLATED_HOLD; return 0.0;
    case SFSM_WINDOW_LIMIT: *why = SFSM_R_WINDOW_HOLD; return 0.0;
    case SFSM_HALTED:
    case SFSM_STATE_COUNT: /* MISRA 16.4 default */
    default: break;
    }
    *why = f->valid ? SFSM_R_HALTED : SFSM_R_BAD_INPUT;
    return 0.0;
}

/* Shortens a step to stay inside the window (never reverses it: outside the
 * window an outward step becomes zero) and caps it at Δmax. */
static double sfsm_clamp(const sfsm_t *sm, const sfsm_input_t *in, double step)
{
    double v = step;
    if (v > 0.0) {
        v = fmin(v, fmax(in->depth_max_um - in->depth_um, 0.0));
    } else if (v < 0.0) {
        v = fmax(v, fmin(in->depth_min_um - in->depth_um, 0.0));
    } else {
        v = 0.0;
    }
    return fmin(fmax(v, -sm->cfg.move_max_um), sm->cfg.move_max_um);
}

/* The reference SNR is what the neuron gives at the isolation depth: the
 * window of recent SNRs restarts with another track or after a move (a
 * depth change beyond the servo's tolerance), so an Ω3 declared right after
 * a step does not average in the weaker SNRs of shallower positions. */
static void sfsm_note_snr(sfsm_t *sm, const sfsm_input_t *in)
{
    if ((sm->recent_n == 0u) || (sm->recent_track != in->dominant_track) ||
        (fabs(in->depth_um - sm->recent_depth_um) > SFSM_SAME_DEPTH_UM)) {
        sm->recent_n = 0u;
        sm->recent_head = 0u;
        sm->recent_track = in->dominant_track;
        sm->recent_depth_um = in->depth_um;
    }
    sm->recent_snr[sm->recent_head] = in->snr;
    sm->recent_iqm[sm->recent_head] = in->iqm;
    sm->recent_head = (uint8_t)((sm->recent_head + 1u) % sm->cfg.wait_r);
    if (sm->recent_n < sm->cfg.wait_r) {
        sm->recent_n++;
    }
}

static double sfsm_mean(const double *v, uint8_t n)
{
    double s = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        s += v[i];
    }
    return s / (double)n;
}

static double sfsm_recent_mean(const sfsm_t *sm)
{
    return sfsm_mean(sm->recent_snr, sm->recent_n);
}

/* Reference ratchet (ours, docs/sfsm.md): Ω3 can declare isolation tens of
 * µm before the peak and tissue relaxation then brings the neuron closer;
 * the 85 % rule must measure a later drift against what the neuron gives at
 * its best here, not against the SNR of the moment of isolation. Only a full
 * window of R cycles of the isolated track at this depth raises it. */
static void sfsm_raise_reference(sfsm_t *sm, const sfsm_facts_t *f)
{
    if ((sm->state != SFSM_NEURON_ISOLATED) || !sm->has_ref || !f->ours || (sm->recent_n < sm->cfg.wait_r) ||
        (fabs(sm->recent_depth_um - sm->ref_depth_um) > SFSM_SAME_DEPTH_UM)) {
        return;
    }
    const double m = sfsm_recent_mean(sm);
    if (m > sm->ref_snr) {
        sm->ref_snr = m;
    }
}

static void sfsm_do_action(sfsm_t *sm, const sfsm_input_t *in, sfsm_action_t a)
{
    switch (a) {
    case SFSM_A_RESTART:
        sm->search_dir = sm->cfg.initial_dir;
        sm->reversals = 0u;
        break;
    case SFSM_A_REVERSE:
        sm->search_dir = (int8_t)-sm->search_dir;
        sm->reversals = (sm->reversals < UINT8_MAX) ? (uint8_t)(sm->reversals + 1u) : UINT8_MAX;
        break;
    case SFSM_A_DECLARE:
        sm->has_ref = true;
        sm->ref_track = in->dominant_track;
        sm->ref_snr = (sm->recent_n > 0u) ? sfsm_recent_mean(sm) : in->snr;
        sm->ref_depth_um = in->depth_um;
        sm->approach_dir = sm->search_dir;
        sm->approach_done = false;
        sm->approach_has_last = false;
        break;
    case SFSM_A_ADOPT: sm->ref_track = in->dominant_track; break;
    case SFSM_A_TURN:
        sm->search_dir = (int8_t)-sm->search_dir;
        sm->seek_best_snr = in->snr;
        break;
    case SFSM_A_LEASH:
        sm->search_dir = (int8_t)-sm->search_dir;
        sm->leash_turns++;
        break;
    case SFSM_A_RESTORE:
    case SFSM_A_NONE:
    case SFSM_ACTION_COUNT: /* MISRA 16.4 default */
    default: break;
    }
}

/* Entry actions (SFSM_INFO[].entry). The reference exists only in the
 * isolated modes (Neuron Isolated, Re-Estimate Gradient, Re-Isolate Neuron). */
static void sfsm_enter(sfsm_t *sm, const sfsm_input_t *in, bool dom, sfsm_state_t to, sfsm_output_t *out)
{
    if (to == SFSM_GRADIENT_SEARCH) {
        sm->seek_best_snr = dom ? in->snr : 0.0; /* the SNR that started the search counts */
    }
    const bool isolated_mode = (to == SFSM_NEURON_ISOLATED) || (to == SFSM_REESTIMATE_GRADIENT) ||
                               (to == SFSM_REISOLATE_NEURON);
    if (!isolated_mode) {
        sm->has_ref = false;
    }
    if (to == SFSM_ISOLATE_NEURON) {
        sm->reversals = 0u;
    }
    if ((to == SFSM_REESTIMATE_GRADIENT) && sm->has_ref) {
        out->reset_curve = true;
        out->reset_track = sm->ref_track;
    }
}

bool sfsm_holds_lone_neuron(const sfsm_t *sm)
{
    return (sm != NULL) && (sm->state == SFSM_NEURON_ISOLATED) && sm->has_ref && (sm->recent_n >= sm->cfg.wait_r) &&
           (sm->recent_track == sm->ref_track) && (sfsm_mean(sm->recent_iqm, sm->recent_n) >= sm->cfg.gamma3);
}

/* Settled approach (ours, docs/sfsm.md): Ω3 stops the tip tens of µm before
 * the neuron's SNR peak, and the tissue's give-back carries the neuron the
 * rest of the way, together with any neuron hidden below it. With the
 * give-back paced or followed (approach_guard.h rules 8 and 9) the SFSM
 * closes the distance itself, once the tissue has settled, in steps of
 * approach_um, each judged on R cycles of the neuron's SNR where it ended: a
 * rise of approach_gain earns the next step, a fall sends the tip back one
 * step and ends the approach, anything between ends it there. Only a lone
 * neuron (sfsm_holds_lone_neuron: mean IQM >= γ3) is approached: in crowded
 * tissue, where Ω3 fired by loudness, a neuron louder ones mask may lie on
 * the path. Every step passes the approach guard; a step it did not let
 * through, or a retraction behind its start, also ends the approach.
 * Returns the step (0: none). */
static double sfsm_approach(sfsm_t *sm, const sfsm_input_t *in, const sfsm_facts_t *f, sfsm_reason_t *why)
{
    const sfsm_config_t *k = &sm->cfg;
    if (!(k->approach_um > 0.0) || sm->approach_done || !f->ours || !in->settled || !sfsm_holds_lone_neuron(sm)) {
        return 0.0; /* off, done, not settled, or crowded (Ω3 by loudness): hold */
    }
    const double m = sfsm_recent_mean(sm);
    if (sm->approach_has_last) {
        if ((double)sm->approach_dir * (in->depth_um - sm->approach_last_um) <= SFSM_SAME_DEPTH_UM) {
            sm->approach_done = true; /* the step was not taken, or the guard retracted */
            return 0.0;
        }
        if (m < sm->approach_last_snr) {
            sm->approach_done = true;
            sm->ref_depth_um = sm->approach_last_um;
            sm->approach_steps++;
            *why = SFSM_R_APPROACH_BACK;
            return sm->approach_last_um - in->depth_um;
        }
        sm->ref_depth_um = in->depth_um; /* the best position so far: the reference lives here */
        sm->ref_snr = fmax(sm->ref_snr, m);
        if (m < sm->approach_last_snr * (1.0 + k->approach_gain)) {
            sm->approach_done = true;
            return 0.0;
        }
    }
    sm->approach_has_last = true;
    sm->approach_last_um = in->depth_um;
    sm->approach_last_snr = m;
    sm->approach_steps++;
    *why = SFSM_R_APPROACH;
    return (double)sm->approach_dir * k->approach_um;
}

/* Advances every applicable row's WAIT counter and returns the first row that
 * fires, or -1. Counters of rows whose condition failed restart at 0, so a
 * condition that holds R-1 cycles and then breaks never fires. */
static int16_t sfsm_select(sfsm_t *sm, const sfsm_input_t *in, const sfsm_facts_t *f)
{
    int16_t fired = -1;
    for (size_t i = 0u; i < SFSM_ROWS; ++i) {
        const sfsm_row_t *r = &SFSM_TABLE[i];
        if ((r->from_mask & B(sm->state)) == 0u) {
            sm->wait[i] = 0u;
            continue;
        }
        const bool holds = sfsm_cond_holds(sm, in, f, r->cond);
        sm->wait[i] = holds ? ((sm->wait[i] < UINT8_MAX) ? (uint8_t)(sm->wait[i] + 1u) : UINT8_MAX) : 0u;
        const unsigned need = (r->wait == SFSM_W_R)      ? sm->cfg.wait_r
                              : (r->wait == SFSM_W_LOST) ? sm->cfg.lost_cycles
                                                         : 1u;
        if ((fired < 0) && (sm->wait[i] >= need)) {
            fired = (int16_t)i;
        }
    }
    return fired;
}

md_status_t sfsm_decide(sfsm_t *sm, const sfsm_input_t *in, sfsm_output_t *out)
{
    if ((sm == NULL) || (in == NULL) || (out == NULL)) {
        return MD_E_ARG;
    }
    (void)memset(out, 0, sizeof *out);
    sfsm_facts_t f;
    f.valid = sfsm_input_valid(in);
    /* Noise floor (ours, docs/sfsm.md): threshold crossings of noise and
     * distant multi-unit activity form clusters whose SNR is inflated by the
     * detection threshold; such a track is no neuron and never dominant. */
    f.dom = f.valid && in->has_dominant && (in->snr >= sm->cfg.snr_min);
    f.ours = f.dom && (!sm->has_ref || (in->dominant_track == sm->ref_track));
    if (!f.valid) {
        sm->bad_inputs++;
    } else if (f.dom) {
        sfsm_note_snr(sm, in);
        sfsm_raise_reference(sm, &f);
        sm->has_anchor = true;
        sm->anchor_um = in->depth_um;
        sm->leash_turns = 0u;
        if ((sm->state == SFSM_GRADIENT_SEARCH) && (in->snr > sm->seek_best_snr)) {
            sm->seek_best_snr = in->snr;
        }
    }
    sfsm_reason_t why = SFSM_R_HALTED;
    const double nominal = sfsm_policy(sm, in, &f, &why);
    f.at_limit = f.valid && (fabs(nominal) >= SFSM_EDGE_UM) && (fabs(sfsm_clamp(sm, in, nominal)) < SFSM_EDGE_UM);
    out->from = sm->state;
    out->row = sfsm_select(sm, in, &f);
    if (out->row >= 0) {
        const sfsm_row_t *r = &SFSM_TABLE[out->row];
        sfsm_do_action(sm, in, r->action);
        if (r->to != sm->state) {
            sm->state = r->to;
            sfsm_enter(sm, in, f.dom, r->to, out);
        }
        (void)memset(sm->wait, 0, sizeof sm->wait);
        sm->transitions++;
    }
    double step = sfsm_policy(sm, in, &f, &why);
    if ((out->row < 0) && f.valid) {
        const double a = sfsm_approach(sm, in, &f, &why);
        step = (fabs(a) > 0.0) ? a : step;
    }
    out->move_um = f.valid ? sfsm_clamp(sm, in, step) : 0.0;
    out->clamped = fabs(out->move_um - step) > 1e-9;
    out->reason = why;
    out->state = sm->state;
    sm->cycles++;
    return f.valid ? MD_OK : MD_E_ARG;
}
