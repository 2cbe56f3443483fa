#include "simnode_hall.h"

#include <math.h>
#include <string.h>

#include "md_can.h"

void simnode_hall_init(simnode_hall_t *h, simnode_world_t *world, bool autostart, bool lockstep, double rate_hz,
                       uint32_t calib_period_ms, simnode_sink_t sink)
{
    memset(h, 0, sizeof *h);
    simnode_init(&h->node, MD_NODE_HALL, simnode_world_electrodes(world), autostart, lockstep, sink);
    h->world = world;
    const double period = floor(1e6 / rate_hz + 0.5);
    h->period_us = (period < 1.0) ? 1u : (uint64_t)period;
    h->calib_period_us = (uint64_t)calib_period_ms * 1000u;
    h->next_reading_us = UINT64_MAX;
    h->next_calib_us = UINT64_MAX;
}

static void hall_send_coeff(simnode_hall_t *h, uint32_t e, uint32_t index, uint32_t count, double value)
{
    struct md_can_hall_calib_t c;
    md_frame_t f;
    c.electrode = (uint8_t)e;
    c.coeff_index = (uint8_t)index;
    c.coeff_count = (uint8_t)count;
    c.coeff_value = (float)value;
    simnode_frame_init(&f, MD_CAN_HALL_CALIB_FRAME_ID, (uint8_t)MD_CAN_HALL_CALIB_LENGTH);
    (void)md_can_hall_calib_pack(f.data, &c, sizeof f.data);
    (void)simnode_send(&h->node, &f);
}

static void hall_send_calibration(simnode_hall_t *h)
{
    for (uint32_t e = 0; e < h->node.electrodes; e++) {
        simnode_hall_cal_t cal;
        simnode_world_hall_cal(h->world, e, &cal);
        for (uint32_t k = 0; k < cal.count; k++) {
            hall_send_coeff(h, e, k, cal.count, cal.coef[k]);
        }
        hall_send_coeff(h, e, SIMNODE_HALL_CAL_INDEX_MID, cal.count, cal.code_mid);
        hall_send_coeff(h, e, SIMNODE_HALL_CAL_INDEX_HALF, cal.count, cal.code_half);
    }
}

static void hall_send_readings(simnode_hall_t *h, uint64_t t_us)
{
    for (uint32_t e = 0; e < h->node.electrodes; e++) {
        struct md_can_hall_reading_t r;
        md_frame_t f;
        r.electrode = (uint8_t)e;
        r.seq = h->seq[e]++; /* wraps at 256 by the type: loss stays detectable */
        r.raw_code = simnode_world_hall_read(h->world, e);
        r.sample_time_ms = (uint32_t)(t_us / 1000u);
        simnode_frame_init(&f, MD_CAN_HALL_READING_FRAME_ID, (uint8_t)MD_CAN_HALL_READING_LENGTH);
        (void)md_can_hall_reading_pack(f.data, &r, sizeof f.data);
        (void)simnode_send(&h->node, &f);
    }
}

/* The next tick of the fixed grid k * period strictly after t. */
static uint64_t hall_next_tick(const simnode_hall_t *h, uint64_t t_us)
{
    return (t_us / h->period_us + 1u) * h->period_us;
}

void simnode_hall_announce(simnode_hall_t *h, uint64_t t_us)
{
    hall_send_calibration(h);
    hall_send_readings(h, t_us);
    h->next_reading_us = hall_next_tick(h, t_us);
    h->next_calib_us = t_us + h->calib_period_us;
}

void simnode_hall_on_nmt(simnode_hall_t *h, simnode_nmt_effect_t effect, uint64_t t_us)
{
    switch (effect) {
    case SIMNODE_NMT_ENTER_OP: simnode_hall_announce(h, t_us); break;
    case SIMNODE_NMT_RESET:
        memset(h->seq, 0, sizeof h->seq);
        h->next_reading_us = UINT64_MAX;
        h->next_calib_us = UINT64_MAX;
        if (simnode_operational(&h->node)) {
            simnode_hall_announce(h, t_us);
        }
        break;
    case SIMNODE_NMT_LEAVE_OP:
        h->next_reading_us = UINT64_MAX;
        h->next_calib_us = UINT64_MAX;
        break;
    case SIMNODE_NMT_CLEAR_ESTOP:
    case SIMNODE_NMT_NOT_ADDRESSED:
    default: break;
    }
}

uint64_t simnode_hall_next_event_us(const simnode_hall_t *h)
{
    if (!simnode_operational(&h->node)) {
        return UINT64_MAX;
    }
    return (h->next_reading_us < h->next_calib_us) ? h->next_reading_us : h->next_calib_us;
}

void simnode_hall_run(simnode_hall_t *h, uint64_t t_us)
{
    if (!simnode_operational(&h->node)) {
        return;
    }
    if (t_us >= h->next_calib_us) {
        hall_send_calibration(h);
        h->next_calib_us = t_us + h->calib_period_us;
    }
    if (t_us >= h->next_reading_us) {
        hall_send_readings(h, t_us);
        h->next_reading_us = hall_next_tick(h, t_us);
    }
}
