/// @file md_telemetry.c
/// Packing of TLM_CYCLE, TLM_STATUS, TLM_TRACK, TLM_WAVE, TLM_HYP, TLM_SPIKES. See md_telemetry.h.
#include "md_telemetry.h"

#include <math.h>
#include <string.h>

#include "md_can.h"

#define SPIKES_HEADER_BYTES 6u /* Electrode, Count, Cycle, Part */
#define SPIKES_ENTRY_BYTES 5u  /* Sample (24 bit) + Track (int16) */
#define WAVE_HEADER_BYTES 4u   /* Electrode, Part, TrackId */
#define INT16_LIMIT 32767.0

_Static_assert(SPIKES_HEADER_BYTES + MD_TLM_SPIKES_PER_PART * SPIKES_ENTRY_BYTES <= MD_CAN_TLM_SPIKES_LENGTH,
               "TLM_SPIKES layout of the DBC");
_Static_assert(WAVE_HEADER_BYTES + 2u * MD_TLM_WAVE_PER_PART <= MD_CAN_TLM_WAVE_LENGTH, "TLM_WAVE layout");

static float finite_f(double v)
{
    return isfinite(v) ? (float)v : 0.0f;
}

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)(v >> 8);
}

static int16_t sat_i16(double v)
{
    if (!isfinite(v)) {
        return 0;
    }
    const double r = floor(v + 0.5);
    return (int16_t)((r > INT16_LIMIT) ? INT16_LIMIT : ((r < -INT16_LIMIT - 1.0) ? -INT16_LIMIT - 1.0 : r));
}

md_status_t md_tlm_cycle(md_node_t *node, uint8_t e, const md_electrode_t *el, uint8_t phase, uint32_t num_samples)
{
    struct md_can_tlm_cycle_t m;
    uint8_t buf[MD_CAN_TLM_CYCLE_LENGTH];
    (void)md_can_tlm_cycle_init(&m);
    m.electrode = e;
    m.phase = phase;
    m.cycle = el->cycle;
    m.interval_id = el->interval_id;
    m.sample_rate_hz = el->sample_rate_hz;
    m.num_samples = num_samples;
    m.start_time_us = el->rec_start_us;
    return md_node_send(node, MD_CAN_TLM_CYCLE_FRAME_ID, buf, md_can_tlm_cycle_pack(buf, &m, sizeof buf), true);
}

md_status_t md_tlm_status(md_node_t *node, uint8_t e, const md_electrode_t *el, uint32_t num_spikes)
{
    struct md_can_tlm_status_t m;
    uint8_t buf[MD_CAN_TLM_STATUS_LENGTH];
    (void)md_can_tlm_status_init(&m);
    m.electrode = e;
    m.sfsm_state = (uint8_t)el->sfsm.state;
    m.cycle = el->cycle;
    m.depth_um = finite_f(el->depth_um);
    m.target_depth_um = finite_f(el->target_um);
    m.snr = el->has_dominant ? finite_f(el->snr) : 0.0f;
    m.iqm = el->has_dominant ? finite_f(el->iqm) : 0.0f;
    m.dominant_track = el->has_dominant ? (uint16_t)el->dominant : 0u;
    m.num_tracks = (el->mhtc.n_hyp > 0u) ? el->mhtc.hyp[0].n_tracks : 0u;
    m.num_hypotheses = (uint8_t)el->mhtc.n_hyp;
    m.flags = el->flags;
    m.num_spikes = (uint16_t)((num_spikes > UINT16_MAX) ? UINT16_MAX : num_spikes);
    m.guard_amp = md_can_tlm_status_guard_amp_encode(fmin(fmax(el->guard_amp, 0.0), 655.35));
    const uint64_t total = el->cost_detect + el->cost_chain;
    m.cycle_cost = (total > UINT32_MAX) ? UINT32_MAX : (uint32_t)total;
    m.process_cost = (el->cost_chain > UINT32_MAX) ? UINT32_MAX : (uint32_t)el->cost_chain;
    return md_node_send(node, MD_CAN_TLM_STATUS_FRAME_ID, buf, md_can_tlm_status_pack(buf, &m, sizeof buf), true);
}

/* Mean waveform (the track's Kalman mean, in the windows' µV) in parts of 28. */
static md_status_t send_wave(md_node_t *node, uint8_t e, const mhtc_track_t *t)
{
    md_status_t result = MD_OK;
    const size_t d_w = (t->kf.d_w <= KF_DW_MAX) ? t->kf.d_w : KF_DW_MAX;
    const size_t parts = (d_w + MD_TLM_WAVE_PER_PART - 1u) / MD_TLM_WAVE_PER_PART;
    for (size_t p = 0u; p < parts; ++p) {
        uint8_t buf[MD_CAN_TLM_WAVE_LENGTH];
        memset(buf, 0, sizeof buf);
        buf[0] = e;
        buf[1] = (uint8_t)p;
        put_u16(&buf[2], (uint16_t)t->id);
        for (size_t k = 0u; k < MD_TLM_WAVE_PER_PART && p * MD_TLM_WAVE_PER_PART + k < d_w; ++k) {
            put_u16(&buf[WAVE_HEADER_BYTES + 2u * k], (uint16_t)sat_i16(t->kf.x[p * MD_TLM_WAVE_PER_PART + k]));
        }
        if (md_node_send(node, MD_CAN_TLM_WAVE_FRAME_ID, buf, (int)sizeof buf, true) != MD_OK) {
            result = MD_E_IO;
        }
    }
    return result;
}

/* Index of track id in the result's report list, or -1. */
static int report_of(const mhtc_result_t *r, uint32_t id)
{
    for (size_t j = 0u; j < r->n_tracks && j < MHTC_TARGETS_MAX; ++j) {
        if (r->track[j].id == id) {
            return (int)j;
        }
    }
    return -1;
}

static md_status_t send_tracks(md_node_t *node, uint8_t e, const md_electrode_t *el, const md_workspace_t *ws)
{
    md_status_t result = MD_OK;
    if (el->mhtc.n_hyp == 0u) {
        return MD_OK;
    }
    const mhtc_hyp_t *h = &el->mhtc.hyp[0];
    for (size_t i = 0u; i < h->n_tracks && i < MHTC_TARGETS_MAX; ++i) {
        const mhtc_track_t *t = &el->mhtc.pool[h->track[i]];
        const int j = report_of(&ws->res, t->id);
        struct md_can_tlm_track_t m;
        uint8_t buf[MD_CAN_TLM_TRACK_LENGTH];
        (void)md_can_tlm_track_init(&m);
        m.electrode = e;
        m.index = (uint8_t)i;
        m.track_id = (uint16_t)t->id;
        m.cycle = el->cycle;
        m.spike_count = (t->misses == 0u) ? (uint16_t)fmin(fmax(t->n_last, 0.0), 65535.0) : 0u;
        m.mean_pc1 = (j >= 0) ? finite_f(ws->res.track[j].mean_feat[0]) : 0.0f;
        m.mean_pc2 = (j >= 0) ? finite_f(ws->res.track[j].mean_feat[1]) : 0.0f;
        m.snr = (j >= 0) ? finite_f(ws->track_snr[j]) : 0.0f;
        m.missed = t->misses;
        if (md_node_send(node, MD_CAN_TLM_TRACK_FRAME_ID, buf, md_can_tlm_track_pack(buf, &m, sizeof buf), true) !=
                MD_OK ||
            send_wave(node, e, t) != MD_OK) {
            result = MD_E_IO;
        }
    }
    return result;
}

/* HypId: (tracker interval << 8) | (parent index << 4) | rank — unique per
 * electrode and interval, and it names the parent (docs/controller.md). */
static md_status_t send_hyps(md_node_t *node, uint8_t e, const md_electrode_t *el)
{
    md_status_t result = MD_OK;
    for (size_t h = 0u; h < el->mhtc.n_hyp && h < MHTC_L_MAX; ++h) {
        const mhtc_hyp_t *hy = &el->mhtc.hyp[h];
        struct md_can_tlm_hyp_t m;
        uint8_t buf[MD_CAN_TLM_HYP_LENGTH];
        (void)md_can_tlm_hyp_init(&m);
        m.electrode = e;
        m.rank = (uint8_t)h;
        m.cycle = el->cycle;
        m.hyp_id = (el->mhtc.interval << 8) | ((uint32_t)(hy->parent & 0x0Fu) << 4) | (uint32_t)h;
        m.log_prob = finite_f(hy->log_prob);
        m.num_tracks = hy->n_tracks;
        m.model_g = hy->g;
        if (md_node_send(node, MD_CAN_TLM_HYP_FRAME_ID, buf, md_can_tlm_hyp_pack(buf, &m, sizeof buf), true) != MD_OK) {
            result = MD_E_IO;
        }
    }
    return result;
}

/* Track id of spike i under the leading hypothesis (labels: cluster, 0 = outlier). */
static int16_t spike_track(const md_workspace_t *ws, size_t i, bool labelled)
{
    if (!labelled || i >= ws->n_spikes) {
        return (int16_t)MD_TLM_TRACK_UNLABELLED;
    }
    const uint8_t c = ws->res.labels[i];
    if (c == 0u || c > ws->res.g || c > MHTC_G_MAX) {
        return (int16_t)MD_TLM_TRACK_OUTLIER;
    }
    const int32_t id = ws->res.cluster_track[c - 1u];
    return (id > 0 && id <= (int32_t)INT16_LIMIT) ? (int16_t)id : (int16_t)MD_TLM_TRACK_OUTLIER;
}

static md_status_t send_spikes(md_node_t *node, uint8_t e, const md_electrode_t *el, const md_workspace_t *ws,
                               bool labelled)
{
    md_status_t result = MD_OK;
    const size_t n = ws->win.n;
    const size_t parts = (n == 0u) ? 1u : (n + MD_TLM_SPIKES_PER_PART - 1u) / MD_TLM_SPIKES_PER_PART;
    for (size_t p = 0u; p < parts; ++p) {
        uint8_t buf[MD_CAN_TLM_SPIKES_LENGTH];
        memset(buf, 0, sizeof buf);
        const size_t first = p * MD_TLM_SPIKES_PER_PART;
        const size_t count = (n - first < MD_TLM_SPIKES_PER_PART) ? n - first : MD_TLM_SPIKES_PER_PART;
        buf[0] = e;
        buf[1] = (uint8_t)count;
        put_u16(&buf[2], el->cycle);
        put_u16(&buf[4], (uint16_t)p);
        for (size_t k = 0u; k < count; ++k) {
            uint8_t *q = &buf[SPIKES_HEADER_BYTES + k * SPIKES_ENTRY_BYTES];
            const uint32_t t = ws->win.t[first + k] & 0xFFFFFFu;
            q[0] = (uint8_t)(t & 0xFFu);
            q[1] = (uint8_t)((t >> 8) & 0xFFu);
            q[2] = (uint8_t)(t >> 16);
            put_u16(&q[3], (uint16_t)spike_track(ws, first + k, labelled));
        }
        if (md_node_send(node, MD_CAN_TLM_SPIKES_FRAME_ID, buf, (int)sizeof buf, true) != MD_OK) {
            result = MD_E_IO;
        }
    }
    return result;
}

md_status_t md_tlm_interval(md_node_t *node, uint8_t e, const md_electrode_t *el, const md_workspace_t *ws)
{
    const md_status_t a = send_tracks(node, e, el, ws);
    const md_status_t b = send_hyps(node, e, el);
    const md_status_t c = send_spikes(node, e, el, ws, true);
    return (a != MD_OK) ? a : ((b != MD_OK) ? b : c);
}

md_status_t md_tlm_spikes_unlabelled(md_node_t *node, uint8_t e, const md_electrode_t *el, const md_workspace_t *ws)
{
    return send_spikes(node, e, el, ws, false);
}
