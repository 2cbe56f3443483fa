/// @file md_cycle.c
/// The electrode cycle: scheduling, recording, decision, motion, settling.
/// See md_cycle.h; processing in md_interval.c, frames in md_telemetry.c.
#include "md_cycle.h"

#include <math.h>
#include <string.h>

#include "md_can.h"
#include "md_interval.h"
#include "md_telemetry.h"

#define US_PER_MS 1000u
#define US_PER_S 1000000u
#define ANSWER_MARGIN_US ((uint64_t)5u * US_PER_S)  /* platform-time slack on every wait for an answer */
#define LOCKSTEP_LOST_US ((uint64_t)30u * US_PER_S) /* lockstep: no answer frame this long = a lost frame */
#define SERVO_ACTIONS_PER_POLL 4u                   /* servo actions taken in one poll at most */
#define STEP_EPS_UM 1e-6                            /* a smaller SFSM step is no step */
#define REC_SAMPLES_MAX (30u * 65536u)              /* REC_REQ bound of the front-end (Seq range × 30) */

/* ------------------------------------------------------------------ */
/* Configuration from the parameters                                   */
/* ------------------------------------------------------------------ */

static void sfsm_cfg_from(const md_params_t *p, sfsm_config_t *cfg)
{
    sfsm_config_default(cfg);
    cfg->move_search_um = md_params_get(p, MD_P_MOVE_SEARCH_UM);
    cfg->move_sample_um = md_params_get(p, MD_P_MOVE_SAMPLE_UM);
    cfg->move_resample_um = md_params_get(p, MD_P_MOVE_RESAMPLE_UM);
    cfg->move_max_um = md_params_get(p, MD_P_MOVE_MAX_UM);
    cfg->gamma1 = md_params_get(p, MD_P_SFSM_GAMMA1);
    cfg->gamma2 = md_params_get(p, MD_P_SFSM_GAMMA2);
    cfg->gamma3 = md_params_get(p, MD_P_SFSM_GAMMA3);
    cfg->snr_isolate = md_params_get(p, MD_P_SFSM_SNR_ISOLATE);
    cfg->snr_drop_frac = md_params_get(p, MD_P_SFSM_SNR_DROP);
    cfg->snr_min = md_params_get(p, MD_P_SFSM_SNR_MIN);
    cfg->wait_r = (uint8_t)md_params_get_u32(p, MD_P_SFSM_WAIT_R);
    cfg->lost_cycles = (uint8_t)md_params_get_u32(p, MD_P_SFSM_LOST_CYCLES);
    cfg->search_span_um = md_params_get(p, MD_P_SFSM_SEARCH_SPAN_UM);
    cfg->approach_um = fmin(md_params_get(p, MD_P_SFSM_APPROACH_UM), cfg->move_max_um);
    cfg->approach_gain = md_params_get(p, MD_P_SFSM_APPROACH_GAIN);
}

static void sc_cfg_from(const md_params_t *p, sc_config_t *cfg)
{
    sc_config_default(cfg);
    cfg->move_max_um = md_params_get(p, MD_P_MOVE_MAX_UM);
    cfg->move_sample_um = fmin(md_params_get(p, MD_P_MOVE_SAMPLE_UM), cfg->move_max_um);
    cfg->tol_um = md_params_get(p, MD_P_SC_TOL_UM);
}

static void servo_cfg_from(const md_params_t *p, md_servo_config_t *cfg)
{
    md_servo_config_default(cfg);
    cfg->tol_um = md_params_get(p, MD_P_SERVO_TOL_UM);
    cfg->max_iter = (uint8_t)md_params_get_u32(p, MD_P_SERVO_MAX_ITER);
    cfg->avg_n = (uint8_t)md_params_get_u32(p, MD_P_SERVO_AVG_N);
    cfg->step_nm = md_params_get(p, MD_P_SERVO_STEP_NM);
    cfg->rate_hz = (uint16_t)md_params_get_u32(p, MD_P_SERVO_RATE_HZ);
}

static void guard_cfg_from(const md_params_t *p, ag_config_t *cfg)
{
    ag_config_default(cfg);
    cfg->growth_stop = md_params_get(p, MD_P_GUARD_GROWTH_STOP);
    cfg->amp_slow = md_params_get(p, MD_P_GUARD_AMP_SLOW);
    cfg->amp_floor = fmin(cfg->amp_floor, cfg->amp_slow);
    cfg->amp_stop = md_params_get(p, MD_P_GUARD_AMP_STOP);
    cfg->move_near_um = md_params_get(p, MD_P_GUARD_MOVE_NEAR_UM);
    cfg->retract_um = md_params_get(p, MD_P_GUARD_RETRACT_UM);
    cfg->climb_free_frac = md_params_get(p, MD_P_GUARD_CLIMB_FRAC);
    cfg->climb_frac = md_params_get(p, MD_P_GUARD_CEILING_CLIMB);
    cfg->growth_slow = md_params_get(p, MD_P_GUARD_GROWTH_SLOW);
    cfg->growth_max = md_params_get(p, MD_P_GUARD_GROWTH_MAX);
    cfg->fence_drop_frac = md_params_get(p, MD_P_GUARD_FENCE_DROP);
    cfg->fence_lapse = (uint16_t)md_params_get_u32(p, MD_P_GUARD_FENCE_LAPSE);
    cfg->relax_frac = md_params_get(p, MD_P_GUARD_RELAX_FRAC);
    cfg->relax_tau_s = md_params_get(p, MD_P_GUARD_RELAX_TAU_S);
    cfg->probe_um = md_params_get(p, MD_P_GUARD_PROBE_UM);
    cfg->creep_horizon_s = md_params_get(p, MD_P_GUARD_CREEP_HORIZON_S);
    cfg->baseline_min_um = md_params_get(p, MD_P_GUARD_BASELINE_UM);
    cfg->baseline_new_um = fmin(md_params_get(p, MD_P_GUARD_BASELINE_NEW_UM), cfg->baseline_min_um);
    cfg->pace_um = md_params_get(p, MD_P_GUARD_PACE_UM);
    cfg->settle_um = md_params_get(p, MD_P_GUARD_SETTLE_UM);
    cfg->follow = md_params_get_u32(p, MD_P_GUARD_FOLLOW) != 0u;
    cfg->near_scale = md_params_get_u32(p, MD_P_GUARD_NEAR_SCALE) != 0u;
}

static void mhtc_cfg_from(const md_params_t *p, mhtc_config_t *cfg)
{
    mhtc_config_default(cfg, md_interval_tracker(p));
    const double q = md_params_get(p, MD_P_MHTC_Q_UV);
    cfg->q_process = q * q; /* µV² per waveform sample and interval (§4.4.2) */
    cfg->init_var = q * q;
    cfg->unimodal_ratio = md_params_get(p, MD_P_MHTC_UNIMODAL_RATIO);
    cfg->count_sigma = md_params_get(p, MD_P_MHTC_COUNT_SIGMA);
    cfg->lambda_first = md_params_get(p, MD_P_MHTC_LAMBDA_FIRST);
}

/* Tunables take effect at the start of a cycle; an inconsistent set (e.g.
 * γ1 >= γ2) is not applied and the previous one stays. */
static void apply_params(md_electrode_t *el, const md_node_t *node)
{
    sfsm_config_t sc;
    sfsm_cfg_from(&node->params, &sc);
    if (sfsm_config_check(&sc) == MD_OK) {
        el->sfsm.cfg = sc;
    }
    md_servo_config_t vc;
    servo_cfg_from(&node->params, &vc);
    (void)md_servo_configure(&el->servo, &vc);
    ag_config_t gc;
    guard_cfg_from(&node->params, &gc);
    if (ag_config_check(&gc) == MD_OK) {
        el->guard.cfg = gc; /* history and barrier stay: they describe the tissue */
    }
    mhtc_config_t mc;
    mhtc_cfg_from(&node->params, &mc);
    if (mc.tracker != el->mhtc.cfg.tracker) {
        /* Another tracker (a CONFIG parameter: set only while not operational)
         * starts from no tracks; the curves were keyed by the old IDs. */
        if (mhtc_init(&el->mhtc, &mc) == MD_OK) {
            sc_table_init(&el->curves);
        }
        return;
    }
    el->mhtc.cfg.q_process = mc.q_process;
    el->mhtc.cfg.unimodal_ratio = mc.unimodal_ratio; /* read per fit: safe between intervals */
    el->mhtc.cfg.count_sigma = mc.count_sigma;       /* read per association: likewise */
    el->mhtc.cfg.lambda_first = mc.lambda_first;     /* likewise; used until the first hypothesis exists */
}

md_status_t md_cycle_init(md_cycle_t *c, const md_node_t *node)
{
    if (c == NULL || node == NULL) {
        return MD_E_ARG;
    }
    memset(c, 0, sizeof *c);
    sfsm_config_t sc;
    md_servo_config_t vc;
    mhtc_config_t mc;
    ag_config_t gc;
    sfsm_cfg_from(&node->params, &sc);
    servo_cfg_from(&node->params, &vc);
    mhtc_cfg_from(&node->params, &mc);
    guard_cfg_from(&node->params, &gc);
    for (size_t e = 0u; e < MD_ELECTRODES; ++e) {
        md_electrode_t *el = &c->el[e];
        sc_table_init(&el->curves);
        md_status_t st = mhtc_init(&el->mhtc, &mc);
        st = (st == MD_OK) ? sfsm_init(&el->sfsm, &sc) : st;
        st = (st == MD_OK) ? md_servo_init(&el->servo, &vc) : st;
        st = (st == MD_OK) ? ag_init(&el->guard, &gc) : st;
        if (st != MD_OK) {
            return st;
        }
    }
    return MD_OK;
}

/* ------------------------------------------------------------------ */
/* Time and waits                                                      */
/* ------------------------------------------------------------------ */

uint64_t md_cycle_time_us(const md_cycle_t *c, const md_node_t *node, uint64_t now_us)
{
    return (c->lockstep) ? node->sim_time_us : now_us;
}

/* A lockstep wait not yet anchored to a SIM_CLOCK: no simulated time reaches it. */
#define WAIT_SIM_UNANCHORED UINT64_MAX

/* Lets duration_us pass: SIM_ADVANCE in lockstep (the simulator closes it with
 * a SIM_CLOCK), the platform clock otherwise. In lockstep the wait starts
 * from the first SIM_CLOCK received after the SIM_ADVANCE, not from the clock
 * known now: over a socket bus the SIM_CLOCK closing the previous batch may
 * still be queued behind its REC_END / final ACT_STATUS, and a wait based on
 * the older time would end at once on it. Until anchored, wait_step_us holds
 * the duration. */
/* Platform time at which the current wait for an answer has failed. In
 * lockstep simulated time moves only when the plant answers, so a wall-clock
 * bound there says nothing about the session, only about the plant's health:
 * it is pushed back while the plant keeps sending (heartbeats every 100 ms),
 * and the outcome no longer depends on how fast the host runs. */
static uint64_t answer_deadline_us(const md_cycle_t *c)
{
    if (!c->lockstep) {
        return c->timeout_wall_us;
    }
    /* Dead plant: nothing for 5 s. Live plant that lost our request or its
     * answer (a socket bus under load): heartbeats but no answer frame for
     * 30 s since the request or the last answer, far beyond what even the
     * ~20x slower vcan VM needs between two answer frames. */
    const uint64_t dead = c->plant_alive_us + ANSWER_MARGIN_US;
    const uint64_t lost = c->answer_us + LOCKSTEP_LOST_US;
    const uint64_t d = (dead < lost) ? dead : lost;
    return (d > c->timeout_wall_us) ? d : c->timeout_wall_us;
}

/* A request went out at now_us: its answer is due by deadline_us. */
static void arm_timeout(md_cycle_t *c, uint64_t now_us, uint64_t deadline_us)
{
    c->timeout_wall_us = deadline_us;
    c->answer_us = now_us;
}

static bool answer_late(const md_cycle_t *c, uint64_t now_us)
{
    return now_us >= answer_deadline_us(c);
}

static void start_wait(md_cycle_t *c, md_node_t *node, uint32_t duration_us, uint64_t now_us)
{
    arm_timeout(c, now_us, now_us + duration_us + ANSWER_MARGIN_US);
    if (duration_us == 0u) {
        c->wait = MD_WAIT_NONE;
        return;
    }
    if (c->lockstep) {
        struct md_can_sim_advance_t m;
        uint8_t buf[MD_CAN_SIM_ADVANCE_LENGTH];
        (void)md_can_sim_advance_init(&m);
        m.duration_us = duration_us;
        m.token = ++c->sim_token;
        (void)md_node_send(node, MD_CAN_SIM_ADVANCE_FRAME_ID, buf, md_can_sim_advance_pack(buf, &m, sizeof buf), false);
        c->wait = MD_WAIT_SIM;
        c->wait_sim_us = WAIT_SIM_UNANCHORED;
        c->wait_step_us = duration_us;
    } else {
        c->wait = MD_WAIT_WALL;
        c->wait_wall_us = now_us + duration_us;
    }
}

static bool wait_done(const md_cycle_t *c, const md_node_t *node, uint64_t now_us)
{
    switch (c->wait) {
    case MD_WAIT_SIM: return node->sim_time_us >= c->wait_sim_us;
    case MD_WAIT_WALL: return now_us >= c->wait_wall_us;
    case MD_WAIT_NONE:
    default: return true;
    }
}

static bool cycle_allowed(const md_node_t *node)
{
    return md_node_motion_allowed(node);
}

/* ------------------------------------------------------------------ */
/* Ending a cycle                                                      */
/* ------------------------------------------------------------------ */

static void end_cycle(md_cycle_t *c, md_node_t *node)
{
    md_electrode_t *el = &c->el[c->active];
    el->phase = MD_CYC_IDLE;
    el->cycle++;
    el->cycles++;
    c->cycles++;
    node->counters.cycles_done++;
    c->wait = MD_WAIT_NONE;
    c->active = (uint8_t)((c->active + 1u) % MD_ELECTRODES); /* round robin */
}

/* The platform's work counter (0 where it has none) at the start of a
 * stretch of measured work (the cycle's cost). */
static uint64_t work_begin(const md_node_t *node)
{
    if (node->port.work_section != NULL) {
        node->port.work_section(node->port.ctx, true);
    }
    return (node->port.work_now != NULL) ? node->port.work_now(node->port.ctx) : 0u;
}

/* The work done since work_begin returned w0. */
static uint64_t work_end(const md_node_t *node, uint64_t w0)
{
    const uint64_t w1 = (node->port.work_now != NULL) ? node->port.work_now(node->port.ctx) : 0u;
    if (node->port.work_section != NULL) {
        node->port.work_section(node->port.ctx, false);
    }
    return w1 - w0;
}

static void settle(md_cycle_t *c, md_node_t *node, uint64_t now_us)
{
    c->el[c->active].phase = MD_CYC_SETTLING;
    start_wait(c, node, md_params_get_u32(&node->params, MD_P_SETTLE_MS) * US_PER_MS, now_us);
}

static void recording_failed(md_cycle_t *c, md_node_t *node)
{
    md_electrode_t *el = &c->el[c->active];
    el->rec_failed++;
    node->counters.rec_failed++;
    el->flags = MD_TLM_F_REC_FAILED | (c->lockstep ? MD_TLM_F_LOCKSTEP : 0u);
    /* the status reports the depth now and asks for no step; without a
     * depth yet (e.g. just after a restart) it says so instead of sending
     * the placeholder as if it were measured */
    double depth = 0.0;
    if (md_servo_depth_um(&el->servo, &depth) == MD_OK) {
        el->depth_um = depth;
    } else {
        el->flags |= MD_TLM_F_NO_DEPTH;
    }
    el->target_um = el->depth_um;
    (void)md_tlm_cycle(node, c->active, el, MD_TLM_PHASE_PROCESSED, el->rec_samples);
    (void)md_tlm_status(node, c->active, el, 0u);
    end_cycle(c, node);
}

/* ------------------------------------------------------------------ */
/* Record                                                              */
/* ------------------------------------------------------------------ */

static void start_recording(md_cycle_t *c, md_node_t *node, uint64_t now_us)
{
    md_electrode_t *el = &c->el[c->active];
    apply_params(el, node);
    const double n_d = md_params_get(&node->params, MD_P_INTERVAL_S) * (double)el->sample_rate_hz;
    const uint32_t n = (n_d >= (double)REC_SAMPLES_MAX) ? REC_SAMPLES_MAX : (uint32_t)n_d;
    if (md_interval_begin(&c->ws, el, n) != MD_OK) {
        recording_failed(c, node);
        return;
    }
    el->interval_id++;
    el->rec_requested = n;
    el->rec_samples = 0u;
    el->rec_bad = false;
    el->rec_status = MD_OK;
    el->rec_clock_seen = false;
    el->rec_end_ok = false;
    el->cost_detect = 0u;
    el->cost_chain = 0u;
    el->rec_start_us = md_cycle_time_us(c, node, now_us);
    struct md_can_rec_req_t m;
    uint8_t buf[MD_CAN_REC_REQ_LENGTH];
    (void)md_can_rec_req_init(&m);
    m.electrode = c->active;
    m.interval_id = el->interval_id;
    m.num_samples = n;
    if (md_node_send(node, MD_CAN_REC_REQ_FRAME_ID, buf, md_can_rec_req_pack(buf, &m, sizeof buf), false) != MD_OK) {
        recording_failed(c, node);
        return;
    }
    el->phase = MD_CYC_RECORDING;
    c->wait = MD_WAIT_NONE;
    arm_timeout(c, now_us, now_us + 2u * (uint64_t)n * US_PER_S / el->sample_rate_hz + ANSWER_MARGIN_US);
    (void)md_tlm_cycle(node, c->active, el, MD_TLM_PHASE_REQUESTED, n);
}

static void on_rec_data(md_cycle_t *c, const md_node_t *node, const md_frame_t *f, bool accepted)
{
    md_electrode_t *el = &c->el[c->active];
    if (el->phase != MD_CYC_RECORDING || f->len < 1u || f->data[0] != c->active) {
        return;
    }
    if (!accepted) {
        el->rec_bad = true; /* lost or out of sequence: the interval is not the signal */
        return;
    }
    const uint8_t count = f->data[1];
    int16_t x[MD_REC_SAMPLES_PER_FRAME];
    for (size_t i = 0u; i < count && i < MD_REC_SAMPLES_PER_FRAME; ++i) {
        const uint16_t u = (uint16_t)((uint16_t)f->data[4u + 2u * i] | (uint16_t)((uint16_t)f->data[5u + 2u * i] << 8));
        x[i] = (int16_t)u; /* DBC: little-endian int16 at bit 32 + 16 i */
    }
    if (el->rec_status == MD_OK) {
        const uint64_t w0 = work_begin(node);
        el->rec_status = md_interval_push(&c->ws, x, count);
        el->cost_detect += work_end(node, w0);
    }
    el->rec_samples += count;
}

static void on_rec_end(md_cycle_t *c, md_node_t *node, const md_frame_t *f)
{
    md_electrode_t *el = &c->el[c->active];
    struct md_can_rec_end_t m;
    if (el->phase != MD_CYC_RECORDING || md_can_rec_end_unpack(&m, f->data, f->len) != 0 || m.electrode != c->active ||
        m.interval_id != el->interval_id) {
        return; /* another interval's end (e.g. an aborted earlier one) */
    }
    if (m.status != MD_REC_COMPLETE || el->rec_bad || m.total_samples != el->rec_samples ||
        el->rec_samples != el->rec_requested) {
        recording_failed(c, node);
        return;
    }
    /* In lockstep the batch ends with SIM_CLOCK(t + n/fs), right behind the
     * REC_END; processing waits for it, so that what follows (the next
     * REC_REQ when nothing moves) has the interval's end as its cycle time
     * even when the link delivers the clock later than the REC_END. */
    if (c->lockstep) {
        el->rec_end_ok = true;
    } else {
        el->phase = MD_CYC_PROCESS;
    }
}

/* ------------------------------------------------------------------ */
/* Process, score, decide                                              */
/* ------------------------------------------------------------------ */

static void skip_cycle(md_cycle_t *c, md_node_t *node, md_status_t st, uint64_t now_us)
{
    md_electrode_t *el = &c->el[c->active];
    el->skipped++;
    node->counters.cycles_skipped++;
    el->flags |= MD_TLM_F_SKIPPED;
    (void)md_node_emcy(node, MD_EMCY_SOFTWARE, c->active, (uint32_t)(-(int32_t)st));
    (void)md_tlm_cycle(node, c->active, el, MD_TLM_PHASE_PROCESSED, el->rec_samples);
    (void)md_tlm_status(node, c->active, el, (uint32_t)c->ws.win.n);
    (void)md_tlm_spikes_unlabelled(node, c->active, el, &c->ws);
    (void)now_us;
    end_cycle(c, node);
}

/* SNR curve and SFSM (§2.2.3-2.2.4); returns the step the SFSM asks for. */
static double decide(md_decision_scratch_t *d, md_electrode_t *el, const md_node_t *node, const md_interval_out_t *po,
                     double depth)
{
    sc_config_t scc;
    sc_cfg_from(&node->params, &scc);
    sfsm_input_t *in = &d->sfsm_in;
    memset(in, 0, sizeof *in);
    in->has_dominant = po->has_dominant;
    in->dominant_track = po->dominant;
    in->snr = po->snr;
    in->iqm = po->iqm; /* ID_g, not squared (sfsm.h) */
    in->spikes_seen = po->spikes_seen;
    in->depth_um = depth;
    in->depth_min_um = md_params_get(&node->params, MD_P_DEPTH_MIN_UM);
    in->depth_max_um = md_params_get(&node->params, MD_P_DEPTH_MAX_UM);
    in->estop = node->estop_latched;
    in->fault = !md_node_motion_allowed(node);
    in->resume = el->resume;
    in->settled = ag_settled(&el->guard);
    if (po->has_dominant) {
        sc_curve_t *curve = NULL;
        if (sc_table_observe(&el->curves, &scc, po->dominant, depth, po->snr, &curve) == MD_OK && curve != NULL) {
            (void)sc_curve_suggest(curve, &scc, depth, el->sfsm.search_dir, &in->suggestion);
        }
    }
    sfsm_output_t *out = &d->sfsm_out;
    memset(out, 0, sizeof *out);
    if (sfsm_decide(&el->sfsm, in, out) != MD_OK) {
        return 0.0; /* invalid input: the SFSM is in HALTED and asks for nothing */
    }
    el->resume = false;
    if (out->reset_curve) {
        (void)sc_table_reset_track(&el->curves, out->reset_track);
    }
    el->flags |= (out->clamped ? MD_TLM_F_CLAMPED : 0u) | ((uint32_t)out->reason << MD_TLM_REASON_SHIFT);
    return out->move_um;
}

/* The guard's units: the robust amplitude of all detections (no tracker) and
 * the SNR of every track the leading hypothesis detected this interval. */
static size_t guard_units(const md_workspace_t *ws, const md_interval_out_t *po, ag_unit_t *unit)
{
    size_t n = 0u;
    unit[n++] = (ag_unit_t){AG_UNIT_RAW, po->amp};
    for (size_t j = 0u; j < ws->res.n_tracks && j < MHTC_TARGETS_MAX && n < AG_UNITS_MAX; ++j) {
        if (ws->res.track[j].cluster > 0u && ws->track_snr[j] > 0.0) {
            unit[n++] = (ag_unit_t){ws->res.track[j].id, ws->track_snr[j]};
        }
    }
    return n;
}

/* Approach guard after the SFSM (approach_guard.h): may shorten, cancel or
 * reverse the step, in every state and with every tracker. Computed and
 * reported even when disabled, so its effect can be measured. */
static double guard(md_decision_scratch_t *d, md_electrode_t *el, const md_node_t *node, const md_workspace_t *ws,
                    const md_interval_out_t *po, double depth, double step)
{
    ag_unit_t *unit = d->unit;
    const ag_input_t in = {unit, guard_units(ws, po, unit),        depth, (double)el->rec_start_us * 1e-6,
                           step, sfsm_holds_lone_neuron(&el->sfsm)};
    ag_output_t out;
    if (ag_apply(&el->guard, &in, &out) != MD_OK) {
        el->flags |= MD_TLM_F_GUARD_LIMITED;
        el->guard_limited++;
        return 0.0; /* the guard cannot judge: hold */
    }
    el->flags |= (out.n_ceilings > 0u) ? MD_TLM_F_GUARD_CEILING : 0u;
    if (out.action == AG_PASS || md_params_get_u32(&node->params, MD_P_GUARD_ENABLE) == 0u) {
        return step;
    }
    el->flags |= MD_TLM_F_GUARD_LIMITED | ((out.action == AG_RETRACT) ? MD_TLM_F_GUARD_RETRACT : 0u);
    el->guard_limited++;
    return out.move_um;
}

/* The electrode's depth as TLM_STATUS reports it (float32). The tracker's
 * travel is measured on it, so a session's recording holds the tracker's input
 * to the bit and mhtc-replay reproduces the labels (docs/mhtc.md "Offline
 * replay"); the rounding is < 3e-8 of the depth. False: no calibrated depth. */
static bool reported_depth_um(const md_electrode_t *el, double *depth_um)
{
    double d = 0.0;
    const bool ok = (md_servo_depth_um(&el->servo, &d) == MD_OK);
    *depth_um = (double)(float)d;
    return ok;
}

/* The flags a cycle starts with: lockstep and how the last move ended. */
static uint32_t cycle_start_flags(const md_cycle_t *c, const md_electrode_t *el)
{
    uint32_t flags = c->lockstep ? MD_TLM_F_LOCKSTEP : 0u;
    flags |= (el->last_move == MD_SERVO_R_CONVERGED) ? MD_TLM_F_LAST_MOVE_OK : 0u;
    flags |= (el->last_move != MD_SERVO_R_NONE && el->last_move != MD_SERVO_R_CONVERGED) ? MD_TLM_F_LAST_MOVE_FAILED
                                                                                         : 0u;
    return flags;
}

/* Keeps the interval's results on the electrode and returns the step the SFSM
 * and the approach guard ask for; 0 without a calibrated depth (no decision
 * without one). */
static double decide_step(md_decision_scratch_t *d, md_electrode_t *el, const md_node_t *node, const md_workspace_t *ws,
                          const md_interval_out_t *po)
{
    el->has_dominant = po->has_dominant;
    el->dominant = po->dominant;
    el->snr = po->snr;
    el->iqm = po->iqm;
    el->guard_amp = po->amp;
    double depth = 0.0;
    double step = 0.0;
    if (md_servo_depth_um(&el->servo, &depth) == MD_OK) {
        el->depth_um = depth;
        step = guard(d, el, node, ws, po, depth, decide(d, el, node, po, depth));
    } else {
        el->flags |= MD_TLM_F_NO_DEPTH;
    }
    return step;
}

/* Starts the move to el->target_um when the step is not negligible and
 * motion is allowed; an inhibited move is flagged and counted. True: the
 * servo is moving. */
static bool begin_move(md_electrode_t *el, const md_node_t *node, double step)
{
    if (fabs(step) <= STEP_EPS_UM) {
        return false;
    }
    const bool move = cycle_allowed(node) &&
                      md_servo_begin(&el->servo, el->target_um, md_params_get(&node->params, MD_P_DEPTH_MIN_UM),
                                     md_params_get(&node->params, MD_P_DEPTH_MAX_UM),
                                     md_params_get(&node->params, MD_P_MOVE_MAX_UM)) == MD_OK;
    el->flags |= move ? MD_TLM_F_MOVE : MD_TLM_F_INHIBITED;
    el->inhibited += move ? 0u : 1u;
    return move;
}

static void process(md_cycle_t *c, md_node_t *node, uint64_t now_us)
{
    const uint64_t w0 = work_begin(node);
    md_electrode_t *el = &c->el[c->active];
    el->flags = cycle_start_flags(c, el);
    md_interval_out_t po;
    const double duration_s = (double)el->rec_samples / (double)el->sample_rate_hz;
    md_status_t st = (el->rec_status != MD_OK) ? el->rec_status : MD_OK;
    double here = 0.0;
    const bool here_ok = reported_depth_um(el, &here);
    el->move_um = (here_ok && el->tracked_depth_ok) ? fabs(here - el->tracked_depth_um) : 0.0;
    if (st == MD_OK) {
        st = md_interval_run(&c->ws, el, duration_s, md_params_get(&node->params, MD_P_MIN_RATE_HZ), &po);
    }
    if (st != MD_OK) {
        el->cost_chain = work_end(node, w0);
        skip_cycle(c, node, st, now_us); /* tracks and SFSM untouched */
        return;
    }
    el->tracked_depth_um = here;
    el->tracked_depth_ok = here_ok;
    const double step = decide_step(&c->dec, el, node, &c->ws, &po);
    el->target_um = el->depth_um + step;
    const bool move = begin_move(el, node, step);
    el->cost_chain = work_end(node, w0);
    (void)md_tlm_cycle(node, c->active, el, MD_TLM_PHASE_PROCESSED, el->rec_samples);
    (void)md_tlm_status(node, c->active, el, po.n_spikes);
    (void)md_tlm_interval(node, c->active, el, &c->ws);
    if (move) {
        el->moves++;
        el->phase = MD_CYC_MOVING;
        c->wait = MD_WAIT_NONE;
        arm_timeout(c, now_us, now_us + ANSWER_MARGIN_US);
    } else {
        end_cycle(c, node); /* nothing moved: nothing to settle */
    }
}

/* ------------------------------------------------------------------ */
/* Move                                                                */
/* ------------------------------------------------------------------ */

static void move_finished(md_cycle_t *c, md_node_t *node, uint64_t now_us)
{
    md_electrode_t *el = &c->el[c->active];
    el->last_move = el->servo.result;
    if (el->last_move != MD_SERVO_R_CONVERGED) {
        el->moves_failed++;
        node->counters.moves_failed++;
        if (el->last_move != MD_SERVO_R_NOT_CONVERGED) {
            (void)md_node_emcy(node, MD_EMCY_MOTION, c->active, (uint32_t)el->last_move);
        }
    }
    settle(c, node, now_us);
}

static void drive_servo(md_cycle_t *c, md_node_t *node, uint64_t now_us)
{
    md_electrode_t *el = &c->el[c->active];
    for (uint32_t k = 0u; k < SERVO_ACTIONS_PER_POLL && c->wait == MD_WAIT_NONE; ++k) {
        const md_servo_action_t a = md_servo_next(&el->servo);
        switch (a.kind) {
        case MD_SERVO_A_STEP:
            if (md_node_step(node, c->active, a.direction, a.steps, a.rate_hz) == MD_OK) {
                md_servo_sent(&el->servo, node->electrode[c->active].act_seq);
                arm_timeout(c, now_us, now_us + 2u * (uint64_t)a.steps * US_PER_S / a.rate_hz + ANSWER_MARGIN_US);
            } else {
                md_servo_send_failed(&el->servo);
            }
            return; /* wait for its final ACT_STATUS */
        case MD_SERVO_A_WAIT: start_wait(c, node, a.wait_us, now_us); return;
        case MD_SERVO_A_FINISHED: move_finished(c, node, now_us); return;
        case MD_SERVO_A_NONE:
        default:
            if (answer_late(c, now_us)) { /* the actuator never answered */
                md_servo_abort(&el->servo);
                (void)md_node_step(node, c->active, MD_ACT_DIR_ADVANCE, 0u, 0u);
                el->timeouts++;
                move_finished(c, node, now_us);
            }
            return;
        }
    }
}

/* ------------------------------------------------------------------ */
/* Frames and poll                                                     */
/* ------------------------------------------------------------------ */

static void on_plant_frame(md_cycle_t *c, const md_frame_t *f)
{
    if (f->id == MD_CAN_FE_INFO_FRAME_ID) {
        struct md_can_fe_info_t m;
        if (md_can_fe_info_unpack(&m, f->data, f->len) == 0 && m.electrode < MD_ELECTRODES && m.sample_rate_hz > 0u &&
            m.gain_u_v_per_lsb > 0.0f) {
            c->el[m.electrode].fe_info = true;
            c->el[m.electrode].sample_rate_hz = m.sample_rate_hz;
            c->el[m.electrode].gain_uv = (double)m.gain_u_v_per_lsb;
        }
    } else if (f->id == MD_CAN_HALL_CALIB_FRAME_ID) {
        struct md_can_hall_calib_t m;
        if (md_can_hall_calib_unpack(&m, f->data, f->len) == 0 && m.electrode < MD_ELECTRODES) {
            (void)md_servo_calib(&c->el[m.electrode].servo, m.coeff_index, m.coeff_count, (double)m.coeff_value);
        }
    } else if (f->id == MD_CAN_HALL_READING_FRAME_ID) {
        struct md_can_hall_reading_t m;
        if (md_can_hall_reading_unpack(&m, f->data, f->len) == 0 && m.electrode < MD_ELECTRODES) {
            md_servo_reading(&c->el[m.electrode].servo, m.raw_code);
        }
    } else if (f->id == MD_CAN_ACT_STATUS_FRAME_ID) {
        struct md_can_act_status_t m;
        if (md_can_act_status_unpack(&m, f->data, f->len) == 0 && m.electrode < MD_ELECTRODES) {
            md_servo_act_status(&c->el[m.electrode].servo, m.cmd_seq, m.state, m.end_stops, m.steps_done);
        }
    } else if (f->id == MD_CAN_HEARTBEAT_FE_FRAME_ID && f->len >= 3u) {
        c->lockstep = (f->data[2] & MD_HB_FLAG_LOCKSTEP) != 0u; /* HEARTBEAT Flags bit2 */
    } else {
        /* other frames: the node's business */
    }
}

static bool heartbeat_frame(uint32_t id)
{
    return id == MD_CAN_HEARTBEAT_ACT_FRAME_ID || id == MD_CAN_HEARTBEAT_HALL_FRAME_ID ||
           id == MD_CAN_HEARTBEAT_FE_FRAME_ID;
}

/* Frames only a live plant sends: its heartbeats and its answers. */
static bool plant_frame(uint32_t id)
{
    return heartbeat_frame(id) || id == MD_CAN_SIM_CLOCK_FRAME_ID || id == MD_CAN_REC_END_FRAME_ID ||
           id == MD_CAN_HALL_READING_FRAME_ID || id == MD_CAN_ACT_STATUS_FRAME_ID || id == MD_CAN_REC_DATA_FRAME_ID;
}

void md_cycle_on_frame(md_cycle_t *c, md_node_t *node, const md_frame_t *f, bool accepted, uint64_t now_us)
{
    if (c == NULL || node == NULL || f == NULL) {
        return;
    }
    if (accepted && plant_frame(f->id)) {
        c->plant_alive_us = now_us;
        if (!heartbeat_frame(f->id)) {
            c->answer_us = now_us;
        }
    }
    if (f->id == MD_CAN_REC_DATA_FRAME_ID && (f->flags & MD_FRAME_FLAG_EXT) == 0u) {
        on_rec_data(c, node, f, accepted);
        return;
    }
    if (!accepted) {
        return; /* rejected frames change nothing (the node counted them) */
    }
    md_electrode_t *el = &c->el[c->active];
    if (f->id == MD_CAN_SIM_CLOCK_FRAME_ID && c->wait == MD_WAIT_SIM && c->wait_sim_us == WAIT_SIM_UNANCHORED) {
        c->wait_sim_us = node->sim_time_us + c->wait_step_us; /* the SIM_ADVANCE's time starts here */
    }
    if (f->id == MD_CAN_SIM_CLOCK_FRAME_ID && el->phase == MD_CYC_RECORDING && !el->rec_clock_seen) {
        el->rec_clock_seen = true;
        if (c->lockstep) {
            el->rec_start_us = node->sim_time_us; /* the batch of the recording opens at its first sample */
        }
    }
    if (f->id == MD_CAN_SIM_CLOCK_FRAME_ID && el->phase == MD_CYC_RECORDING && el->rec_end_ok) {
        el->rec_end_ok = false;
        el->phase = MD_CYC_PROCESS; /* the recording's batch is closed */
    }
    if (f->id == MD_CAN_REC_END_FRAME_ID) {
        on_rec_end(c, node, f);
        return;
    }
    on_plant_frame(c, f);
}

/* The next electrode (from the active one, round robin) that can record:
 * one without FE_INFO yet is passed over. False if none can. */
static bool take_turn(md_cycle_t *c)
{
    for (size_t k = 0u; k < MD_ELECTRODES; ++k) {
        const uint8_t e = (uint8_t)((c->active + k) % MD_ELECTRODES);
        if (c->el[e].fe_info) {
            c->active = e;
            return true;
        }
    }
    return false;
}

static bool any_fe_info(const md_cycle_t *c)
{
    for (size_t e = 0u; e < MD_ELECTRODES; ++e) {
        if (c->el[e].fe_info) {
            return true;
        }
    }
    return false;
}

/* Motion or recording no longer allowed (e-stop, node lost, not
 * operational): stop what is running; the node has halted the actuators. */
static void abort_active(md_cycle_t *c, md_node_t *node)
{
    md_electrode_t *el = &c->el[c->active];
    if (el->phase == MD_CYC_MOVING) {
        md_servo_abort(&el->servo);
        el->last_move = MD_SERVO_R_ABORTED;
        el->moves_failed++;
        node->counters.moves_failed++;
        end_cycle(c, node);
    } else if (el->phase == MD_CYC_RECORDING) {
        recording_failed(c, node);
    } else if (el->phase == MD_CYC_SETTLING) {
        end_cycle(c, node);
    } else {
        /* idle: nothing runs; processing runs to its end without motion */
    }
}

void md_cycle_poll(md_cycle_t *c, md_node_t *node, uint64_t now_us)
{
    if (c == NULL || node == NULL) {
        return;
    }
    const bool op = node->state == MD_NODE_STATE_OPERATIONAL;
    if (op && !c->was_operational) {
        for (size_t e = 0u; e < MD_ELECTRODES; ++e) {
            c->el[e].resume = true; /* NMT start is the operator's resume (SFSM_C_RESUME) */
        }
    }
    c->was_operational = op;
    md_electrode_t *el = &c->el[c->active];
    if (!cycle_allowed(node) && el->phase != MD_CYC_PROCESS) {
        abort_active(c, node);
        return;
    }
    if (!wait_done(c, node, now_us)) {
        if (answer_late(c, now_us)) { /* the simulator never closed the SIM_ADVANCE */
            el->timeouts++;
            c->wait = MD_WAIT_NONE;
            if (el->phase == MD_CYC_MOVING) {
                md_servo_abort(&el->servo);
                move_finished(c, node, now_us);
            } else {
                end_cycle(c, node);
            }
        }
        return;
    }
    c->wait = MD_WAIT_NONE;
    switch (el->phase) {
    case MD_CYC_IDLE:
        if (take_turn(c)) {
            start_recording(c, node, now_us);
        }
        break;
    case MD_CYC_RECORDING:
        if (answer_late(c, now_us)) {
            el->timeouts++;
            recording_failed(c, node);
        }
        break;
    case MD_CYC_PROCESS: process(c, node, now_us); break;
    case MD_CYC_MOVING: drive_servo(c, node, now_us); break;
    case MD_CYC_SETTLING: end_cycle(c, node); break;
    default: break;
    }
}

uint64_t md_cycle_next_deadline_us(const md_cycle_t *c, const md_node_t *node)
{
    if (c == NULL || node == NULL) {
        return UINT64_MAX;
    }
    const md_electrode_t *el = &c->el[c->active];
    const bool allowed = md_node_motion_allowed(node);
    const bool op = node->state == MD_NODE_STATE_OPERATIONAL;
    if ((op && !c->was_operational) || el->phase == MD_CYC_PROCESS || (!allowed && el->phase != MD_CYC_IDLE) ||
        (allowed && el->phase == MD_CYC_IDLE && any_fe_info(c))) {
        return 0u;
    }
    if (el->phase == MD_CYC_IDLE) {
        return UINT64_MAX;
    }
    if (c->wait == MD_WAIT_SIM && node->sim_time_us >= c->wait_sim_us) {
        return 0u;
    }
    if (c->wait == MD_WAIT_NONE && el->phase == MD_CYC_MOVING && el->servo.phase != MD_SERVO_MOVING) {
        return 0u; /* the servo has its next action */
    }
    if (c->wait == MD_WAIT_NONE && el->phase == MD_CYC_SETTLING) {
        return 0u;
    }
    if (c->wait == MD_WAIT_WALL && c->wait_wall_us < c->timeout_wall_us) {
        return c->wait_wall_us;
    }
    return answer_deadline_us(c);
}
