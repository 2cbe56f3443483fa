#include "simnode_plant.h"

#include <string.h>

#include "md_can.h"

void simnode_plant_cfg_default(simnode_plant_cfg_t *cfg)
{
    cfg->lockstep = true;
    cfg->autostart = true;
    cfg->hall_rate_hz = 0.0;
    cfg->calib_period_ms = 10000u;
    cfg->status_moving_ms = 100u;
    cfg->status_idle_ms = 1000u;
    cfg->clock_period_ms = 10u;
}

static int plant_send_raw(simnode_plant_t *p, const md_frame_t *f)
{
    return p->out.send(p->out.ctx, f);
}

static void plant_send_clock(simnode_plant_t *p, uint64_t t_us)
{
    struct md_can_sim_clock_t c;
    md_frame_t f;
    c.sim_time_us = t_us;
    simnode_frame_init(&f, MD_CAN_SIM_CLOCK_FRAME_ID, (uint8_t)MD_CAN_SIM_CLOCK_LENGTH);
    (void)md_can_sim_clock_pack(f.data, &c, sizeof f.data);
    if (plant_send_raw(p, &f) >= 0) {
        p->stats.clock_frames++;
    }
}

/* Every node's sink: in lockstep the first frame of a batch is preceded by
 * SIM_CLOCK(batch start), so the controller knows the time of what follows. */
static int plant_node_send(void *ctx, const md_frame_t *f)
{
    simnode_plant_t *p = ctx;
    if (p->batch_open && !p->batch_clock_sent) {
        p->batch_clock_sent = true;
        p->stats.batches++;
        plant_send_clock(p, p->batch_start_us);
    }
    return plant_send_raw(p, f);
}

md_status_t simnode_plant_init(simnode_plant_t *p, const simnode_plant_cfg_t *cfg, simnode_world_t *world,
                               simnode_sink_t out)
{
    const uint32_t electrodes = (world != NULL) ? simnode_world_electrodes(world) : 0u;
    if (cfg == NULL || out.send == NULL || electrodes == 0u || electrodes > SIMNODE_MAX_ELECTRODES ||
        cfg->calib_period_ms == 0u || cfg->status_moving_ms == 0u || cfg->status_idle_ms == 0u ||
        cfg->clock_period_ms == 0u || simnode_world_fe_rate_hz(world) == 0u) {
        return MD_E_ARG;
    }
    memset(p, 0, sizeof *p);
    p->cfg = *cfg;
    p->world = world;
    p->out = out;
    const simnode_sink_t node_sink = {plant_node_send, p};
    const double hall_rate = (cfg->hall_rate_hz > 0.0) ? cfg->hall_rate_hz : simnode_world_hall_rate_hz(world);
    if (!(hall_rate > 0.0)) {
        return MD_E_ARG;
    }
    simnode_act_init(&p->act, world, cfg->autostart, cfg->lockstep, cfg->status_moving_ms, cfg->status_idle_ms,
                     node_sink);
    simnode_hall_init(&p->hall, world, cfg->autostart, cfg->lockstep, hall_rate, cfg->calib_period_ms, node_sink);
    simnode_fe_init(&p->fe, world, cfg->autostart, cfg->lockstep, cfg->calib_period_ms, node_sink);
    p->now_us = simnode_world_time_us(world);
    p->next_clock_us = p->now_us;
    simnode_plant_silence_at(p, p->now_us);
    return MD_OK;
}

static bool plant_busy(const simnode_plant_t *p)
{
    return simnode_act_busy(&p->act) || simnode_fe_busy(&p->fe);
}

uint64_t simnode_plant_next_event_us(const simnode_plant_t *p)
{
    uint64_t t = simnode_act_next_event_us(&p->act);
    const uint64_t h = simnode_hall_next_event_us(&p->hall);
    const uint64_t s = simnode_fe_next_event_us(&p->fe);
    t = (h < t) ? h : t;
    t = (s < t) ? s : t;
    if (!p->cfg.lockstep && p->next_clock_us < t) {
        t = p->next_clock_us;
    }
    return t;
}

void simnode_plant_silence_at(simnode_plant_t *p, uint64_t t_us)
{
    if (t_us > p->silence_t_us) {
        p->silence_t_us = t_us;
    }
    const scenario_faults_t *f = simnode_world_faults(p->world);
    const double t_s = (double)p->silence_t_us * 1e-6;
    p->act.node.silent = scenario_faults_node_silent(f, MD_NODE_ACT, t_s);
    p->hall.node.silent = scenario_faults_node_silent(f, MD_NODE_HALL, t_s);
    p->fe.node.silent = scenario_faults_node_silent(f, MD_NODE_FE, t_s);
}

/* Runs every event due at t (t >= now): world first, then the nodes in a
 * fixed order so that equal times always give the same frame order. */
static void plant_run_at(simnode_plant_t *p, uint64_t t_us)
{
    p->now_us = t_us;
    simnode_plant_silence_at(p, t_us);
    simnode_world_advance(p->world, t_us);
    simnode_act_run(&p->act, t_us);
    simnode_hall_run(&p->hall, t_us);
    simnode_fe_run(&p->fe, t_us);
    if (!p->cfg.lockstep && t_us >= p->next_clock_us) {
        plant_send_clock(p, t_us);
        p->next_clock_us = t_us + (uint64_t)p->cfg.clock_period_ms * 1000u;
    }
}

/* Lockstep: simulated time runs exactly while a motion or a stream is in
 * progress. Terminates: every event time is > now and each motion/stream
 * ends after finitely many events. */
static void plant_run_lockstep(simnode_plant_t *p)
{
    while (plant_busy(p)) {
        const uint64_t t = simnode_plant_next_event_us(p);
        if (t == UINT64_MAX) {
            break; /* defensive: busy always has a pending event */
        }
        plant_run_at(p, (t > p->now_us) ? t : p->now_us);
    }
}

static void plant_batch_open(simnode_plant_t *p)
{
    p->batch_open = p->cfg.lockstep;
    p->batch_clock_sent = false;
    p->batch_start_us = p->now_us;
}

static void plant_batch_close(simnode_plant_t *p)
{
    if (p->batch_open && p->batch_clock_sent && p->now_us > p->batch_start_us) {
        plant_send_clock(p, p->now_us);
    }
    p->batch_open = false;
}

void simnode_plant_start(simnode_plant_t *p)
{
    plant_batch_open(p);
    if (simnode_boot_done(&p->act.node)) {
        simnode_act_announce(&p->act, p->now_us);
    }
    if (simnode_boot_done(&p->hall.node)) {
        simnode_hall_announce(&p->hall, p->now_us);
    }
    if (simnode_boot_done(&p->fe.node)) {
        simnode_fe_announce(&p->fe, p->now_us);
    }
    plant_batch_close(p);
}

static void plant_on_nmt(simnode_plant_t *p, const md_frame_t *f)
{
    struct md_can_nmt_t m;
    const bool ok = f->len == MD_CAN_NMT_LENGTH && md_can_nmt_unpack(&m, f->data, f->len) == 0;
    const bool known = ok && (m.nmt_command == MD_NMT_START || m.nmt_command == MD_NMT_STOP ||
                              m.nmt_command == MD_NMT_PREOP || m.nmt_command == MD_NMT_RESET_NODE ||
                              m.nmt_command == MD_NMT_CLEAR_ESTOP);
    if (!known || m.nmt_target > 127u) {
        p->stats.rx_malformed++;
        return;
    }
    simnode_act_on_nmt(&p->act, simnode_nmt_apply(&p->act.node, m.nmt_command, m.nmt_target), p->now_us);
    simnode_hall_on_nmt(&p->hall, simnode_nmt_apply(&p->hall.node, m.nmt_command, m.nmt_target), p->now_us);
    simnode_fe_on_nmt(&p->fe, simnode_nmt_apply(&p->fe.node, m.nmt_command, m.nmt_target), p->now_us);
}

static void plant_on_estop(simnode_plant_t *p, const md_frame_t *f)
{
    struct md_can_estop_t m;
    if (f->len != MD_CAN_ESTOP_LENGTH || md_can_estop_unpack(&m, f->data, f->len) != 0) {
        p->stats.rx_malformed++;
        return;
    }
    simnode_act_on_estop(&p->act, m.estop_source, p->now_us);
    simnode_fe_abort(&p->fe, UINT32_MAX);
}

/* SIM_ADVANCE (lockstep only): the front-end lets Duration_us of simulated time
 * pass with nothing commanded, e.g. for the tissue to settle after a motion.
 * The answer is a batch like any other: SIM_CLOCK(t), the plant's periodic
 * frames that fall in (t, t + d] in time order, SIM_CLOCK(t + d); a zero
 * duration is answered with SIM_CLOCK(t) alone. Validated like a command of
 * the front-end; refused (no answer) when it is not operational, ignored in
 * realtime mode where the wall clock moves time. */
static void plant_on_step(simnode_plant_t *p, const md_frame_t *f)
{
    struct md_can_sim_advance_t m;
    simnode_t *fe = &p->fe.node;
    if (f->len != MD_CAN_SIM_ADVANCE_LENGTH || (f->flags & MD_FRAME_FLAG_FD) != 0u ||
        md_can_sim_advance_unpack(&m, f->data, f->len) != 0) {
        simnode_malformed(fe, f->id);
        return;
    }
    if (!p->cfg.lockstep) {
        p->stats.rx_ignored++;
        return;
    }
    if (!simnode_operational(fe)) {
        fe->stats.rx_refused++;
        return;
    }
    fe->stats.rx_frames++;
    p->stats.steps++;
    const uint64_t end_us = p->now_us + m.duration_us;
    if (!p->batch_clock_sent) { /* the answer starts with the clock even if nothing else goes out */
        p->batch_clock_sent = true;
        p->stats.batches++;
        plant_send_clock(p, p->batch_start_us);
    }
    /* bounded: every event time is > now and at most end_us */
    for (uint64_t t = simnode_plant_next_event_us(p); t <= end_us; t = simnode_plant_next_event_us(p)) {
        plant_run_at(p, (t > p->now_us) ? t : p->now_us);
    }
    if (end_us > p->now_us) {
        plant_run_at(p, end_us);
    }
}

static void plant_dispatch(simnode_plant_t *p, const md_frame_t *f)
{
    const uint64_t malformed_before = p->act.node.stats.rx_malformed + p->fe.node.stats.rx_malformed;
    if ((f->flags & MD_FRAME_FLAG_EXT) != 0u) {
        p->stats.rx_ignored++;
        return;
    }
    switch (f->id) {
    case MD_CAN_ESTOP_FRAME_ID: plant_on_estop(p, f); break;
    case MD_CAN_NMT_FRAME_ID: plant_on_nmt(p, f); break;
    case MD_CAN_ACT_CMD_FRAME_ID: {
        const int moving = simnode_act_on_cmd(&p->act, f, p->now_us);
        if (moving >= 0) {
            simnode_fe_abort(&p->fe, (uint32_t)moving); /* a recording does not survive a motion */
        }
        break;
    }
    case MD_CAN_REC_REQ_FRAME_ID: (void)simnode_fe_on_req(&p->fe, f, p->now_us); break;
    case MD_CAN_SIM_CLOCK_FRAME_ID: p->stats.rx_foreign_clock++; break;
    case MD_CAN_SIM_ADVANCE_FRAME_ID: plant_on_step(p, f); break;
    default: p->stats.rx_ignored++; break;
    }
    p->stats.rx_malformed += p->act.node.stats.rx_malformed + p->fe.node.stats.rx_malformed - malformed_before;
}

void simnode_plant_handle(simnode_plant_t *p, const md_frame_t *f)
{
    p->stats.rx_frames++;
    simnode_plant_silence_at(p, p->now_us);
    plant_batch_open(p);
    plant_dispatch(p, f);
    if (p->cfg.lockstep) {
        plant_run_lockstep(p);
    }
    plant_batch_close(p);
}

bool simnode_plant_advance(simnode_plant_t *p, uint64_t t_us)
{
    if (p->cfg.lockstep || t_us < p->now_us) {
        return false;
    }
    /* bounded by the events due in (now, t]; each moves time forward */
    for (uint64_t t = simnode_plant_next_event_us(p); t <= t_us; t = simnode_plant_next_event_us(p)) {
        plant_run_at(p, (t > p->now_us) ? t : p->now_us);
    }
    p->now_us = t_us;
    simnode_world_advance(p->world, t_us);
    simnode_plant_silence_at(p, t_us);
    return true;
}

simnode_t *simnode_plant_node(simnode_plant_t *p, md_node_id_t id)
{
    switch (id) {
    case MD_NODE_ACT: return &p->act.node;
    case MD_NODE_HALL: return &p->hall.node;
    case MD_NODE_FE: return &p->fe.node;
    case MD_NODE_CTRL:
    case MD_NODE_OPER:
    default: return NULL;
    }
}
