#include "simnode_fe.h"

#include <string.h>

#include "md_can.h"

_Static_assert(MD_REC_SAMPLES_PER_FRAME == 30u, "REC_DATA packing below lists 30 sample fields");

void simnode_fe_init(simnode_fe_t *fe, simnode_world_t *world, bool autostart, bool lockstep, uint32_t info_period_ms,
                     simnode_sink_t sink)
{
    memset(fe, 0, sizeof *fe);
    simnode_init(&fe->node, MD_NODE_FE, simnode_world_electrodes(world), autostart, lockstep, sink);
    fe->world = world;
    fe->rate_hz = simnode_world_fe_rate_hz(world);
    fe->gain_uv = simnode_world_fe_gain_uv(world);
    fe->info_period_us = (uint64_t)info_period_ms * 1000u;
    fe->next_info_us = UINT64_MAX;
}

static void fe_stream_end(simnode_fe_t *fe, uint32_t e)
{
    simnode_world_record_stop(fe->world, e);
    memset(&fe->st[e], 0, sizeof fe->st[e]);
}

void simnode_fe_announce(simnode_fe_t *fe, uint64_t t_us)
{
    fe->next_info_us = t_us + fe->info_period_us;
    for (uint32_t e = 0; e < fe->node.electrodes; e++) {
        struct md_can_fe_info_t info;
        md_frame_t f;
        info.electrode = (uint8_t)e;
        info.channels = 1u;
        info.sample_rate_hz = fe->rate_hz;
        info.gain_u_v_per_lsb = (float)fe->gain_uv;
        simnode_frame_init(&f, MD_CAN_FE_INFO_FRAME_ID, (uint8_t)MD_CAN_FE_INFO_LENGTH);
        (void)md_can_fe_info_pack(f.data, &info, sizeof f.data);
        (void)simnode_send(&fe->node, &f);
    }
}

static void fe_send_end(simnode_fe_t *fe, uint32_t e, uint16_t interval_id, uint8_t status, uint32_t total)
{
    struct md_can_rec_end_t end;
    md_frame_t f;
    end.electrode = (uint8_t)e;
    end.status = status;
    end.interval_id = interval_id;
    end.total_samples = total;
    simnode_frame_init(&f, MD_CAN_REC_END_FRAME_ID, (uint8_t)MD_CAN_REC_END_LENGTH);
    (void)md_can_rec_end_pack(f.data, &end, sizeof f.data);
    (void)simnode_send(&fe->node, &f);
}

/* Fills REC_DATA's 30 named sample fields from an array (cantools names each
 * field); unused fields stay 0. */
static void fe_fill_samples(struct md_can_rec_data_t *m, const int16_t *x, uint32_t n)
{
    int16_t *const slot[30] = {&m->sample00, &m->sample01, &m->sample02, &m->sample03, &m->sample04, &m->sample05,
                               &m->sample06, &m->sample07, &m->sample08, &m->sample09, &m->sample10, &m->sample11,
                               &m->sample12, &m->sample13, &m->sample14, &m->sample15, &m->sample16, &m->sample17,
                               &m->sample18, &m->sample19, &m->sample20, &m->sample21, &m->sample22, &m->sample23,
                               &m->sample24, &m->sample25, &m->sample26, &m->sample27, &m->sample28, &m->sample29};
    for (uint32_t i = 0; i < 30u; i++) {
        *slot[i] = (i < n) ? x[i] : (int16_t)0;
    }
}

static void fe_send_data(simnode_fe_t *fe, uint32_t e)
{
    simnode_fe_stream_t *s = &fe->st[e];
    const uint32_t left = s->n_total - s->n_sent;
    const uint32_t n = (left < MD_REC_SAMPLES_PER_FRAME) ? left : MD_REC_SAMPLES_PER_FRAME;
    int16_t x[MD_REC_SAMPLES_PER_FRAME];
    struct md_can_rec_data_t m;
    md_frame_t f;
    if (simnode_world_record_next(fe->world, e, n, x) != MD_OK) {
        fe->node.fault = true; /* cannot happen while the stream is active; counted if it does */
        (void)simnode_emcy(&fe->node, (uint16_t)MD_EMCY_SOFTWARE, (uint8_t)e, (uint32_t)(int32_t)MD_E_STATE);
        memset(x, 0, sizeof x);
    }
    memset(&m, 0, sizeof m);
    m.electrode = (uint8_t)e;
    m.sample_count = (uint8_t)n;
    m.seq = s->seq;
    fe_fill_samples(&m, x, n);
    simnode_frame_init(&f, MD_CAN_REC_DATA_FRAME_ID, (uint8_t)MD_CAN_REC_DATA_LENGTH);
    (void)md_can_rec_data_pack(f.data, &m, sizeof f.data);
    (void)simnode_send(&fe->node, &f);
    s->n_sent += n;
    s->seq++;
}

bool simnode_fe_on_req(simnode_fe_t *fe, const md_frame_t *f, uint64_t t_us)
{
    struct md_can_rec_req_t r;
    if (f->len != MD_CAN_REC_REQ_LENGTH || md_can_rec_req_unpack(&r, f->data, f->len) != 0 ||
        r.electrode >= fe->node.electrodes || r.num_samples == 0u || r.num_samples > SIMNODE_FE_MAX_SAMPLES) {
        simnode_malformed(&fe->node, f->id);
        return false;
    }
    if (!simnode_operational(&fe->node)) {
        fe->node.stats.rx_refused++;
        return false;
    }
    fe->node.stats.rx_frames++;
    simnode_fe_stream_t *s = &fe->st[r.electrode];
    if (s->active) {
        fe->node.stats.rx_refused++;
        fe_send_end(fe, r.electrode, r.interval_id, MD_REC_OVERFLOW, 0u);
        return false;
    }
    if (simnode_world_record_start(fe->world, r.electrode, r.interval_id, r.num_samples) != MD_OK) {
        fe->node.fault = true;
        (void)simnode_emcy(&fe->node, (uint16_t)MD_EMCY_SOFTWARE, r.electrode, (uint32_t)(int32_t)MD_E_STATE);
        fe_send_end(fe, r.electrode, r.interval_id, MD_REC_ABORTED, 0u);
        return false;
    }
    s->active = true;
    s->interval_id = r.interval_id;
    s->n_total = r.num_samples;
    s->n_sent = 0u;
    s->seq = 0u;
    s->t0_us = t_us;
    return true;
}

void simnode_fe_abort(simnode_fe_t *fe, uint32_t e)
{
    for (uint32_t i = 0; i < fe->node.electrodes; i++) {
        simnode_fe_stream_t *s = &fe->st[i];
        if ((e < fe->node.electrodes && i != e) || !s->active) {
            continue;
        }
        fe_send_end(fe, i, s->interval_id, MD_REC_ABORTED, s->n_sent);
        fe_stream_end(fe, i);
    }
}

void simnode_fe_on_nmt(simnode_fe_t *fe, simnode_nmt_effect_t effect, uint64_t t_us)
{
    switch (effect) {
    case SIMNODE_NMT_ENTER_OP: simnode_fe_announce(fe, t_us); break;
    case SIMNODE_NMT_LEAVE_OP:
        simnode_fe_abort(fe, UINT32_MAX);
        fe->next_info_us = UINT64_MAX;
        break;
    case SIMNODE_NMT_RESET:
        simnode_fe_abort(fe, UINT32_MAX);
        fe->node.fault = false;
        fe->next_info_us = UINT64_MAX;
        if (simnode_operational(&fe->node)) {
            simnode_fe_announce(fe, t_us);
        }
        break;
    case SIMNODE_NMT_CLEAR_ESTOP:
    case SIMNODE_NMT_NOT_ADDRESSED:
    default: break;
    }
}

/* Time at which the next frame of stream s is complete: its last sample taken. */
static uint64_t fe_frame_due_us(const simnode_fe_t *fe, const simnode_fe_stream_t *s)
{
    const uint32_t left = s->n_total - s->n_sent;
    const uint64_t last = (uint64_t)s->n_sent + ((left < MD_REC_SAMPLES_PER_FRAME) ? left : MD_REC_SAMPLES_PER_FRAME);
    return s->t0_us + (last * 1000000u + fe->rate_hz - 1u) / fe->rate_hz;
}

uint64_t simnode_fe_next_event_us(const simnode_fe_t *fe)
{
    uint64_t t = simnode_operational(&fe->node) ? fe->next_info_us : UINT64_MAX;
    for (uint32_t e = 0; e < fe->node.electrodes; e++) {
        if (fe->st[e].active) {
            const uint64_t d = fe_frame_due_us(fe, &fe->st[e]);
            t = (d < t) ? d : t;
        }
    }
    return t;
}

void simnode_fe_run(simnode_fe_t *fe, uint64_t t_us)
{
    if (simnode_operational(&fe->node) && t_us >= fe->next_info_us) {
        simnode_fe_announce(fe, t_us);
    }
    for (uint32_t e = 0; e < fe->node.electrodes; e++) {
        simnode_fe_stream_t *s = &fe->st[e];
        /* bounded: each pass sends one frame of a finite stream */
        while (s->active && fe_frame_due_us(fe, s) <= t_us) {
            fe_send_data(fe, e);
            if (s->n_sent >= s->n_total) {
                fe_send_end(fe, e, s->interval_id, MD_REC_COMPLETE, s->n_total);
                fe->intervals_done++;
                fe_stream_end(fe, e);
            }
        }
    }
}

bool simnode_fe_busy(const simnode_fe_t *fe)
{
    for (uint32_t e = 0; e < fe->node.electrodes; e++) {
        if (fe->st[e].active) {
            return true;
        }
    }
    return false;
}
