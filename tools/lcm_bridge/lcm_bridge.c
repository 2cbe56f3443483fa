/// @file lcm_bridge.c
/// CAN side of the bridge core: every telemetry and plant frame of the DBC that
/// has an LCM type, decoded with the cantools-generated md_can_*_unpack.
/// Grouping of the per-cycle frames is described in docs/telemetry.md.
#include <stdlib.h>
#include <string.h>

#include "lb_internal.h"
#include "mdlcm_actuator_t.h"
#include "mdlcm_cycle_t.h"
#include "mdlcm_hall_calib_t.h"
#include "mdlcm_hall_t.h"
#include "mdlcm_hypotheses_t.h"
#include "mdlcm_spikes_t.h"
#include "mdlcm_status_t.h"
#include "mdlcm_tracks_t.h"
#include "md_protocol.h"

#define LB_CALIB_BIT_MID (1u << 16)
#define LB_CALIB_BIT_HALF (1u << 17)

static void hall_publish(lb_t *st, size_t e);

size_t lb_size(void)
{
    return sizeof(lb_t);
}

int lb_init(lb_t *st, lb_time_mode_t mode, lb_sink_fn sink, void *sink_ctx)
{
    if (st == NULL || sink == NULL) {
        return -1;
    }
    memset(st, 0, sizeof *st);
    st->mode = mode;
    st->sink = sink;
    st->sink_ctx = sink_ctx;
    return 0;
}

int64_t lb_now_us(const lb_t *st)
{
    return st->mode == LB_TIME_SIM ? st->sim_time_us : st->frame_time_us;
}

const lb_stats_t *lb_stats(const lb_t *st)
{
    return &st->stats;
}

void lb_emit(lb_t *st, const char *channel, int64_t utime, const uint8_t *data, int len)
{
    if (len <= 0 || st->sink(st->sink_ctx, channel, utime, data, (size_t)len) < 0) {
        st->stats.sink_errors++;
        return;
    }
    st->stats.messages++;
}

/* ---- per-cycle groups ------------------------------------------------------------------------- */

/// Wave parts received contiguously from part 0, in samples.
static int16_t wave_samples(const lb_wave_t *w)
{
    unsigned parts = 0u;
    while (parts < LB_MAX_WAVE_PARTS && (w->parts_mask & (1u << parts)) != 0u) {
        ++parts;
    }
    return (int16_t)(parts * LB_WAVE_PART_LEN);
}

static size_t wave_index(const lb_group_t *g, uint16_t track_id)
{
    for (size_t i = 0u; i < g->n_waves; ++i) {
        if (g->wave[i].track_id == track_id) {
            return i;
        }
    }
    return SIZE_MAX;
}

static const lb_wave_t *wave_find(const lb_group_t *g, uint16_t track_id)
{
    const size_t i = wave_index(g, track_id);
    return (i == SIZE_MAX) ? NULL : &g->wave[i];
}

static void publish_tracks(lb_t *st, const lb_group_t *g)
{
    mdlcm_tracks_t m = {.utime = g->utime, .electrode = (int8_t)(g - st->group), .cycle = g->cycle};
    size_t idx[LB_MAX_TRACKS];
    size_t n = 0u;
    for (size_t i = 0u; i < LB_MAX_TRACKS; ++i) {
        if (g->track_have[i]) {
            idx[n++] = i;
        }
    }
    int16_t wave_len = 0;
    for (size_t k = 0u; k < n; ++k) {
        const lb_wave_t *w = wave_find(g, g->track[idx[k]].track_id);
        const int16_t s = (w != NULL) ? wave_samples(w) : 0;
        wave_len = (s > wave_len) ? s : wave_len;
    }
    m.num_tracks = (int16_t)n;
    m.pc_dim = 2;
    m.wave_len = wave_len;
    m.track_id = calloc(n + 1u, sizeof *m.track_id);
    m.spike_count = calloc(n + 1u, sizeof *m.spike_count);
    m.mean_pc = calloc(n + 1u, sizeof *m.mean_pc);
    float *pc = calloc(2u * n + 1u, sizeof *pc);
    m.snr = calloc(n + 1u, sizeof *m.snr);
    m.missed = calloc(n + 1u, sizeof *m.missed);
    m.wave_samples = calloc(n + 1u, sizeof *m.wave_samples);
    m.mean_wave_uv = calloc(n + 1u, sizeof *m.mean_wave_uv);
    float *wv = calloc((size_t)wave_len * n + 1u, sizeof *wv);
    if (m.track_id && m.spike_count && m.mean_pc && pc && m.snr && m.missed && m.wave_samples && m.mean_wave_uv && wv) {
        for (size_t k = 0u; k < n; ++k) {
            const struct md_can_tlm_track_t *t = &g->track[idx[k]];
            m.track_id[k] = t->track_id;
            m.spike_count[k] = t->spike_count;
            m.mean_pc[k] = &pc[2u * k];
            m.mean_pc[k][0] = t->mean_pc1;
            m.mean_pc[k][1] = t->mean_pc2;
            m.snr[k] = t->snr;
            m.missed[k] = t->missed;
            m.mean_wave_uv[k] = &wv[(size_t)wave_len * k];
            const lb_wave_t *w = wave_find(g, t->track_id);
            m.wave_samples[k] = (w != NULL) ? wave_samples(w) : 0;
            for (int16_t s = 0; s < m.wave_samples[k]; ++s) {
                m.mean_wave_uv[k][s] = (float)w->wave_uv[s];
            }
        }
        LB_PUBLISH(st, LB_CH_TRACKS, mdlcm_tracks_t, &m);
    } else {
        st->stats.sink_errors++;
    }
    free(m.track_id), free(m.spike_count), free(m.mean_pc), free(pc), free(m.snr);
    free(m.missed), free(m.wave_samples), free(m.mean_wave_uv), free(wv);
}

static void publish_hypotheses(lb_t *st, const lb_group_t *g)
{
    mdlcm_hypotheses_t m = {.utime = g->utime, .electrode = (int8_t)(g - st->group), .cycle = g->cycle};
    size_t n = 0u;
    for (size_t i = 0u; i < LB_MAX_HYPS; ++i) {
        n += g->hyp_have[i] ? 1u : 0u;
    }
    m.num_hypotheses = (int16_t)n;
    m.rank = calloc(n + 1u, sizeof *m.rank);
    m.hyp_id = calloc(n + 1u, sizeof *m.hyp_id);
    m.log_prob = calloc(n + 1u, sizeof *m.log_prob);
    m.num_tracks = calloc(n + 1u, sizeof *m.num_tracks);
    m.model_g = calloc(n + 1u, sizeof *m.model_g);
    if (m.rank && m.hyp_id && m.log_prob && m.num_tracks && m.model_g) {
        size_t k = 0u;
        for (size_t i = 0u; i < LB_MAX_HYPS; ++i) {
            if (g->hyp_have[i]) {
                m.rank[k] = g->hyp[i].rank;
                m.hyp_id[k] = g->hyp[i].hyp_id;
                m.log_prob[k] = g->hyp[i].log_prob;
                m.num_tracks[k] = g->hyp[i].num_tracks;
                m.model_g[k] = g->hyp[i].model_g;
                ++k;
            }
        }
        LB_PUBLISH(st, LB_CH_HYPOTHESES, mdlcm_hypotheses_t, &m);
    } else {
        st->stats.sink_errors++;
    }
    free(m.rank), free(m.hyp_id), free(m.log_prob), free(m.num_tracks), free(m.model_g);
}

static void publish_spikes(lb_t *st, const lb_group_t *g)
{
    mdlcm_spikes_t m = {.utime = g->utime, .electrode = (int8_t)(g - st->group), .cycle = g->cycle};
    m.interval_start_us = g->have_cycle ? (int64_t)g->cyc.start_time_us : -1;
    m.sample_rate_hz = g->have_cycle ? (int64_t)g->cyc.sample_rate_hz : 0;
    size_t n = 0u;
    for (size_t i = 0u; i < LB_MAX_SPIKES; ++i) {
        n += g->spike_have[i] ? 1u : 0u;
    }
    m.num_spikes = (int32_t)n;
    m.sample = calloc(n + 1u, sizeof *m.sample);
    m.track_id = calloc(n + 1u, sizeof *m.track_id);
    if (m.sample && m.track_id) {
        size_t k = 0u;
        for (size_t i = 0u; i < LB_MAX_SPIKES; ++i) {
            if (g->spike_have[i]) {
                m.sample[k] = (int32_t)g->spike_sample[i];
                m.track_id[k] = g->spike_track[i];
                ++k;
            }
        }
        LB_PUBLISH(st, LB_CH_SPIKES, mdlcm_spikes_t, &m);
    } else {
        st->stats.sink_errors++;
    }
    free(m.sample), free(m.track_id);
}

static void group_publish(lb_t *st, lb_group_t *g)
{
    publish_tracks(st, g);
    publish_hypotheses(st, g);
    publish_spikes(st, g);
    g->open = false;
    g->closed = true;
}

/// The group of (electrode, cycle), opened if needed; an open group of another
/// cycle is published first. NULL (counted) for a bad electrode or a late frame.
static lb_group_t *group_get(lb_t *st, uint8_t electrode, uint16_t cycle)
{
    if (electrode >= LB_MAX_ELECTRODES) {
        st->stats.dropped++;
        return NULL;
    }
    lb_group_t *g = &st->group[electrode];
    if (g->open && g->cycle != cycle) {
        group_publish(st, g);
    }
    if (!g->open) {
        if (g->closed && g->cycle == cycle) {
            st->stats.late++;
            return NULL;
        }
        memset(g, 0, sizeof *g);
        g->open = true;
        g->cycle = cycle;
    }
    g->utime = lb_now_us(st);
    return g;
}

/// Complete when TLM_STATUS came and every record it counts is in: its tracks
/// (each with at least its first wave part), its hypotheses, and TLM_SPIKES
/// parts holding at least its spike count (at least one part: the controller
/// sends one even for no spikes, and sends them last). Any order of arrival
/// works; an incomplete group goes out at the next cycle or at lb_flush.
static bool group_complete(const lb_group_t *g)
{
    if (!g->have_status || g->spike_frames == 0u) {
        return false;
    }
    size_t tracks = 0u, hyps = 0u, spikes = 0u;
    for (size_t i = 0u; i < LB_MAX_TRACKS; ++i) {
        if (g->track_have[i]) {
            const lb_wave_t *w = wave_find(g, g->track[i].track_id);
            if (w == NULL || (w->parts_mask & 1u) == 0u) {
                return false;
            }
            ++tracks;
        }
    }
    for (size_t i = 0u; i < LB_MAX_HYPS; ++i) {
        hyps += g->hyp_have[i] ? 1u : 0u;
    }
    for (size_t i = 0u; i < LB_MAX_SPIKES; ++i) {
        spikes += g->spike_have[i] ? 1u : 0u;
    }
    const size_t want_spikes = g->status.num_spikes < LB_MAX_SPIKES ? g->status.num_spikes : LB_MAX_SPIKES;
    return tracks == g->status.num_tracks && hyps == g->status.num_hypotheses && spikes >= want_spikes;
}

static void group_maybe_publish(lb_t *st, lb_group_t *g)
{
    if (g->open && group_complete(g)) {
        group_publish(st, g);
    }
}

void lb_flush(lb_t *st)
{
    for (size_t e = 0u; e < LB_MAX_ELECTRODES; ++e) {
        if (st->group[e].open) {
            group_publish(st, &st->group[e]);
        }
        hall_publish(st, e);
    }
    lb_truth_flush(st);
}

/* ---- controller telemetry ------------------------------------------------------------------- */

static void on_status(lb_t *st, const md_frame_t *f)
{
    struct md_can_tlm_status_t r;
    if (md_can_tlm_status_unpack(&r, f->data, f->len) != 0) {
        st->stats.malformed++;
        return;
    }
    lb_group_t *g = group_get(st, r.electrode, r.cycle);
    if (g == NULL) {
        return;
    }
    st->stats.telemetry++;
    g->have_status = true;
    g->status = r;
    const mdlcm_status_t m = {.utime = g->utime,
                              .electrode = (int8_t)r.electrode,
                              .cycle = r.cycle,
                              .sfsm_state = (int8_t)r.sfsm_state,
                              .depth_um = r.depth_um,
                              .target_depth_um = r.target_depth_um,
                              .snr = r.snr,
                              .iqm = r.iqm,
                              .dominant_track = r.dominant_track,
                              .num_tracks = r.num_tracks,
                              .num_hypotheses = r.num_hypotheses,
                              .num_spikes = r.num_spikes,
                              .flags = r.flags};
    LB_PUBLISH(st, LB_CH_STATUS, mdlcm_status_t, &m);
    group_maybe_publish(st, g);
}

static void on_cycle(lb_t *st, const md_frame_t *f)
{
    struct md_can_tlm_cycle_t r;
    if (md_can_tlm_cycle_unpack(&r, f->data, f->len) != 0) {
        st->stats.malformed++;
        return;
    }
    lb_group_t *g = group_get(st, r.electrode, r.cycle);
    if (g == NULL) {
        return;
    }
    st->stats.telemetry++;
    if (!g->have_cycle || r.phase == 1u) {
        g->have_cycle = true;
        g->cyc = r;
    }
    const mdlcm_cycle_t m = {.utime = g->utime,
                             .electrode = (int8_t)r.electrode,
                             .phase = (int8_t)r.phase,
                             .cycle = r.cycle,
                             .interval_id = r.interval_id,
                             .sample_rate_hz = r.sample_rate_hz,
                             .num_samples = r.num_samples,
                             .start_time_us = (int64_t)r.start_time_us};
    LB_PUBLISH(st, LB_CH_CYCLE, mdlcm_cycle_t, &m);
    group_maybe_publish(st, g);
}

/* The group of (electrode, cycle) for entry `index` of a table of `cap` (TLM_TRACK's index, TLM_HYP's
 * rank), counted as telemetry; NULL when group_get refuses or the index is out of range (dropped). */
static lb_group_t *group_entry(lb_t *st, uint8_t electrode, uint16_t cycle, size_t index, size_t cap)
{
    lb_group_t *g = group_get(st, electrode, cycle);
    if (g == NULL) {
        return NULL;
    }
    if (index >= cap) {
        st->stats.dropped++;
        return NULL;
    }
    st->stats.telemetry++;
    return g;
}

/* The handler `fn` of a frame that is one entry of a per-cycle table: TLM_TRACK (a track by its index) and
 * TLM_HYP (a hypothesis by its rank). The frame `msg` decoded, its entry r.idx of the group's `table` (of `cap`
 * entries) is stored and marked in table##_have. One definition for both, so the two cannot drift apart. */
#define LB_TABLE_ENTRY_HANDLER(fn, msg, idx, table, cap)                     \
    static void fn(lb_t *st, const md_frame_t *f)                            \
    {                                                                        \
        struct md_can_##msg##_t r;                                           \
        if (md_can_##msg##_unpack(&r, f->data, f->len) != 0) {               \
            st->stats.malformed++;                                           \
            return;                                                          \
        }                                                                    \
        lb_group_t *g = group_entry(st, r.electrode, r.cycle, r.idx, (cap)); \
        if (g == NULL) {                                                     \
            return;                                                          \
        }                                                                    \
        g->table##_have[r.idx] = true;                                       \
        g->table[r.idx] = r;                                                 \
        group_maybe_publish(st, g);                                          \
    }

LB_TABLE_ENTRY_HANDLER(on_track, tlm_track, index, track, LB_MAX_TRACKS)
LB_TABLE_ENTRY_HANDLER(on_hyp, tlm_hyp, rank, hyp, LB_MAX_HYPS)

static void on_wave(lb_t *st, const md_frame_t *f)
{
    struct md_can_tlm_wave_t r;
    if (md_can_tlm_wave_unpack(&r, f->data, f->len) != 0) {
        st->stats.malformed++;
        return;
    }
    if (r.electrode >= LB_MAX_ELECTRODES || r.part >= LB_MAX_WAVE_PARTS) {
        st->stats.dropped++;
        return;
    }
    lb_group_t *g = &st->group[r.electrode];
    if (!g->open) { /* TLM_WAVE carries no cycle: it belongs to the open group only */
        st->stats.late++;
        return;
    }
    size_t wi = wave_index(g, r.track_id);
    if (wi == SIZE_MAX) {
        if (g->n_waves >= LB_MAX_TRACKS) {
            st->stats.dropped++;
            return;
        }
        wi = g->n_waves++;
        g->wave[wi].track_id = r.track_id;
    }
    lb_wave_t *w = &g->wave[wi];
    const int16_t v[LB_WAVE_PART_LEN] = {r.wave00, r.wave01, r.wave02, r.wave03, r.wave04, r.wave05, r.wave06,
                                         r.wave07, r.wave08, r.wave09, r.wave10, r.wave11, r.wave12, r.wave13,
                                         r.wave14, r.wave15, r.wave16, r.wave17, r.wave18, r.wave19, r.wave20,
                                         r.wave21, r.wave22, r.wave23, r.wave24, r.wave25, r.wave26, r.wave27};
    memcpy(&w->wave_uv[(size_t)r.part * LB_WAVE_PART_LEN], v, sizeof v);
    w->parts_mask = (uint8_t)(w->parts_mask | (1u << r.part));
    st->stats.telemetry++;
    g->utime = lb_now_us(st);
    group_maybe_publish(st, g);
}

static void on_spikes(lb_t *st, const md_frame_t *f)
{
    struct md_can_tlm_spikes_t r;
    if (md_can_tlm_spikes_unpack(&r, f->data, f->len) != 0) {
        st->stats.malformed++;
        return;
    }
    lb_group_t *g = group_get(st, r.electrode, r.cycle);
    if (g == NULL) {
        return;
    }
    const uint32_t s[LB_SPIKES_PER_PART] = {r.sample00, r.sample01, r.sample02, r.sample03, r.sample04, r.sample05,
                                            r.sample06, r.sample07, r.sample08, r.sample09, r.sample10};
    const int16_t t[LB_SPIKES_PER_PART] = {r.track00, r.track01, r.track02, r.track03, r.track04, r.track05,
                                           r.track06, r.track07, r.track08, r.track09, r.track10};
    /* Count = entries used in this part (the DBC's 8-bit field cannot hold an interval's total). */
    const size_t count = r.count < LB_SPIKES_PER_PART ? r.count : LB_SPIKES_PER_PART;
    if (r.count > LB_SPIKES_PER_PART) {
        st->stats.malformed++;
    }
    for (size_t i = 0u; i < count; ++i) {
        const size_t pos = (size_t)r.part * LB_SPIKES_PER_PART + i;
        if (pos >= LB_MAX_SPIKES) {
            st->stats.dropped++;
            break;
        }
        g->spike_have[pos] = 1u;
        g->spike_sample[pos] = s[i];
        g->spike_track[pos] = t[i];
    }
    g->spike_frames++;
    st->stats.telemetry++;
    group_maybe_publish(st, g);
}

/* ---- plant frames ----------------------------------------------------------------------------- */

static void on_act_status(lb_t *st, const md_frame_t *f)
{
    struct md_can_act_status_t r;
    if (md_can_act_status_unpack(&r, f->data, f->len) != 0) {
        st->stats.malformed++;
        return;
    }
    st->stats.telemetry++;
    const mdlcm_actuator_t m = {.utime = lb_now_us(st),
                                .electrode = (int8_t)r.electrode,
                                .state = (int8_t)r.state,
                                .cmd_seq = r.cmd_seq,
                                .end_stops = (int8_t)r.end_stops,
                                .steps_done = r.steps_done,
                                .steps_remaining = r.steps_remaining};
    LB_PUBLISH(st, LB_CH_ACTUATOR, mdlcm_actuator_t, &m);
}

/// depth_um = sum_k c_k x^k with x = (code - code_mid) / code_half (DBC HALL_CALIB), Horner's rule.
static double calib_depth(const lb_calib_t *c, double code)
{
    const double x = (code - c->pub_mid) / c->pub_half;
    double acc = 0.0;
    for (size_t k = c->pub_count; k > 0u; --k) {
        acc = acc * x + c->pub_coeff[k - 1u];
    }
    return acc;
}

_Static_assert(LB_HALL_BATCH == MDLCM_HALL_T_MAX_READINGS, "batch size is the LCM constant");

/// Publishes electrode e's pending Hall readings as one hall_t (nothing if none).
static void hall_publish(lb_t *st, size_t e)
{
    lb_hall_batch_t *b = &st->hall[e];
    if (b->n == 0) {
        return;
    }
    const mdlcm_hall_t m = {.utime = b->utime,
                            .electrode = (int8_t)e,
                            .calibrated = b->calibrated,
                            .num_readings = b->n,
                            .seq = b->seq,
                            .raw_code = b->raw_code,
                            .sample_time_ms = b->sample_time_ms,
                            .depth_um = b->depth_um};
    LB_PUBLISH(st, LB_CH_HALL, mdlcm_hall_t, &m);
    b->n = 0;
}

/// Publishes the Hall batches whose time the bridge's clock has left, so that
/// nothing stamped later goes out before them.
static void hall_publish_due(lb_t *st)
{
    const int64_t now = lb_now_us(st);
    for (size_t e = 0u; e < LB_MAX_ELECTRODES; ++e) {
        if (st->hall[e].n > 0 && st->hall[e].utime != now) {
            hall_publish(st, e);
        }
    }
}

static void on_hall_reading(lb_t *st, const md_frame_t *f)
{
    struct md_can_hall_reading_t r;
    if (md_can_hall_reading_unpack(&r, f->data, f->len) != 0) {
        st->stats.malformed++;
        return;
    }
    if (r.electrode >= LB_MAX_ELECTRODES) {
        st->stats.dropped++;
        return;
    }
    st->stats.telemetry++;
    const lb_calib_t *c = &st->calib[r.electrode];
    lb_hall_batch_t *b = &st->hall[r.electrode];
    const int64_t now = lb_now_us(st);
    if (b->n > 0 && b->utime != now) {
        hall_publish(st, r.electrode);
    }
    b->utime = now;
    b->calibrated = c->valid;
    b->seq[b->n] = r.seq;
    b->raw_code[b->n] = r.raw_code;
    b->sample_time_ms[b->n] = r.sample_time_ms;
    b->depth_um[b->n] = c->valid ? calib_depth(c, (double)r.raw_code) : 0.0;
    if (++b->n >= (int16_t)LB_HALL_BATCH) {
        hall_publish(st, r.electrode);
    }
}

/// Publishes the collected set if it is complete and differs from the last one.
static void calib_maybe_publish(lb_t *st, lb_calib_t *c, uint8_t electrode)
{
    const uint32_t coeff_bits = (c->count >= 32u) ? 0u : ((1u << c->count) - 1u);
    const uint32_t need = coeff_bits | LB_CALIB_BIT_MID | LB_CALIB_BIT_HALF;
    if (c->count == 0u || c->count > LB_MAX_CALIB_COEFFS || (c->have_mask & need) != need ||
        !(c->code_half > 0.0f || c->code_half < 0.0f)) {
        return;
    }
    double coeff[LB_MAX_CALIB_COEFFS] = {0};
    for (size_t k = 0u; k < c->count; ++k) {
        coeff[k] = (double)c->coeff[k];
    }
    const double mid = (double)c->code_mid, half = (double)c->code_half;
    if (c->valid && c->pub_count == c->count && memcmp(coeff, c->pub_coeff, sizeof coeff) == 0 &&
        memcmp(&mid, &c->pub_mid, sizeof mid) == 0 && memcmp(&half, &c->pub_half, sizeof half) == 0) {
        return;
    }
    hall_publish(st, electrode); /* its readings so far were converted with the old set (or none) */
    c->valid = true;
    c->pub_count = c->count;
    memcpy(c->pub_coeff, coeff, sizeof coeff);
    c->pub_mid = mid;
    c->pub_half = half;
    const mdlcm_hall_calib_t m = {.utime = lb_now_us(st),
                                  .electrode = (int8_t)electrode,
                                  .code_mid = mid,
                                  .code_half = half,
                                  .num_coeffs = (int16_t)c->count,
                                  .coeff_um = c->pub_coeff};
    LB_PUBLISH(st, LB_CH_HALL_CALIB, mdlcm_hall_calib_t, &m);
}

static void on_hall_calib(lb_t *st, const md_frame_t *f)
{
    struct md_can_hall_calib_t r;
    if (md_can_hall_calib_unpack(&r, f->data, f->len) != 0) {
        st->stats.malformed++;
        return;
    }
    if (r.electrode >= LB_MAX_ELECTRODES || r.coeff_count > LB_MAX_CALIB_COEFFS) {
        st->stats.dropped++;
        return;
    }
    lb_calib_t *c = &st->calib[r.electrode];
    if (r.coeff_count != c->count) { /* a new polynomial: forget the old coefficients */
        c->count = r.coeff_count;
        c->have_mask &= (LB_CALIB_BIT_MID | LB_CALIB_BIT_HALF);
    }
    if (r.coeff_index == MD_HALL_CALIB_INDEX_CODE_MID) {
        c->code_mid = r.coeff_value;
        c->have_mask |= LB_CALIB_BIT_MID;
    } else if (r.coeff_index == MD_HALL_CALIB_INDEX_CODE_HALF) {
        c->code_half = r.coeff_value;
        c->have_mask |= LB_CALIB_BIT_HALF;
    } else if (r.coeff_index < LB_MAX_CALIB_COEFFS) {
        c->coeff[r.coeff_index] = r.coeff_value;
        c->have_mask |= 1u << r.coeff_index;
    } else {
        st->stats.dropped++;
        return;
    }
    st->stats.telemetry++;
    calib_maybe_publish(st, c, r.electrode);
}

static void on_sim_clock(lb_t *st, const md_frame_t *f)
{
    struct md_can_sim_clock_t r;
    if (md_can_sim_clock_unpack(&r, f->data, f->len) != 0) {
        st->stats.malformed++;
        return;
    }
    st->stats.telemetry++;
    st->sim_time_us = (r.sim_time_us > (uint64_t)INT64_MAX) ? INT64_MAX : (int64_t)r.sim_time_us;
    hall_publish_due(st);
}

void lb_feed_frame(lb_t *st, const md_frame_t *frame, int64_t frame_time_us)
{
    st->stats.frames++;
    st->frame_time_us = frame_time_us;
    if (st->mode == LB_TIME_FRAME) {
        hall_publish_due(st);
    }
    if ((frame->flags & MD_FRAME_FLAG_EXT) != 0u) {
        st->stats.ignored++;
        return;
    }
    switch (frame->id) {
    case MD_CAN_SIM_CLOCK_FRAME_ID: on_sim_clock(st, frame); break;
    case MD_CAN_TLM_STATUS_FRAME_ID: on_status(st, frame); break;
    case MD_CAN_TLM_CYCLE_FRAME_ID: on_cycle(st, frame); break;
    case MD_CAN_TLM_TRACK_FRAME_ID: on_track(st, frame); break;
    case MD_CAN_TLM_WAVE_FRAME_ID: on_wave(st, frame); break;
    case MD_CAN_TLM_HYP_FRAME_ID: on_hyp(st, frame); break;
    case MD_CAN_TLM_SPIKES_FRAME_ID: on_spikes(st, frame); break;
    case MD_CAN_ACT_STATUS_FRAME_ID: on_act_status(st, frame); break;
    case MD_CAN_HALL_READING_FRAME_ID: on_hall_reading(st, frame); break;
    case MD_CAN_HALL_CALIB_FRAME_ID: on_hall_calib(st, frame); break;
    default: st->stats.ignored++; break;
    }
}
