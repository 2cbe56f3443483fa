/* Unit: supervisory finite state machine (thesis §2.2.4, Table 2.1).
 * Every row of the transition table is driven (the last test checks that each
 * one fired), every WAIT row is shown not to fire after R-1 qualifying cycles
 * followed by a break, HALTED and the hold states never request motion, and
 * no step ever exceeds Δmax or leaves the depth window. */
#include <math.h>
#include <string.h>

#include "numeric/md_rng.h"
#include "control/sfsm.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define TRACK_A 7u
#define TRACK_B 9u

static sfsm_config_t cfg;
static sfsm_t sm;
static sfsm_output_t out;
static unsigned fired[SFSM_ROWS_MAX];

static bool holds_still(sfsm_state_t s)
{
    return (s == SFSM_NEURON_ISOLATED) || (s == SFSM_WINDOW_LIMIT) || (s == SFSM_HALTED);
}

/* Dominant TRACK_A, SNR 5, IQM 2.5 (Ω1), spikes, depth 1000 in [0, 5000],
 * a ready cubic-order suggestion stepping +12 µm. */
static sfsm_input_t base(void)
{
    sfsm_input_t in;
    (void)memset(&in, 0, sizeof in);
    in.has_dominant = true;
    in.dominant_track = TRACK_A;
    in.snr = 5.0;
    in.iqm = 2.5;
    in.spikes_seen = true;
    in.depth_um = 1000.0;
    in.depth_min_um = 0.0;
    in.depth_max_um = 5000.0;
    in.suggestion.ready = true;
    in.suggestion.m_star = 3u;
    in.suggestion.move_um = 12.0;
    in.suggestion.newton_um = 12.0;
    return in;
}

static void converged(sfsm_input_t *in)
{
    in->suggestion.converged = true;
    in->suggestion.move_um = 0.0;
    in->suggestion.newton_um = 1.0;
}

/* One cycle with the invariants every cycle must keep. */
static md_status_t cycle(const sfsm_input_t *in)
{
    const md_status_t st = sfsm_decide(&sm, in, &out);
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(cfg.move_max_um, fabs(out.move_um));
    const bool approach = (out.reason == SFSM_R_APPROACH) || (out.reason == SFSM_R_APPROACH_BACK);
    if (holds_still(out.state) && !approach) {
        TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
    }
    if (approach) { /* only from Neuron Isolated, in settled tissue, one approach step at most */
        TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
        TEST_ASSERT_TRUE(in->settled);
        TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(cfg.approach_um + 1e-9, fabs(out.move_um));
    }
    if (isfinite(in->depth_um) && (in->depth_min_um < in->depth_max_um) && (in->depth_um >= in->depth_min_um) &&
        (in->depth_um <= in->depth_max_um)) {
        TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(in->depth_max_um + 1e-9, in->depth_um + out.move_um);
        TEST_ASSERT_GREATER_OR_EQUAL_DOUBLE(in->depth_min_um - 1e-9, in->depth_um + out.move_um);
    }
    if (out.row >= 0) {
        fired[out.row]++;
    }
    return st;
}

static void run(const sfsm_input_t *in, unsigned n)
{
    for (unsigned i = 0u; i < n; ++i) {
        TEST_ASSERT_EQUAL_INT(MD_OK, cycle(in));
    }
}

/* The transition tests use small SNRs (5, 8 ...): the noise floor is set
 * below all of them here and has its own tests (start_with_floor, with the
 * defaults). */
static void start(void)
{
    sfsm_config_default(&cfg);
    cfg.snr_min = 1.0;
    cfg.gamma3 = 5.0; /* and γ3 low enough for IQMs of that scale */
    TEST_ASSERT_EQUAL_INT(MD_OK, sfsm_init(&sm, &cfg));
}

static void start_with_floor(void)
{
    sfsm_config_default(&cfg);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 9.0, cfg.snr_min);
    TEST_ASSERT_EQUAL_INT(MD_OK, sfsm_init(&sm, &cfg));
}

static void to_gradient_search(void)
{
    start();
    const sfsm_input_t in = base();
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_GRADIENT_SEARCH, out.state);
}

static void to_isolate(void)
{
    to_gradient_search();
    const sfsm_input_t in = base();
    run(&in, cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_ISOLATE_NEURON, out.state);
}

/* Isolated on TRACK_A with reference SNR 8. */
static void to_isolated(void)
{
    to_isolate();
    sfsm_input_t in = base();
    converged(&in);
    in.iqm = 3.5;
    in.snr = 8.0;
    run(&in, cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 8.0, sm.ref_snr);
}

static void to_reestimate(void)
{
    to_isolated();
    sfsm_input_t in = base();
    in.snr = 6.0;
    in.suggestion.ready = false;
    run(&in, cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_REESTIMATE_GRADIENT, out.state);
}

static void to_reisolate(void)
{
    to_reestimate();
    sfsm_input_t in = base();
    in.snr = 6.0;
    run(&in, cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_REISOLATE_NEURON, out.state);
}

static void test_config_defaults_and_checks(void)
{
    start();
    TEST_ASSERT_EQUAL_INT(MD_OK, sfsm_config_check(&cfg));
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, sm.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.85, cfg.snr_drop_frac);
    sfsm_config_t bad = cfg;
    bad.gamma2 = bad.gamma3;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad = cfg;
    bad.move_search_um = cfg.move_max_um + 1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad = cfg;
    bad.wait_r = 0u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad = cfg;
    bad.wait_r = SFSM_R_MAX + 1u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad = cfg;
    bad.snr_drop_frac = 1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad = cfg;
    bad.snr_min = -0.5;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad.snr_min = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad = cfg;
    bad.search_span_um = -1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad.search_span_um = INFINITY;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad = cfg;
    bad.approach_um = cfg.move_max_um + 1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad.approach_um = -1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad = cfg;
    bad.approach_gain = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad = cfg;
    bad.initial_dir = 0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_init(&sm, &bad));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_init(NULL, &cfg));
    sfsm_input_t in = base();
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_decide(&sm, NULL, &out));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_decide(&sm, &in, NULL));
}

/* Noise floor (ours): threshold crossings of noise and distant multi-unit
 * activity form a cluster with SNR ~6-7 and an IQM that jumps between 0 and
 * 8 from one interval to the next. Such a track is no neuron: Spike Search
 * goes on, Ω3 never fires; a track above the floor is a neuron again. */
static void test_noise_floor_never_isolates(void)
{
    start_with_floor();
    sfsm_input_t in = base();
    converged(&in);
    in.snr = 8.9;
    for (unsigned k = 0u; k < 50u; ++k) {
        in.iqm = (double)(k % 15u); /* 0 .. 14: Ω3 every few cycles if it counted */
        TEST_ASSERT_EQUAL_INT(MD_OK, cycle(&in));
        TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
        TEST_ASSERT_EQUAL_INT(-1, out.row);
        TEST_ASSERT_DOUBLE_WITHIN(0.0, cfg.move_search_um, out.move_um);
        TEST_ASSERT_EQUAL_INT(SFSM_R_SEARCH, out.reason);
    }
    TEST_ASSERT_FALSE(sm.has_ref);
    in.snr = 9.0; /* at the floor: a neuron; Ω3 at once */
    in.iqm = 12.0;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_EQUAL_UINT32(TRACK_A, sm.ref_track);
}

/* An isolated neuron whose SNR sinks below the floor counts as lost (the
 * lost_cycles rule), not as an SNR drop to re-isolate on noise. */
static void test_noise_floor_counts_as_lost(void)
{
    start_with_floor();
    sfsm_input_t in = base();
    in.snr = 12.0;
    in.iqm = 13.0;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    in.snr = 8.0; /* < 0.85 × 12 and < the floor */
    in.iqm = 2.5;
    run(&in, (unsigned)cfg.lost_cycles - 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, cfg.move_search_um, out.move_um);
}

static void test_spike_search_steps_then_finds_spikes(void)
{
    start();
    sfsm_input_t in = base();
    in.has_dominant = false;
    in.spikes_seen = false;
    run(&in, 4u);
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 20.0, out.move_um);
    TEST_ASSERT_EQUAL_INT(SFSM_R_SEARCH, out.reason);
    in.spikes_seen = true; /* spikes but no dominant track: keep searching */
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
    in = base(); /* no WAIT: moving on by Δsearch while waiting would overshoot */
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_GRADIENT_SEARCH, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 10.0, out.move_um);
    TEST_ASSERT_EQUAL_INT(SFSM_R_SAMPLE, out.reason);
}

/* GS → IN needs R consecutive viable cycles; R-1 then a break does nothing. */
static void test_gradient_search_waits_r_cycles(void)
{
    to_gradient_search();
    sfsm_input_t viable = base();
    sfsm_input_t flat = base();
    flat.suggestion.m_star = 1u;
    sfsm_input_t poor = base();
    poor.iqm = 1.5; /* Ω0 */
    run(&viable, cfg.wait_r - 1u);
    run(&flat, 1u);
    run(&viable, cfg.wait_r - 1u);
    run(&poor, 1u);
    run(&viable, cfg.wait_r - 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_GRADIENT_SEARCH, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 10.0, out.move_um);
    run(&viable, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_ISOLATE_NEURON, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 12.0, out.move_um); /* the optimiser's step at once */
    TEST_ASSERT_EQUAL_INT(SFSM_R_NEWTON, out.reason);
}

static void test_isolate_follows_the_optimiser(void)
{
    to_isolate();
    sfsm_input_t in = base();
    in.suggestion.m_star = 2u;
    in.suggestion.move_um = -30.0;
    run(&in, 1u);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, -30.0, out.move_um);
    TEST_ASSERT_EQUAL_INT(SFSM_R_LINE, out.reason);
    in.suggestion.m_star = 1u;
    in.suggestion.move_um = 10.0;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_R_FLAT, out.reason);
    in.suggestion.m_star = 3u;
    in.suggestion.move_um = 80.0; /* a misbehaving optimiser is still capped */
    run(&in, 1u);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, cfg.move_max_um, out.move_um);
    TEST_ASSERT_TRUE(out.clamped);
    converged(&in); /* converged but only Ω1: hold, no isolation */
    run(&in, 2u * cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_ISOLATE_NEURON, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
    TEST_ASSERT_EQUAL_INT(SFSM_R_CONVERGED_HOLD, out.reason);
    in.iqm = 1.0; /* Ω0 for R-1 cycles: hold, do not follow the gradient */
    in.suggestion = base().suggestion;
    run(&in, cfg.wait_r - 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_R_LOW_IQM_HOLD, out.reason);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
}

static void test_isolate_declares_after_r_converged_cycles(void)
{
    to_isolate();
    sfsm_input_t in = base();
    converged(&in);
    in.iqm = 3.5; /* Ω2 */
    sfsm_input_t moving = base();
    moving.iqm = 3.5;
    in.snr = 7.0;
    run(&in, cfg.wait_r - 1u);
    run(&moving, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_ISOLATE_NEURON, out.state);
    in.snr = 9.0;
    run(&in, cfg.wait_r - 1u);
    in.snr = 12.0;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
    TEST_ASSERT_TRUE(sm.has_ref);
    TEST_ASSERT_EQUAL_UINT32(TRACK_A, sm.ref_track);
    /* reference = mean SNR of the last R cycles of the track (9, 9, 12) */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 10.0, sm.ref_snr);
}

static void test_isolate_falls_back_to_gradient_search(void)
{
    to_isolate();
    sfsm_input_t low = base();
    low.iqm = 1.0;
    run(&low, cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_GRADIENT_SEARCH, out.state);
    to_isolate();
    sfsm_input_t young = base(); /* the dominant track's curve is new: no WAIT */
    young.suggestion.ready = false;
    young.suggestion.m_star = 0u;
    run(&young, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_GRADIENT_SEARCH, out.state);
}

/* Neuron Isolated: hold; leave below 85 % of the isolation SNR for R cycles. */
static void test_isolated_snr_drop_rule(void)
{
    to_isolated();
    sfsm_input_t in = base();
    in.snr = 0.86 * 8.0;
    run(&in, 3u * cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_EQUAL_INT(SFSM_R_ISOLATED_HOLD, out.reason);
    in.snr = 0.84 * 8.0;
    run(&in, cfg.wait_r - 1u);
    in.snr = 7.0;
    run(&in, 1u);
    in.snr = 0.84 * 8.0;
    run(&in, cfg.wait_r - 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_FALSE(out.reset_curve);
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_REESTIMATE_GRADIENT, out.state);
    TEST_ASSERT_TRUE(out.reset_curve); /* entry: restart the drifted neuron's curve */
    TEST_ASSERT_EQUAL_UINT32(TRACK_A, out.reset_track);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, -5.0, out.move_um); /* retract by Δresample */
    TEST_ASSERT_EQUAL_INT(SFSM_R_RETRACT, out.reason);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 8.0, sm.ref_snr);
}

/* The neuron comes closer after isolation (tissue relaxation): R cycles of
 * the isolated track at a higher SNR raise the reference, so a later drift
 * is measured against the best SNR here; one loud interval, another track or
 * another depth do not. */
static void test_isolated_reference_follows_a_louder_neuron(void)
{
    to_isolated(); /* reference 8 at 1000 µm */
    sfsm_input_t in = base();
    in.snr = 12.0;
    run(&in, 1u); /* the window's mean: (8 + 8 + 12) / 3 */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, (2.0 * 8.0 + 12.0) / 3.0, sm.ref_snr);
    run(&in, cfg.wait_r - 1u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 12.0, sm.ref_snr);
    in.snr = 0.86 * 12.0; /* above 85 % of the raised reference: hold */
    run(&in, 2u * cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 12.0, sm.ref_snr); /* never lowered */
    in.snr = 0.84 * 12.0;                               /* the drift the old reference (8) would have missed */
    run(&in, cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_REESTIMATE_GRADIENT, out.state);
    /* another track, however loud, never raises the isolated neuron's reference */
    to_isolated();
    in = base();
    in.dominant_track = TRACK_A + 1u;
    in.snr = 8.5;
    in.iqm = 3.0;
    run(&in, cfg.wait_r - 1u);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 8.0, sm.ref_snr);
}

static void test_reestimate_to_reisolate_and_back(void)
{
    to_reestimate();
    sfsm_input_t in = base();
    in.snr = 6.0;
    in.suggestion.ready = false;
    run(&in, 5u);
    TEST_ASSERT_EQUAL_INT(SFSM_REESTIMATE_GRADIENT, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, -5.0, out.move_um);
    in = base();
    in.snr = 6.0;
    in.suggestion.m_star = 1u; /* a flat curve says nothing about the direction */
    run(&in, cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_REESTIMATE_GRADIENT, out.state);
    in.suggestion.m_star = 2u; /* a slope: follow it at once (no WAIT, ours) */
    in.suggestion.move_um = -30.0;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_REISOLATE_NEURON, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, -30.0, out.move_um);
    in.snr = 7.99;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_REISOLATE_NEURON, out.state);
    in.snr = 8.0; /* back at the isolation SNR: restored at once, reference kept */
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 8.0, sm.ref_snr);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
    to_reestimate(); /* also straight from Re-Estimate Gradient */
    in = base();
    in.snr = 8.5;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 8.0, sm.ref_snr);
}

static void test_reisolate_exits(void)
{
    to_reisolate();
    sfsm_input_t in = base();
    in.snr = 6.5;
    in.iqm = 3.5;
    converged(&in);
    run(&in, cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 6.5, sm.ref_snr); /* a new isolation, a new reference */
    to_reisolate();
    in = base();
    in.snr = 6.0;
    in.iqm = 1.0;
    run(&in, cfg.wait_r - 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_REISOLATE_NEURON, out.state);
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_REESTIMATE_GRADIENT, out.state);
    to_reisolate();
    in = base();
    in.snr = 6.0;
    in.suggestion.ready = false;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_REESTIMATE_GRADIENT, out.state);
}

/* Another track dominant for R cycles while isolated, at an SNR within the
 * isolation band: the tracker relabelled the neuron (or an equal one took
 * over); it becomes the reference track, same state, same reference SNR. */
static void test_other_dominant_is_adopted(void)
{
    void (*const reach[3])(void) = {to_isolated, to_reestimate, to_reisolate};
    for (size_t k = 0u; k < 3u; ++k) {
        reach[k]();
        const sfsm_state_t here = sm.state;
        const double ref = sm.ref_snr;
        sfsm_input_t other = base();
        other.dominant_track = TRACK_B;
        other.snr = (here == SFSM_NEURON_ISOLATED) ? 7.5 : 6.0; /* no drop below 0.85 × 8, no restore */
        other.suggestion.m_star = 1u;                           /* no slope: Re-Estimate stays */
        sfsm_input_t mine = other;
        mine.dominant_track = TRACK_A;
        run(&other, cfg.wait_r - 1u);
        if (here == SFSM_REESTIMATE_GRADIENT) {
            TEST_ASSERT_DOUBLE_WITHIN(0.0, -cfg.move_resample_um, out.move_um); /* identity-free retract */
        }
        run(&mine, 1u); /* alternating IDs never adopt */
        TEST_ASSERT_EQUAL_INT(here, out.state);
        TEST_ASSERT_EQUAL_UINT32(TRACK_A, sm.ref_track);
        run(&other, cfg.wait_r);
        TEST_ASSERT_EQUAL_INT(here, out.state);
        TEST_ASSERT_EQUAL_UINT32(TRACK_B, sm.ref_track);
        TEST_ASSERT_TRUE(sm.has_ref);
        TEST_ASSERT_DOUBLE_WITHIN(0.0, ref, sm.ref_snr);
    }
}

/* Gradient Search that passed its neuron (the tracker reported it late, then
 * under a new ID every interval, so no curve gets ready): once the dominant
 * SNR stays below the drop fraction of the best SNR of this search for R
 * cycles, turn round; R-1 such cycles change nothing. */
static void test_gradient_search_turns_when_snr_falls(void)
{
    to_gradient_search(); /* entered at SNR 5 */
    sfsm_input_t in = base();
    in.suggestion.ready = false;
    in.snr = 20.0;
    run(&in, 1u);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 20.0, sm.seek_best_snr);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, cfg.move_sample_um, out.move_um);
    in.snr = 16.9; /* < 0.85 × 20 */
    for (unsigned k = 0u; k + 1u < cfg.wait_r; ++k) {
        in.dominant_track = (k % 2u == 0u) ? TRACK_B : TRACK_A; /* a new ID each time: identity-free */
        run(&in, 1u);
    }
    in.snr = 17.1; /* breaks the WAIT */
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(1, sm.search_dir);
    in.snr = 16.0;
    run(&in, cfg.wait_r);
    TEST_ASSERT_EQUAL_INT(SFSM_GRADIENT_SEARCH, out.state);
    TEST_ASSERT_EQUAL_INT(-1, sm.search_dir);
    TEST_ASSERT_EQUAL_UINT8(0u, sm.reversals); /* not an edge reversal */
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 16.0, sm.seek_best_snr);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, -cfg.move_sample_um, out.move_um);
}

/* The 85 % rule reads the dominant SNR whatever its ID: a neuron split into
 * two alternating tracks still leaves Neuron Isolated when its SNR drops, and
 * its return restores isolation. */
static void test_snr_drop_ignores_alternating_ids(void)
{
    to_isolated();
    sfsm_input_t in = base();
    in.snr = 6.0; /* < 0.85 × 8 */
    for (unsigned k = 0u; k < cfg.wait_r; ++k) {
        TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, sm.state);
        in.dominant_track = (k % 2u == 0u) ? TRACK_B : TRACK_A;
        run(&in, 1u);
    }
    TEST_ASSERT_EQUAL_INT(SFSM_REESTIMATE_GRADIENT, out.state);
    TEST_ASSERT_TRUE(out.reset_curve);
    TEST_ASSERT_EQUAL_UINT32(TRACK_A, out.reset_track);
    in.dominant_track = TRACK_B;
    run(&in, 1u);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, -cfg.move_resample_um, out.move_um);
    in.snr = 8.0;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 8.0, sm.ref_snr);
}

/* Ω3 (IQM >= γ3) → Neuron Isolated; in Re-Estimate / Re-Isolate only for a
 * louder other track (the held neuron's own high IQM there is no new
 * isolation: its reference SNR stands until the SNR is restored or the
 * optimiser converges). */
static void test_omega3_isolates_from_any_state(void)
{
    void (*const held[2])(void) = {to_reestimate, to_reisolate};
    for (size_t k = 0u; k < 2u; ++k) {
        held[k]();
        const sfsm_state_t here = sm.state;
        sfsm_input_t in = base();
        in.iqm = 5.0;
        in.snr = 6.0;
        in.suggestion.m_star = 1u; /* no slope: Re-Estimate stays */
        run(&in, 1u);
        TEST_ASSERT_EQUAL_INT(here, out.state);
        TEST_ASSERT_DOUBLE_WITHIN(0.0, 8.0, sm.ref_snr);
        in.dominant_track = TRACK_B;
        in.snr = 7.0; /* another track, Ω3, not louder than the reference */
        run(&in, 1u);
        TEST_ASSERT_EQUAL_INT(here, out.state);
        in.snr = 9.0;
        run(&in, 1u);
        TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
        TEST_ASSERT_EQUAL_UINT32(TRACK_B, sm.ref_track);
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, 8.0, sm.ref_snr); /* B's SNRs at this depth: 7, 9 */
    }
}

/* Ω3 by loudness: with the defaults a dominant track at snr_isolate stops
 * the search however low its IQM (crowded tissue), one just below it does
 * not. */
static void test_omega3_by_snr_in_crowded_tissue(void)
{
    start_with_floor();
    sfsm_input_t in = base();
    in.iqm = 2.5; /* neighbours close in feature space: far below γ3 */
    in.snr = cfg.snr_isolate - 0.5;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_GRADIENT_SEARCH, out.state);
    TEST_ASSERT_TRUE(out.move_um > 0.0);
    in.snr = cfg.snr_isolate;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
    sfsm_config_t bad = cfg;
    bad.snr_isolate = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
    bad.snr_isolate = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sfsm_config_check(&bad));
}

/* Ω3 from Spike Search, Gradient Search, Isolate Neuron and Window Limit
 * (no reference there), and a louder other track while isolated. */
static void test_omega3_isolates_without_a_reference(void)
{
    void (*const reach[3])(void) = {start, to_gradient_search, to_isolate};
    for (size_t k = 0u; k < 3u; ++k) {
        reach[k]();
        sfsm_input_t in = base();
        in.iqm = 5.0;
        in.snr = 4.0;
        in.dominant_track = TRACK_B;
        run(&in, 1u);
        TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
        TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
        TEST_ASSERT_EQUAL_UINT32(TRACK_B, sm.ref_track);
    }
    /* from Window Limit too */
    start();
    sfsm_input_t edge = base();
    edge.has_dominant = false;
    edge.depth_um = 5000.0;
    run(&edge, 1u);
    edge.depth_um = 0.0;
    run(&edge, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_WINDOW_LIMIT, out.state);
    sfsm_input_t in = base();
    in.iqm = 6.0;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    /* isolated on A; B appears with Ω3: isolate B instead */
    to_isolated();
    in = base();
    in.iqm = 2.0;
    in.dominant_track = TRACK_B;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_UINT32(TRACK_A, sm.ref_track);
    in.iqm = 5.5;
    in.snr = 7.9; /* Ω3 but not louder than the isolated neuron (8): no switch */
    run(&in, 1u);
    TEST_ASSERT_EQUAL_UINT32(TRACK_A, sm.ref_track);
    in.snr = 11.0;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    TEST_ASSERT_EQUAL_UINT32(TRACK_B, sm.ref_track);
    TEST_ASSERT_GREATER_OR_EQUAL_INT(0, out.row);
}

/* No dominant track for lost_cycles cycles → Spike Search; one fewer, then a
 * track again, → stay. The electrode holds while the neuron is missing. */
static void test_losing_all_spikes(void)
{
    void (*const reach[5])(void) = {to_gradient_search, to_isolate, to_isolated, to_reestimate, to_reisolate};
    for (size_t k = 0u; k < 5u; ++k) {
        reach[k]();
        const sfsm_state_t here = sm.state;
        sfsm_input_t none = base();
        none.has_dominant = false;
        none.spikes_seen = false;
        sfsm_input_t back = base();
        back.snr = 6.0;
        back.suggestion.m_star = 1u;
        run(&none, cfg.lost_cycles - 1u);
        TEST_ASSERT_EQUAL_INT(here, out.state);
        TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
        TEST_ASSERT_EQUAL_INT((here == SFSM_NEURON_ISOLATED) ? SFSM_R_ISOLATED_HOLD : SFSM_R_NO_DOMINANT_HOLD,
                              out.reason);
        run(&back, 1u);
        TEST_ASSERT_EQUAL_INT(here, out.state);
        run(&none, cfg.lost_cycles);
        TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
        TEST_ASSERT_DOUBLE_WITHIN(0.0, 20.0, out.move_um);
        TEST_ASSERT_FALSE(sm.has_ref);
    }
}

/* Spike Search with no dominant track from depth `from`, following its own
 * steps for n cycles; returns the deepest and shallowest depths reached. */
static void search_blind(double from, unsigned n, double *lo, double *hi, double *at)
{
    sfsm_input_t none = base();
    none.has_dominant = false;
    none.spikes_seen = false;
    none.depth_um = from;
    *lo = from;
    *hi = from;
    for (unsigned i = 0u; i < n; ++i) {
        TEST_ASSERT_EQUAL_INT(MD_OK, cycle(&none));
        TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
        none.depth_um += out.move_um;
        *lo = fmin(*lo, none.depth_um);
        *hi = fmax(*hi, none.depth_um);
    }
    *at = none.depth_um;
}

/* A neuron isolated at 1000 µm falls silent: Spike Search walks out one
 * span, turns, walks through the neuron's depth to one span on the other
 * side, turns again and then searches on into new tissue. */
static void test_search_leash_looks_both_sides_of_a_lost_neuron(void)
{
    to_isolated();
    sfsm_input_t none = base();
    none.has_dominant = false;
    none.spikes_seen = false;
    run(&none, cfg.lost_cycles);
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
    double lo = 0.0, hi = 0.0, at = 0.0;
    /* from 1020: 4 steps out to 1100, 10 back to 900, 15 on to 1200 */
    search_blind(1000.0 + out.move_um, 29u, &lo, &hi, &at);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 900.0, lo);
    TEST_ASSERT_EQUAL_UINT8(SFSM_LEASH_TURNS, sm.leash_turns);
    TEST_ASSERT_EQUAL_INT(1, sm.search_dir);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1200.0, at);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1200.0, hi);
    TEST_ASSERT_EQUAL_UINT8(0u, sm.reversals); /* no window-edge reversal counted */
    /* a dominant track anywhere sets a new anchor with a fresh leash */
    sfsm_input_t seen = base();
    seen.depth_um = at;
    seen.spikes_seen = false;
    run(&seen, 1u);
    TEST_ASSERT_EQUAL_UINT8(0u, sm.leash_turns);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, at, sm.anchor_um);
}

/* No dominant track yet: nothing to return to, the search goes on; span 0
 * switches the leash off. */
static void test_search_leash_needs_an_anchor_and_a_span(void)
{
    start();
    double lo = 0.0, hi = 0.0, at = 0.0;
    search_blind(1000.0, 20u, &lo, &hi, &at);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1400.0, at);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1000.0, lo);
    to_isolated();
    sm.cfg.search_span_um = 0.0;
    sfsm_input_t none = base();
    none.has_dominant = false;
    none.spikes_seen = false;
    run(&none, cfg.lost_cycles);
    search_blind(1000.0, 20u, &lo, &hi, &at);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1000.0, lo);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1400.0, at);
}

static void test_window_edges(void)
{
    start();
    sfsm_input_t in = base();
    in.has_dominant = false;
    in.depth_um = 4990.0; /* Δsearch shortened to the edge */
    run(&in, 1u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 10.0, out.move_um);
    TEST_ASSERT_TRUE(out.clamped);
    in.depth_um = 5000.0; /* at the deep edge: reverse the search */
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
    TEST_ASSERT_EQUAL_INT(-1, sm.search_dir);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, -20.0, out.move_um);
    in.depth_um = 0.0; /* the other edge too: stop and wait for the operator */
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_WINDOW_LIMIT, out.state);
    run(&in, 4u);
    TEST_ASSERT_EQUAL_INT(SFSM_WINDOW_LIMIT, out.state);
    TEST_ASSERT_EQUAL_INT(SFSM_R_WINDOW_HOLD, out.reason);
    in.resume = true;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
    TEST_ASSERT_EQUAL_INT(1, sm.search_dir);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 20.0, out.move_um);
}

/* Every other state at an edge of the window, and a depth outside it. */
static void test_window_edges_other_states(void)
{
    /* Gradient Search at the edge: back to Spike Search, reversed */
    to_gradient_search();
    sfsm_input_t in = base();
    in.depth_um = 5000.0;
    in.suggestion.m_star = 1u;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
    TEST_ASSERT_EQUAL_INT(-1, sm.search_dir);
    /* Isolate Neuron pushing out of the window: with IQM >= γ2 the edge is the
     * best reachable position (declare), below γ2 stop and wait */
    to_isolate();
    in = base();
    in.depth_um = 5000.0;
    in.iqm = 3.2;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    to_isolate();
    in.iqm = 2.5;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_WINDOW_LIMIT, out.state);
    /* Re-Estimate retracting into the shallow edge */
    to_reestimate();
    in = base();
    in.snr = 6.0;
    in.depth_um = 0.2;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_WINDOW_LIMIT, out.state);
    /* Outside the window (operator narrowed it): outward steps become zero */
    start();
    in = base();
    in.has_dominant = false;
    in.depth_um = 6000.0;
    in.depth_min_um = 0.0;
    in.depth_max_um = 5000.0;
    run(&in, 1u);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, -20.0, out.move_um); /* reversed, moving back in */
}

/* E-stop or fault → HALTED from every state; nothing moves until resume. */
static void test_halt_and_resume(void)
{
    void (*const reach[6])(void) = {start, to_gradient_search, to_isolate, to_isolated, to_reestimate, to_reisolate};
    for (size_t k = 0u; k < 6u; ++k) {
        reach[k]();
        sfsm_input_t in = base();
        in.estop = (k % 2u) == 0u;
        in.fault = !in.estop;
        run(&in, 1u);
        TEST_ASSERT_EQUAL_INT(SFSM_HALTED, out.state);
        TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
        TEST_ASSERT_EQUAL_INT(SFSM_R_HALTED, out.reason);
    }
    /* resume is refused while the cause persists */
    sfsm_input_t in = base();
    in.fault = true;
    in.resume = true;
    run(&in, 3u);
    TEST_ASSERT_EQUAL_INT(SFSM_HALTED, out.state);
    in.fault = false;
    in.resume = false;
    in.iqm = 9.0; /* even Ω3 does not leave HALTED */
    run(&in, 3u);
    TEST_ASSERT_EQUAL_INT(SFSM_HALTED, out.state);
    in.resume = true;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state); /* resumed: one row per cycle */
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 20.0, out.move_um);
    in.resume = false;
    run(&in, 1u);
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state); /* then Ω3 */
}

/* Random inputs for many cycles in HALTED without resume: never a step. */
static void test_no_motion_while_halted(void)
{
    start();
    sfsm_input_t in = base();
    in.estop = true;
    run(&in, 1u);
    md_rng_t rng;
    md_rng_seed(&rng, 3u);
    for (unsigned i = 0u; i < 500u; ++i) {
        in = base();
        in.has_dominant = md_rng_uniform(&rng) < 0.8;
        in.dominant_track = md_rng_below(&rng, 3u);
        in.snr = 20.0 * md_rng_uniform(&rng);
        in.iqm = 8.0 * md_rng_uniform(&rng);
        in.spikes_seen = md_rng_uniform(&rng) < 0.5;
        in.estop = md_rng_uniform(&rng) < 0.5;
        in.fault = md_rng_uniform(&rng) < 0.5;
        in.suggestion.converged = md_rng_uniform(&rng) < 0.3;
        in.suggestion.move_um = 60.0 * md_rng_uniform(&rng) - 30.0;
        (void)cycle(&in);
        TEST_ASSERT_EQUAL_INT(SFSM_HALTED, out.state);
        TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
    }
}

static void test_invalid_input_halts_and_is_counted(void)
{
    to_isolate();
    sfsm_input_t in = base();
    in.depth_um = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, cycle(&in));
    TEST_ASSERT_EQUAL_INT(SFSM_HALTED, out.state);
    TEST_ASSERT_EQUAL_INT(SFSM_R_BAD_INPUT, out.reason);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
    in = base();
    in.snr = INFINITY;
    in.resume = true;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, cycle(&in));
    in = base();
    in.depth_min_um = 6000.0;
    in.resume = true;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, cycle(&in));
    in = base();
    in.suggestion.move_um = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, cycle(&in));
    TEST_ASSERT_EQUAL_UINT32(4u, sm.bad_inputs);
    TEST_ASSERT_EQUAL_INT(SFSM_HALTED, out.state);
    in = base();
    in.resume = true;
    TEST_ASSERT_EQUAL_INT(MD_OK, cycle(&in));
    TEST_ASSERT_EQUAL_INT(SFSM_SPIKE_SEARCH, out.state);
}

/* Isolated on TRACK_A (reference 8 at 1000 µm) with the settled approach on
 * (5 µm, 3 % per step); the R-cycle window at 1000 µm is full. */
static void to_isolated_approaching(void)
{
    to_isolated();
    cfg.approach_um = 5.0;
    cfg.approach_gain = 0.03;
    sm.cfg = cfg;
}

/* The isolated neuron as the approach sees it: well isolated (IQM above γ3). */
static sfsm_input_t isolated_input(double depth, double snr)
{
    sfsm_input_t in = base();
    converged(&in);
    in.iqm = cfg.gamma3 + 0.5;
    in.snr = snr;
    in.depth_um = depth;
    in.settled = true;
    return in;
}

/* The first approach step, from a full window at 1000 µm. */
static void first_approach_step(void)
{
    sfsm_input_t in = isolated_input(1000.0, 8.0);
    in.settled = false;
    run(&in, cfg.wait_r);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
    in.settled = true;
    run(&in, 1u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 5.0, out.move_um);
    TEST_ASSERT_EQUAL_INT(SFSM_R_APPROACH, out.reason);
}

/* R cycles of the isolated neuron at `depth` with `snr`, the tissue settled;
 * returns the last output's step. */
static double stand(double depth, double snr)
{
    const sfsm_input_t in = isolated_input(depth, snr);
    for (unsigned i = 0u; i + 1u < cfg.wait_r; ++i) {
        TEST_ASSERT_EQUAL_INT(MD_OK, cycle(&in));
        TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um); /* the window at this depth is not full yet */
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, cycle(&in));
    TEST_ASSERT_EQUAL_INT(SFSM_NEURON_ISOLATED, out.state);
    return out.move_um;
}

/* Settled approach (ours): Ω3 stops the tip short of the neuron's SNR peak;
 * once the tissue has settled the tip closes in on a well-isolated neuron by
 * approach_um while each step raises the SNR by approach_gain, and stays
 * where the gain ran out. The reference moves with it. In crowded tissue
 * (mean IQM below γ3) it holds. */
static void test_settled_approach_climbs_to_the_peak_and_stays(void)
{
    to_isolated_approaching();
    sfsm_input_t in = isolated_input(1000.0, 8.0);
    in.iqm = cfg.gamma3 - 0.5; /* crowded: isolated by loudness, not by its moat */
    run(&in, 3u * cfg.wait_r);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, out.move_um);
    TEST_ASSERT_FALSE(sfsm_holds_lone_neuron(&sm));
    first_approach_step(); /* well isolated; the tissue settles on the last cycle */
    TEST_ASSERT_TRUE(sfsm_holds_lone_neuron(&sm));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 5.0, stand(1005.0, 9.0)); /* +12.5 %: on */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 9.0, sm.ref_snr);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1005.0, sm.ref_depth_um);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, stand(1010.0, 9.1)); /* +1.1 %: stay here */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1010.0, sm.ref_depth_um);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 9.1, sm.ref_snr);
    TEST_ASSERT_TRUE(sm.approach_done);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, stand(1010.0, 9.5)); /* done: the reference ratchet takes over */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 9.5, sm.ref_snr);
    TEST_ASSERT_EQUAL_UINT32(2u, sm.approach_steps);
}

/* A step past the peak lowers the SNR: one step back, and the approach ends. */
static void test_settled_approach_steps_back_past_the_peak(void)
{
    to_isolated_approaching();
    first_approach_step();
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, -5.0, stand(1005.0, 7.6));
    TEST_ASSERT_EQUAL_INT(SFSM_R_APPROACH_BACK, out.reason);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1000.0, sm.ref_depth_um);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 8.0, sm.ref_snr);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, stand(1000.0, 8.0));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, stand(1000.0, 8.0));
}

/* Every approach step passes the approach guard: a step it cut (the depth
 * did not change) or a retraction behind the step's start ends the
 * approach; a new isolation starts a new one. Off (approach_um 0): hold. */
static void test_settled_approach_ends_where_the_guard_stopped_it(void)
{
    to_isolated_approaching();
    first_approach_step();
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, stand(1000.0, 8.0)); /* the guard held the tip */
    TEST_ASSERT_TRUE(sm.approach_done);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, stand(1000.0, 9.0));
    to_isolated_approaching();
    first_approach_step();
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, stand(990.0, 7.0)); /* the guard retracted */
    TEST_ASSERT_TRUE(sm.approach_done);
    sfsm_input_t in = base(); /* Ω3 declares a new isolation: a new approach */
    in.iqm = cfg.gamma3 + 1.0;
    in.snr = 10.0;
    in.dominant_track = TRACK_B;
    in.depth_um = 990.0;
    run(&in, 1u);
    TEST_ASSERT_FALSE(sm.approach_done);
    TEST_ASSERT_FALSE(sfsm_holds_lone_neuron(NULL));
    to_gradient_search();
    TEST_ASSERT_FALSE(sfsm_holds_lone_neuron(&sm));
    to_isolated(); /* off */
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, stand(1000.0, 8.0));
    TEST_ASSERT_EQUAL_UINT32(0u, sm.approach_steps);
}

/* Random plausible inputs over long runs: every step within ±Δmax and inside
 * the window; zero in the hold states (checked in cycle()). */
static void test_steps_bounded_under_random_inputs(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 99u);
    for (unsigned run_i = 0u; run_i < 20u; ++run_i) {
        start();
        cfg.approach_um = (run_i % 2u == 0u) ? 0.0 : 5.0;
        sm.cfg = cfg;
        double depth = 2500.0;
        for (unsigned k = 0u; k < 300u; ++k) {
            sfsm_input_t in = base();
            in.depth_um = depth;
            in.has_dominant = md_rng_uniform(&rng) < 0.85;
            in.dominant_track = 1u + md_rng_below(&rng, 2u);
            in.snr = 2.0 + 10.0 * md_rng_uniform(&rng);
            in.iqm = 6.0 * md_rng_uniform(&rng);
            in.spikes_seen = md_rng_uniform(&rng) < 0.7;
            in.suggestion.ready = md_rng_uniform(&rng) < 0.8;
            in.suggestion.m_star = (uint8_t)(1u + md_rng_below(&rng, 4u));
            in.suggestion.converged = md_rng_uniform(&rng) < 0.2;
            in.suggestion.move_um = 200.0 * md_rng_uniform(&rng) - 100.0;
            in.estop = md_rng_uniform(&rng) < 0.01;
            in.resume = md_rng_uniform(&rng) < 0.05;
            in.settled = md_rng_uniform(&rng) < 0.5;
            TEST_ASSERT_EQUAL_INT(MD_OK, cycle(&in));
            depth += out.move_um;
        }
    }
}

/* Runs last: every row of the table fired somewhere above. */
static void test_every_row_was_exercised(void)
{
    size_t n = 0u;
    (void)sfsm_table(&n);
    for (size_t i = 0u; i < n; ++i) {
        TEST_ASSERT_MESSAGE(fired[i] > 0u, "a transition-table row never fired");
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_config_defaults_and_checks);
    RUN_TEST(test_noise_floor_never_isolates);
    RUN_TEST(test_noise_floor_counts_as_lost);
    RUN_TEST(test_spike_search_steps_then_finds_spikes);
    RUN_TEST(test_gradient_search_waits_r_cycles);
    RUN_TEST(test_isolate_follows_the_optimiser);
    RUN_TEST(test_isolate_declares_after_r_converged_cycles);
    RUN_TEST(test_isolate_falls_back_to_gradient_search);
    RUN_TEST(test_isolated_snr_drop_rule);
    RUN_TEST(test_isolated_reference_follows_a_louder_neuron);
    RUN_TEST(test_reestimate_to_reisolate_and_back);
    RUN_TEST(test_reisolate_exits);
    RUN_TEST(test_other_dominant_is_adopted);
    RUN_TEST(test_snr_drop_ignores_alternating_ids);
    RUN_TEST(test_gradient_search_turns_when_snr_falls);
    RUN_TEST(test_omega3_isolates_from_any_state);
    RUN_TEST(test_omega3_isolates_without_a_reference);
    RUN_TEST(test_omega3_by_snr_in_crowded_tissue);
    RUN_TEST(test_losing_all_spikes);
    RUN_TEST(test_search_leash_looks_both_sides_of_a_lost_neuron);
    RUN_TEST(test_search_leash_needs_an_anchor_and_a_span);
    RUN_TEST(test_window_edges);
    RUN_TEST(test_window_edges_other_states);
    RUN_TEST(test_halt_and_resume);
    RUN_TEST(test_no_motion_while_halted);
    RUN_TEST(test_invalid_input_halts_and_is_counted);
    RUN_TEST(test_settled_approach_climbs_to_the_peak_and_stays);
    RUN_TEST(test_settled_approach_steps_back_past_the_peak);
    RUN_TEST(test_settled_approach_ends_where_the_guard_stopped_it);
    RUN_TEST(test_steps_bounded_under_random_inputs);
    RUN_TEST(test_every_row_was_exercised);
    return UNITY_END();
}
