/// @file md_params.c
/// The parameter table and its checks. See md_params.h.
#include "md_params.h"

#include <math.h>

#include "tracking/mhtc.h"

#define RO_LIVE ((uint8_t)(MD_PARAM_F_READ_ONLY | MD_PARAM_F_LIVE | MD_PARAM_F_INTEGER))
#define U32_MAX_D 4294967295.0

/* Rows in md_param_id_t order; indices strictly increasing (checked). The
 * heartbeat defaults follow the DBC's GenMsgCycleTime of 100 ms: a consumer
 * timeout of 5 periods tolerates a few late frames on a loaded host. The
 * closed-loop rows are placeholders with the thesis' step sizes (§2.2.4:
 * Delta_search 20 um, Delta_sample 10 um, Delta_resample 5 um). */
static const md_param_def_t PARAM_TABLE[MD_P_COUNT] = {
    [MD_P_EMCY_INHIBIT_MS] = {0x1015u, "emcy_inhibit_ms", "ms", 0.0, 60000.0, 1000.0, MD_PARAM_F_INTEGER,
                              "minimum gap between two protocol-error EMCYs (others are never inhibited)"},
    [MD_P_HEARTBEAT_TIMEOUT_MS] = {0x1016u, "heartbeat_timeout_ms", "ms", 20.0, 60000.0, 500.0, MD_PARAM_F_INTEGER,
                                   "silence after which a monitored node counts as lost"},
    [MD_P_HEARTBEAT_PERIOD_MS] = {0x1017u, "heartbeat_period_ms", "ms", 10.0, 10000.0, 100.0, MD_PARAM_F_INTEGER,
                                  "period of HEARTBEAT_CTRL"},
    [MD_P_MONITOR_ACT] = {0x1020u, "monitor_act", "", 0.0, 1.0, 1.0, MD_PARAM_F_INTEGER,
                          "1: supervise the actuator driver's heartbeat"},
    [MD_P_MONITOR_HALL] = {0x1021u, "monitor_hall", "", 0.0, 1.0, 1.0, MD_PARAM_F_INTEGER,
                           "1: supervise the position sensor's heartbeat"},
    [MD_P_MONITOR_FE] = {0x1022u, "monitor_fe", "", 0.0, 1.0, 1.0, MD_PARAM_F_INTEGER,
                         "1: supervise the front-end's heartbeat"},
    [MD_P_AUTO_START] = {0x1F80u, "auto_start", "", 0.0, 1.0, 0.0, MD_PARAM_F_INTEGER,
                         "1: enter operational by itself after boot (never while the e-stop is latched)"},
    [MD_P_INTERVAL_S] = {0x2000u, "interval_s", "s", 1.0, 120.0, 10.0, MD_PARAM_F_CONFIG,
                         "length of one recording interval"},
    [MD_P_MOVE_MAX_UM] = {0x2001u, "move_max_um", "um", 1.0, 200.0, 30.0, MD_PARAM_F_MOTION,
                          "Delta_max: cap of one electrode step"},
    [MD_P_MOVE_SEARCH_UM] = {0x2002u, "move_search_um", "um", 1.0, 200.0, 20.0, MD_PARAM_F_MOTION,
                             "Delta_search: step while searching for spikes"},
    [MD_P_MOVE_SAMPLE_UM] = {0x2003u, "move_sample_um", "um", 1.0, 200.0, 10.0, MD_PARAM_F_MOTION,
                             "Delta_sample: step while sampling the SNR curve"},
    [MD_P_MOVE_RESAMPLE_UM] = {0x2004u, "move_resample_um", "um", 1.0, 200.0, 5.0, MD_PARAM_F_MOTION,
                               "Delta_resample: retracting step while re-estimating the gradient"},
    [MD_P_DEPTH_MIN_UM] = {0x2010u, "depth_min_um", "um", 0.0, 20000.0, 0.0, MD_PARAM_F_MOTION,
                           "depth window, shallow end (must stay below depth_max_um)"},
    [MD_P_DEPTH_MAX_UM] = {0x2011u, "depth_max_um", "um", 0.0, 20000.0, 5000.0, MD_PARAM_F_MOTION,
                           "depth window, deep end (must stay above depth_min_um)"},
    [MD_P_SETTLE_MS] = {0x2012u, "settle_ms", "ms", 0.0, 60000.0, 500.0, MD_PARAM_F_INTEGER,
                        "wait after a move before the next recording (SIM_ADVANCE in lockstep)"},
    [MD_P_MIN_RATE_HZ] = {0x2013u, "min_rate_hz", "Hz", 0.0, 100.0, 0.5, 0u,
                          "detections per second that count as spikes seen (SFSM Spike Search)"},
    [MD_P_SERVO_TOL_UM] = {0x2020u, "servo_tol_um", "um", 0.1, 20.0, 2.0, MD_PARAM_F_MOTION,
                           "servo converged within this distance of the target (Hall depth)"},
    [MD_P_SERVO_MAX_ITER] = {0x2021u, "servo_max_iter", "", 1.0, 32.0, 8.0, MD_PARAM_F_MOTION | MD_PARAM_F_INTEGER,
                             "servo step commands per move at most"},
    [MD_P_SERVO_AVG_N] = {0x2022u, "servo_avg_n", "", 1.0, 16.0, 5.0, MD_PARAM_F_INTEGER,
                          "Hall readings averaged per depth measurement"},
    [MD_P_SERVO_STEP_NM] = {0x2023u, "servo_step_nm", "nm", 1.0, 1000.0, 40.0, MD_PARAM_F_MOTION,
                            "initial estimate of one piezo step (learned per direction from the Hall depth)"},
    [MD_P_SERVO_RATE_HZ] = {0x2024u, "servo_rate_hz", "Hz", 1.0, 5000.0, 1000.0, MD_PARAM_F_MOTION | MD_PARAM_F_INTEGER,
                            "piezo step rate of ACT_CMD"},
    [MD_P_SFSM_GAMMA1] = {0x2030u, "sfsm_gamma1", "", 0.1, 100.0, 2.0, MD_PARAM_F_MOTION,
                          "SFSM gamma1: isolation distance to follow the SNR gradient (< gamma2)"},
    [MD_P_SFSM_GAMMA2] = {0x2031u, "sfsm_gamma2", "", 0.1, 100.0, 3.0, MD_PARAM_F_MOTION,
                          "SFSM gamma2: isolation distance to declare isolation at the peak (< gamma3)"},
    [MD_P_SFSM_GAMMA3] = {0x2032u, "sfsm_gamma3", "", 0.1, 100.0, 12.0, MD_PARAM_F_MOTION,
                          "SFSM gamma3: isolation distance to declare isolation at once"},
    [MD_P_SFSM_WAIT_R] = {0x2033u, "sfsm_wait_r", "", 1.0, 8.0, 3.0, MD_PARAM_F_MOTION | MD_PARAM_F_INTEGER,
                          "SFSM R: cycles a WAIT condition must hold"},
    [MD_P_SFSM_LOST_CYCLES] = {0x2034u, "sfsm_lost_cycles", "", 1.0, 100.0, 5.0, MD_PARAM_F_MOTION | MD_PARAM_F_INTEGER,
                               "SFSM cycles without a dominant track before Spike Search"},
    [MD_P_SFSM_SNR_DROP] = {0x2035u, "sfsm_snr_drop", "", 0.05, 0.99, 0.85, MD_PARAM_F_MOTION,
                            "SFSM: leave Neuron Isolated below this fraction of the isolation SNR"},
    [MD_P_SC_TOL_UM] = {0x2036u, "sc_tol_um", "um", 0.1, 50.0, 2.5, MD_PARAM_F_MOTION,
                        "SNR-curve optimiser: eq. 2.1 step below this counts as converged"},
    [MD_P_SFSM_SNR_MIN] = {0x2037u, "sfsm_snr_min", "", 0.0, 100.0, 9.0, MD_PARAM_F_MOTION,
                           "SFSM noise floor: a track below this SNR is never dominant (no isolation on noise)"},
    [MD_P_SFSM_SEARCH_SPAN_UM] = {0x2038u, "sfsm_search_span_um", "um", 0.0, 5000.0, 100.0, MD_PARAM_F_MOTION,
                                  "SFSM: Spike Search turns this far past the last depth with a dominant track "
                                  "(twice at most, then searches on; 0: never)"},
    [MD_P_SFSM_SNR_ISOLATE] = {0x2039u, "sfsm_snr_isolate", "", 1.0, 1000.0, 24.0, MD_PARAM_F_MOTION,
                               "SFSM: a dominant track this loud declares isolation at once, whatever its IQM "
                               "(Omega3 by loudness)"},
    [MD_P_SFSM_APPROACH_UM] = {0x203Au, "sfsm_approach_um", "um", 0.0, 50.0, 0.0, MD_PARAM_F_MOTION,
                               "SFSM: once the tissue has settled, Neuron Isolated steps this far towards the "
                               "neuron while its SNR rises (0: hold; <= move_max_um)"},
    [MD_P_SFSM_APPROACH_GAIN] = {0x203Bu, "sfsm_approach_gain", "", 0.0, 1.0, 0.03, MD_PARAM_F_MOTION,
                                 "SFSM: relative SNR rise over one settled-approach step that earns the next"},
    [MD_P_MHTC_Q_UV] = {0x2040u, "mhtc_q_uv", "uV", 0.01, 1000.0, 10.0, MD_PARAM_F_CONFIG,
                        "MHTC process noise std per waveform sample and interval"},
    [MD_P_TRACKER] = {0x2041u, "tracker", "", 0.0, 3.0, 0.0, MD_PARAM_F_CONFIG | MD_PARAM_F_INTEGER,
                      "tracker: 0 MHTC, 1 MAP-NN, 2 ML-NN, 3 GNN baseline (a change restarts the tracks)"},
    [MD_P_MHTC_UNIMODAL_RATIO] = {0x2042u, "mhtc_unimodal_ratio", "", 0.0, 1.0, MHTC_UNIMODAL_RATIO_DEFAULT,
                                  MD_PARAM_F_CONFIG,
                                  "clustering (every tracker): a model whose clusters include a pair with this "
                                  "ridgeline ratio or more (one mode) is dropped; 0 keeps every model"},
    [MD_P_MHTC_COUNT_SIGMA] = {0x2043u, "mhtc_count_sigma", "", 0.0, 100.0, MHTC_COUNT_SIGMA_DEFAULT, MD_PARAM_F_CONFIG,
                               "MHTC: a cluster continuing a track whose spike count differs by "
                               "a factor e^s from the track's last costs half a nat; 0: no count term"},
    [MD_P_MHTC_LAMBDA_FIRST] = {0x2044u, "mhtc_lambda_first", "", 0.0001, 1.0, MHTC_LAMBDA_FIRST_DEFAULT,
                                MD_PARAM_F_CONFIG,
                                "MHTC: density of new neurons in the first interval after a (re)start; above "
                                "lambda_false (0.015) a cluster seen then is a track at once"},
    [MD_P_GUARD_ENABLE] = {0x2050u, "guard_enable", "", 0.0, 1.0, 1.0, MD_PARAM_F_MOTION | MD_PARAM_F_INTEGER,
                           "approach guard limits motion (0: it is computed and reported, never applied)"},
    [MD_P_GUARD_GROWTH_STOP] = {0x2051u, "guard_growth_stop", "1/um", 0.001, 1.0, 0.022, MD_PARAM_F_MOTION,
                                "approach guard: amplitude growth (ln per um of advance) that blocks advancing"},
    [MD_P_GUARD_AMP_SLOW] = {0x2052u, "guard_amp_slow", "", 1.0, 1000.0, 15.0, MD_PARAM_F_MOTION,
                             "approach guard: robust amplitude (noise RMS units) from which advances are shortened"},
    [MD_P_GUARD_AMP_STOP] = {0x2053u, "guard_amp_stop", "", 1.0, 1000.0, 80.0, MD_PARAM_F_MOTION,
                             "approach guard: robust amplitude that blocks advancing (> guard_amp_slow)"},
    [MD_P_GUARD_MOVE_NEAR_UM] = {0x2054u, "guard_move_near_um", "um", 0.5, 100.0, 10.0, MD_PARAM_F_MOTION,
                                 "approach guard: longest advance at or above guard_amp_slow"},
    [MD_P_GUARD_RETRACT_UM] = {0x2055u, "guard_retract_um", "um", 0.5, 100.0, 10.0, MD_PARAM_F_MOTION,
                               "approach guard: retraction when the unit comes closer while the electrode stands"},
    [MD_P_GUARD_CLIMB_FRAC] = {0x2056u, "guard_climb_frac", "", 0.01, 2.0, 0.15, MD_PARAM_F_MOTION,
                               "approach guard: rise of a unit over its lowest level at a standstill that retracts"},
    [MD_P_GUARD_GROWTH_SLOW] = {0x2057u, "guard_growth_slow", "1/um", 0.0001, 1.0, 0.011, MD_PARAM_F_MOTION,
                                "approach guard: growth on the last advance from which a unit at guard_amp_slow "
                                "shortens advances (<= guard_growth_stop)"},
    [MD_P_GUARD_GROWTH_MAX] = {0x2058u, "guard_growth_max", "1/um", 0.001, 1.0, 1.0 / 30.0, MD_PARAM_F_MOTION,
                               "approach guard: steepest ln-amplitude growth per um of approach of any unit (1 / d0; "
                               ">= guard_growth_stop)"},
    [MD_P_GUARD_FENCE_DROP] = {0x2059u, "guard_fence_drop", "", 0.01, 0.9, 0.15, MD_PARAM_F_MOTION,
                               "approach guard: fall of the level at the depth fence that moves the fence deeper"},
    [MD_P_GUARD_FENCE_LAPSE] = {0x205Au, "guard_fence_lapse", "", 1.0, 1000.0, 30.0,
                                MD_PARAM_F_MOTION | MD_PARAM_F_INTEGER,
                                "approach guard: intervals with no unit at the amplitude floor after which a depth "
                                "fence lapses"},
    [MD_P_GUARD_RELAX_FRAC] = {0x205Bu, "guard_relax_frac", "", 0.001, 0.9, 0.24, MD_PARAM_F_MOTION,
                               "approach guard: share of an advance the tissue gives back towards the tip"},
    [MD_P_GUARD_RELAX_TAU_S] = {0x205Cu, "guard_relax_tau_s", "s", 1.0, 3600.0, 120.0, MD_PARAM_F_MOTION,
                                "approach guard: time constant of the tissue's give-back"},
    [MD_P_GUARD_PROBE_UM] = {0x205Du, "guard_probe_um", "um", 0.5, 50.0, 5.0, MD_PARAM_F_MOTION,
                             "approach guard: advance past the depth fence that measures whether the unit there is "
                             "ahead"},
    [MD_P_GUARD_CREEP_HORIZON_S] = {0x205Eu, "guard_creep_horizon_s", "s", 1.0, 3600.0, 30.0, MD_PARAM_F_MOTION,
                                    "approach guard: the tissue's give-back due within this time limits advances and "
                                    "retracts"},
    [MD_P_GUARD_CEILING_CLIMB] = {0x205Fu, "guard_ceiling_climb", "", 0.01, 2.0, 0.06, MD_PARAM_F_MOTION,
                                  "approach guard: rise of a unit's standing level over its ceiling that retracts "
                                  "(<= guard_climb_frac)"},
    [MD_P_GUARD_BASELINE_UM] = {0x2060u, "guard_baseline_um", "um", 1.0, 100.0, 15.0, MD_PARAM_F_MOTION,
                                "approach guard: shortest advance over which a unit's growth is measured"},
    [MD_P_GUARD_BASELINE_NEW_UM] = {0x2061u, "guard_baseline_new_um", "um", 1.0, 100.0, 8.0, MD_PARAM_F_MOTION,
                                    "approach guard: shortest advance over which the growth of a unit first seen "
                                    "less than guard_baseline_um back is measured (<= guard_baseline_um)"},
    [MD_P_GUARD_PACE_UM] = {0x2062u, "guard_pace_um", "um", 0.0, 1000.0, 0.0, MD_PARAM_F_MOTION,
                            "approach guard: most tissue give-back an advance in active tissue may leave to come "
                            "(0: no limit)"},
    [MD_P_GUARD_SETTLE_UM] = {0x2063u, "guard_settle_um", "um", 0.0, 100.0, 2.0, MD_PARAM_F_MOTION,
                              "approach guard: tissue give-back still to come at or below which the tissue "
                              "counts as settled (the SFSM's settled approach waits for it)"},
    [MD_P_GUARD_FOLLOW] = {0x2064u, "guard_follow", "", 0.0, 1.0, 0.0, MD_PARAM_F_MOTION | MD_PARAM_F_INTEGER,
                           "approach guard: a tip the SFSM lets stand in loud tissue retracts by the tissue's "
                           "give-back as it comes (1) or stands (0)"},
    [MD_P_GUARD_NEAR_SCALE] = {0x2065u, "guard_near_scale", "", 0.0, 1.0, 0.0, MD_PARAM_F_MOTION | MD_PARAM_F_INTEGER,
                               "approach guard: advances towards a loud unit are at most guard_move_near_um times "
                               "guard_amp_slow over its amplitude (1) or guard_move_near_um (0)"},
    [MD_P_NODE_STATE] = {0x3000u, "node_state", "", 0.0, 255.0, 0.0, RO_LIVE, "NMT state (HEARTBEAT NodeState)"},
    [MD_P_ESTOP_LATCHED] = {0x3001u, "estop_latched", "", 0.0, 1.0, 0.0, RO_LIVE, "1 while the e-stop is latched"},
    [MD_P_UPTIME_S] = {0x3002u, "uptime_s", "s", 0.0, U32_MAX_D, 0.0, RO_LIVE, "seconds since power-on"},
    [MD_P_RX_FRAMES] = {0x3010u, "rx_frames", "", 0.0, U32_MAX_D, 0.0, RO_LIVE, "frames received"},
    [MD_P_RX_MALFORMED] = {0x3011u, "rx_malformed", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                           "frames rejected for their form: bad length/FD flag, signal out of range, invalid frame"},
    [MD_P_RX_UNKNOWN_ID] = {0x3012u, "rx_unknown_id", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                            "frames whose id the DBC does not define (29-bit ids included)"},
    [MD_P_RX_BAD_LENGTH] = {0x3013u, "rx_bad_length", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                            "of rx_malformed: length or FD flag not the DBC's"},
    [MD_P_RX_BAD_RANGE] = {0x3014u, "rx_bad_range", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                           "of rx_malformed: a signal out of its range or not finite"},
    [MD_P_RX_BAD_SEQUENCE] = {0x3015u, "rx_bad_sequence", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                              "stream frames out of sequence (REC_DATA, HALL_READING)"},
    [MD_P_RX_ID_CONFLICT] = {0x3016u, "rx_id_conflict", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                             "frames with an id only the controller may send"},
    [MD_P_TX_FRAMES] = {0x3020u, "tx_frames", "", 0.0, U32_MAX_D, 0.0, RO_LIVE, "frames sent"},
    [MD_P_TX_FAILURES] = {0x3021u, "tx_failures", "", 0.0, U32_MAX_D, 0.0, RO_LIVE, "sends the platform refused"},
    [MD_P_EMCY_SENT] = {0x3022u, "emcy_sent", "", 0.0, U32_MAX_D, 0.0, RO_LIVE, "EMCY_CTRL frames sent"},
    [MD_P_HEARTBEAT_LOST] = {0x3030u, "heartbeat_lost", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                             "monitored nodes that went silent"},
    [MD_P_NODE_BACK] = {0x3031u, "node_back", "", 0.0, U32_MAX_D, 0.0, RO_LIVE, "lost nodes whose heartbeat came back"},
    [MD_P_ESTOP_EVENTS] = {0x3032u, "estop_events", "", 0.0, U32_MAX_D, 0.0, RO_LIVE, "ESTOP frames received"},
    [MD_P_NMT_REFUSED] = {0x3033u, "nmt_refused", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                          "NMT commands refused (start while the e-stop is latched)"},
    [MD_P_CYCLES_DONE] = {0x3040u, "cycles_done", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                          "electrode cycles completed (all electrodes)"},
    [MD_P_CYCLES_SKIPPED] = {0x3041u, "cycles_skipped", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                             "cycles whose processing failed numerically (tracks and SFSM kept)"},
    [MD_P_RECORDINGS_FAILED] = {0x3042u, "recordings_failed", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                                "intervals aborted, out of sequence, incomplete or timed out"},
    [MD_P_MOVES_FAILED] = {0x3043u, "moves_failed", "", 0.0, U32_MAX_D, 0.0, RO_LIVE,
                           "servo moves ended by stall, end stop, fault, missing sensor or timeout"},
};

_Static_assert(sizeof(PARAM_TABLE) / sizeof(PARAM_TABLE[0]) == (size_t)MD_P_COUNT, "one row per id");

size_t md_params_count(void)
{
    return (size_t)MD_P_COUNT;
}

const md_param_def_t *md_params_def(size_t id)
{
    return (id < (size_t)MD_P_COUNT) ? &PARAM_TABLE[id] : NULL;
}

int md_params_find(uint16_t index)
{
    for (size_t i = 0u; i < (size_t)MD_P_COUNT; ++i) {
        if (PARAM_TABLE[i].index == index) {
            return (int)i;
        }
    }
    return -1;
}

md_status_t md_params_table_check(void)
{
    for (size_t i = 0u; i < (size_t)MD_P_COUNT; ++i) {
        const md_param_def_t *d = &PARAM_TABLE[i];
        const bool live_ok = ((d->flags & MD_PARAM_F_LIVE) == 0u) || ((d->flags & MD_PARAM_F_READ_ONLY) != 0u);
        const bool order_ok = (i == 0u) || (PARAM_TABLE[i - 1u].index < d->index);
        if (d->name == NULL || d->unit == NULL || d->doc == NULL || !live_ok || !order_ok ||
            !(d->min <= d->def && d->def <= d->max)) {
            return MD_E_STATE;
        }
    }
    return MD_OK;
}

md_status_t md_params_init(md_params_t *p)
{
    if (p == NULL) {
        return MD_E_ARG;
    }
    const md_status_t st = md_params_table_check();
    if (st != MD_OK) {
        return st;
    }
    for (size_t i = 0u; i < (size_t)MD_P_COUNT; ++i) {
        p->value[i] = PARAM_TABLE[i].def;
    }
    return MD_OK;
}

double md_params_get(const md_params_t *p, md_param_id_t id)
{
    if (p == NULL || (size_t)id >= (size_t)MD_P_COUNT) {
        return 0.0;
    }
    return p->value[id];
}

uint32_t md_params_get_u32(const md_params_t *p, md_param_id_t id)
{
    const double v = md_params_get(p, id);
    if (!(v > 0.0)) {
        return 0u;
    }
    if (v >= U32_MAX_D) {
        return UINT32_MAX;
    }
    return (uint32_t)v;
}

/* Rules that involve more than one row; `id` is about to take `value`. */
static bool cross_rules_ok(const md_params_t *p, md_param_id_t id, double value)
{
    if (id == MD_P_DEPTH_MIN_UM) {
        return value < p->value[MD_P_DEPTH_MAX_UM];
    }
    if (id == MD_P_DEPTH_MAX_UM) {
        return value > p->value[MD_P_DEPTH_MIN_UM];
    }
    return true;
}

md_param_status_t md_params_set(md_params_t *p, uint16_t index, double value)
{
    const int found = md_params_find(index);
    if (p == NULL || found < 0) {
        return MD_PARAM_UNKNOWN_INDEX;
    }
    const md_param_id_t id = (md_param_id_t)found;
    const md_param_def_t *d = &PARAM_TABLE[id];
    if ((d->flags & MD_PARAM_F_READ_ONLY) != 0u) {
        return MD_PARAM_READ_ONLY;
    }
    if (!isfinite(value) || value < d->min || value > d->max) {
        return MD_PARAM_OUT_OF_RANGE;
    }
    if ((d->flags & MD_PARAM_F_INTEGER) != 0u && fabs(value - floor(value)) > 0.0) {
        return MD_PARAM_OUT_OF_RANGE;
    }
    if (!cross_rules_ok(p, id, value)) {
        return MD_PARAM_OUT_OF_RANGE;
    }
    p->value[id] = value;
    return MD_PARAM_OK;
}
