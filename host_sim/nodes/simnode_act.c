#include "simnode_act.h"

#include <string.h>

#include "md_can.h"

void simnode_act_init(simnode_act_t *a, simnode_world_t *world, bool autostart, bool lockstep,
                      uint32_t status_moving_ms, uint32_t status_idle_ms, simnode_sink_t sink)
{
    memset(a, 0, sizeof *a);
    simnode_init(&a->node, MD_NODE_ACT, simnode_world_electrodes(world), autostart, lockstep, sink);
    a->world = world;
    a->status_moving_ms = status_moving_ms;
    a->status_idle_ms = status_idle_ms;
    a->next_status_us = UINT64_MAX;
}

static uint8_t act_stops(const simnode_act_report_t *r)
{
    return (uint8_t)((r->at_upper_stop ? 0x01u : 0u) | (r->at_lower_stop ? 0x02u : 0u));
}

static uint8_t act_state(const simnode_act_t *a, const simnode_act_report_t *r)
{
    return a->node.estop_latched ? (uint8_t)MD_ACT_FAULT : r->state;
}

static void act_send_status(simnode_act_t *a, uint32_t e)
{
    const simnode_act_report_t r = simnode_world_act_report(a->world, e);
    struct md_can_act_status_t s;
    md_frame_t f;
    const uint32_t done = (r.steps_done > 0xFFFFu) ? 0xFFFFu : r.steps_done;
    const uint32_t left = (r.steps_requested > r.steps_done) ? r.steps_requested - r.steps_done : 0u;
    const bool moving = r.state == (uint8_t)MD_ACT_MOVING;
    s.electrode = (uint8_t)e;
    s.state = act_state(a, &r);
    s.cmd_seq = a->el[e].cmd_seq;
    s.end_stops = act_stops(&r);
    s.steps_done = (uint16_t)done;
    /* a stalled or halted command has nothing left to do */
    s.steps_remaining = moving ? (uint16_t)((left > 0xFFFFu) ? 0xFFFFu : left) : 0u;
    a->el[e].reported_state = s.state;
    a->el[e].reported_stops = s.end_stops;
    simnode_frame_init(&f, MD_CAN_ACT_STATUS_FRAME_ID, (uint8_t)MD_CAN_ACT_STATUS_LENGTH);
    (void)md_can_act_status_pack(f.data, &s, sizeof f.data);
    (void)simnode_send(&a->node, &f);
}

static void act_schedule_status(simnode_act_t *a, uint64_t t_us)
{
    const uint32_t ms = simnode_act_busy(a) ? a->status_moving_ms : a->status_idle_ms;
    a->next_status_us = t_us + (uint64_t)ms * 1000u;
}

void simnode_act_announce(simnode_act_t *a, uint64_t t_us)
{
    for (uint32_t e = 0; e < a->node.electrodes; e++) {
        act_send_status(a, e);
    }
    act_schedule_status(a, t_us);
}

static void act_halt_all(simnode_act_t *a)
{
    for (uint32_t e = 0; e < a->node.electrodes; e++) {
        (void)simnode_world_act_command(a->world, e, 0u, 1, 1.0);
    }
}

int simnode_act_on_cmd(simnode_act_t *a, const md_frame_t *f, uint64_t t_us)
{
    struct md_can_act_cmd_t c;
    if (f->len != MD_CAN_ACT_CMD_LENGTH || md_can_act_cmd_unpack(&c, f->data, f->len) != 0) {
        simnode_malformed(&a->node, f->id);
        return -1;
    }
    const bool step = c.command == MD_ACT_CMD_STEP;
    if (c.electrode >= a->node.electrodes || c.command > MD_ACT_CMD_STEP || c.direction > MD_ACT_DIR_RETRACT ||
        (step && (c.step_count == 0u || c.step_rate_hz == 0u))) {
        simnode_malformed(&a->node, f->id);
        return -1;
    }
    if (!simnode_operational(&a->node)) {
        a->node.stats.rx_refused++;
        return -1;
    }
    a->node.stats.rx_frames++;
    a->el[c.electrode].cmd_seq = c.seq;
    if (a->node.estop_latched && step) {
        a->node.stats.rx_refused++; /* acknowledged with State = fault */
        act_send_status(a, c.electrode);
        return -1;
    }
    const int dir = (c.direction == MD_ACT_DIR_ADVANCE) ? 1 : -1;
    const uint32_t count = step ? c.step_count : 0u;
    const double rate = step ? (double)c.step_rate_hz : 1.0;
    if (simnode_world_act_command(a->world, c.electrode, count, dir, rate) != MD_OK) {
        (void)simnode_emcy(&a->node, (uint16_t)MD_EMCY_SOFTWARE, c.electrode, (uint32_t)(int32_t)MD_E_STATE);
        a->node.fault = true;
    }
    act_send_status(a, c.electrode);
    if (step) {
        act_schedule_status(a, t_us); /* progress reports from the start of the move */
    }
    return step ? (int)c.electrode : -1;
}

void simnode_act_on_estop(simnode_act_t *a, uint8_t source, uint64_t t_us)
{
    const bool was_latched = a->node.estop_latched;
    a->node.stats.rx_frames++;
    act_halt_all(a);
    a->node.estop_latched = true;
    if (!was_latched) {
        a->estop_source = source;
        (void)simnode_emcy(&a->node, (uint16_t)MD_EMCY_ESTOP, 0xFFu, source);
    }
    if (simnode_operational(&a->node)) {
        simnode_act_announce(a, t_us);
    }
}

void simnode_act_on_nmt(simnode_act_t *a, simnode_nmt_effect_t effect, uint64_t t_us)
{
    switch (effect) {
    case SIMNODE_NMT_ENTER_OP: simnode_act_announce(a, t_us); break;
    case SIMNODE_NMT_LEAVE_OP:
        act_halt_all(a);
        a->next_status_us = UINT64_MAX;
        break;
    case SIMNODE_NMT_RESET:
        act_halt_all(a);
        for (uint32_t e = 0; e < a->node.electrodes; e++) {
            a->el[e].cmd_seq = 0u;
        }
        a->next_status_us = UINT64_MAX;
        if (simnode_operational(&a->node)) {
            simnode_act_announce(a, t_us);
        }
        break;
    case SIMNODE_NMT_CLEAR_ESTOP:
        if (simnode_operational(&a->node)) {
            simnode_act_announce(a, t_us);
        }
        break;
    case SIMNODE_NMT_NOT_ADDRESSED:
    default: break;
    }
}

uint64_t simnode_act_next_event_us(const simnode_act_t *a)
{
    uint64_t t = simnode_operational(&a->node) ? a->next_status_us : UINT64_MAX;
    for (uint32_t e = 0; e < a->node.electrodes; e++) {
        const uint64_t s = simnode_world_act_next_step_us(a->world, e);
        t = (s < t) ? s : t;
    }
    return t;
}

void simnode_act_run(simnode_act_t *a, uint64_t t_us)
{
    const bool operational = simnode_operational(&a->node);
    bool any_stalled = false;
    for (uint32_t e = 0; e < a->node.electrodes; e++) {
        const simnode_act_report_t r = simnode_world_act_report(a->world, e);
        const uint8_t state = act_state(a, &r);
        const uint8_t stops = act_stops(&r);
        any_stalled = any_stalled || r.state == (uint8_t)MD_ACT_STALLED;
        if (!operational || (state == a->el[e].reported_state && stops == a->el[e].reported_stops)) {
            continue;
        }
        const bool new_stall = r.state == (uint8_t)MD_ACT_STALLED && a->el[e].reported_state != state;
        const bool new_stop = (stops & (uint8_t)~a->el[e].reported_stops) != 0u;
        act_send_status(a, e);
        if (new_stall || new_stop) {
            /* Info: EndStops bits in the low byte, steps done above */
            (void)simnode_emcy(&a->node, (uint16_t)MD_EMCY_MOTION, (uint8_t)e,
                               (uint32_t)stops | ((r.steps_done & 0xFFFFFFu) << 8));
        }
    }
    a->node.fault = any_stalled;
    if (operational && t_us >= a->next_status_us) {
        for (uint32_t e = 0; e < a->node.electrodes; e++) {
            act_send_status(a, e);
        }
        act_schedule_status(a, t_us);
    }
}

bool simnode_act_busy(const simnode_act_t *a)
{
    for (uint32_t e = 0; e < a->node.electrodes; e++) {
        if (simnode_world_act_report(a->world, e).state == (uint8_t)MD_ACT_MOVING) {
            return true;
        }
    }
    return false;
}
