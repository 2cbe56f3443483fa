/// Unit-level test of the md-lcm-bridge core (tools/lcm_bridge/lcm_bridge.h):
/// frames packed with the generated md_can_*_pack go in, the encoded LCM
/// messages the sink receives are decoded with the lcm-gen C types and
/// checked field by field. Covers the grouping rules of docs/telemetry.md
/// (TLM_STATUS closes a complete cycle, a new cycle flushes the old one, late
/// frames are counted), wave parts in any order, Hall calibration (published
/// once per change, depth from the polynomial), Hall readings batched per
/// electrode and clock value, the sim clock, malformed and out-of-range input,
/// and the truth-line parser.
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lcm_bridge.h"
#include "md_can.h"
#include "md_protocol.h"
#include "mdlcm_actuator_t.h"
#include "mdlcm_hall_calib_t.h"
#include "mdlcm_hall_t.h"
#include "mdlcm_hypotheses_t.h"
#include "mdlcm_spikes_t.h"
#include "mdlcm_status_t.h"
#include "mdlcm_tracks_t.h"
#include "mdlcm_truth_session_t.h"
#include "mdlcm_truth_spikes_t.h"
#include "mdlcm_truth_state_t.h"
#include "unity.h"

#define CAP_MSGS 64
#define CAP_BYTES 65536

typedef struct {
    int n;
    char channel[CAP_MSGS][32];
    int64_t utime[CAP_MSGS];
    size_t len[CAP_MSGS];
    uint8_t data[CAP_MSGS][CAP_BYTES / 16];
} capture_t;

static capture_t g_cap;
static lb_t *g_st;

static int capture(void *ctx, const char *channel, int64_t utime, const uint8_t *data, size_t len)
{
    capture_t *c = ctx;
    if (c->n >= CAP_MSGS || len > sizeof c->data[0]) {
        return -1;
    }
    strncpy(c->channel[c->n], channel, sizeof c->channel[0] - 1u);
    c->utime[c->n] = utime;
    c->len[c->n] = len;
    memcpy(c->data[c->n], data, len);
    c->n++;
    return 0;
}

void setUp(void)
{
    memset(&g_cap, 0, sizeof g_cap);
    g_st = malloc(lb_size());
    TEST_ASSERT_NOT_NULL(g_st);
    TEST_ASSERT_EQUAL_INT(0, lb_init(g_st, LB_TIME_SIM, capture, &g_cap));
}

void tearDown(void)
{
    free(g_st);
}

/// Index of the k-th captured message on channel, or -1.
static int find(const char *channel, int k)
{
    for (int i = 0; i < g_cap.n; ++i) {
        if (strcmp(g_cap.channel[i], channel) == 0 && k-- == 0) {
            return i;
        }
    }
    return -1;
}

static int count(const char *channel)
{
    int n = 0;
    while (find(channel, n) >= 0) {
        ++n;
    }
    return n;
}

static md_frame_t frame_of(uint32_t id, const uint8_t *data, size_t len)
{
    md_frame_t f = {.id = id, .len = (uint8_t)len, .flags = (uint8_t)(len > 8u ? MD_FRAME_FLAG_FD : 0u)};
    memcpy(f.data, data, len);
    return f;
}

#define FEED(kind, KIND, msg)                                                                          \
    do {                                                                                               \
        uint8_t buf_[64] = {0};                                                                        \
        TEST_ASSERT_EQUAL_INT(MD_CAN_##KIND##_LENGTH, md_can_##kind##_pack(buf_, (msg), sizeof buf_)); \
        md_frame_t f_ = frame_of(MD_CAN_##KIND##_FRAME_ID, buf_, MD_CAN_##KIND##_LENGTH);              \
        lb_feed_frame(g_st, &f_, 0);                                                                   \
    } while (0)

static void feed_clock(uint64_t t_us)
{
    struct md_can_sim_clock_t c = {.sim_time_us = t_us};
    FEED(sim_clock, SIM_CLOCK, &c);
}

static void feed_track(uint8_t e, uint8_t index, uint16_t id, uint16_t cycle, float pc1, uint8_t missed)
{
    struct md_can_tlm_track_t t = {.electrode = e,
                                   .index = index,
                                   .track_id = id,
                                   .cycle = cycle,
                                   .spike_count = (uint16_t)(10u + index),
                                   .mean_pc1 = pc1,
                                   .mean_pc2 = -pc1,
                                   .snr = 5.5f,
                                   .missed = missed};
    FEED(tlm_track, TLM_TRACK, &t);
}

static void feed_wave(uint8_t e, uint16_t id, uint8_t part, int16_t base)
{
    struct md_can_tlm_wave_t w = {.electrode = e, .part = part, .track_id = id};
    int16_t *v = &w.wave00;
    for (int i = 0; i < 28; ++i) {
        v[i] = (int16_t)(base + i); /* the wave fields are consecutive int16_t members */
    }
    FEED(tlm_wave, TLM_WAVE, &w);
}

static void feed_hyp(uint8_t e, uint8_t rank, uint16_t cycle, float log_prob)
{
    struct md_can_tlm_hyp_t h = {.electrode = e,
                                 .rank = rank,
                                 .cycle = cycle,
                                 .hyp_id = 1000u + rank,
                                 .log_prob = log_prob,
                                 .num_tracks = 2,
                                 .model_g = 3};
    FEED(tlm_hyp, TLM_HYP, &h);
}

static void feed_status(uint8_t e, uint16_t cycle, uint8_t tracks, uint8_t hyps, uint16_t spikes)
{
    struct md_can_tlm_status_t s = {.electrode = e,
                                    .sfsm_state = 3,
                                    .cycle = cycle,
                                    .depth_um = 1234.5f,
                                    .target_depth_um = 1240.0f,
                                    .snr = 7.25f,
                                    .iqm = 0.8f,
                                    .dominant_track = 7,
                                    .num_tracks = tracks,
                                    .num_hypotheses = hyps,
                                    .flags = 0x5u,
                                    .num_spikes = spikes};
    FEED(tlm_status, TLM_STATUS, &s);
}

static void feed_spikes(uint8_t e, uint16_t cycle, uint16_t part, uint8_t n, uint32_t first)
{
    struct md_can_tlm_spikes_t s = {.electrode = e, .count = n, .cycle = cycle, .part = part};
    uint32_t *samples[11] = {&s.sample00, &s.sample01, &s.sample02, &s.sample03, &s.sample04, &s.sample05,
                             &s.sample06, &s.sample07, &s.sample08, &s.sample09, &s.sample10};
    int16_t *tracks[11] = {&s.track00, &s.track01, &s.track02, &s.track03, &s.track04, &s.track05,
                           &s.track06, &s.track07, &s.track08, &s.track09, &s.track10};
    for (uint8_t i = 0; i < 11u; ++i) {
        *samples[i] = first + 100u * i;
        *tracks[i] = (int16_t)(i % 3u == 0u ? -1 : 7);
    }
    FEED(tlm_spikes, TLM_SPIKES, &s);
}

/// One complete cycle: 2 tracks with 2 wave parts each, 3 hypotheses, 13 spikes, TLM_STATUS last.
static void feed_cycle(uint8_t e, uint16_t cycle)
{
    feed_track(e, 0, 7, cycle, 1.5f, 0);
    feed_track(e, 1, 9, cycle, -2.5f, 2);
    feed_wave(e, 9, 1, 900); /* parts out of order */
    feed_wave(e, 7, 0, 100);
    feed_wave(e, 7, 1, 200);
    feed_wave(e, 9, 0, 800);
    feed_hyp(e, 1, cycle, -1.0f);
    feed_hyp(e, 0, cycle, -0.5f);
    feed_hyp(e, 2, cycle, -3.0f);
    feed_spikes(e, cycle, 0, 11, 50);
    feed_spikes(e, cycle, 1, 2, 5000);
}

/* The MD_STATUS message of the cycle test_complete_cycle_published_at_status feeds. */
static void check_status_message(void)
{
    const int i = find(LB_CH_STATUS, 0);
    mdlcm_status_t s;
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_status_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &s));
    TEST_ASSERT_EQUAL_INT64(20000000, s.utime);
    TEST_ASSERT_EQUAL_INT(1, s.electrode);
    TEST_ASSERT_EQUAL_INT(42, s.cycle);
    TEST_ASSERT_EQUAL_INT(MDLCM_STATUS_T_SFSM_NEURON_ISOLATED, s.sfsm_state);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 1234.5f, s.depth_um);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 1240.0f, s.target_depth_um);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 7.25f, s.snr);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 0.8f, s.iqm);
    TEST_ASSERT_EQUAL_INT(7, s.dominant_track);
    TEST_ASSERT_EQUAL_INT(2, s.num_tracks);
    TEST_ASSERT_EQUAL_INT(3, s.num_hypotheses);
    TEST_ASSERT_EQUAL_INT(13, s.num_spikes);
    TEST_ASSERT_EQUAL_INT64(5, s.flags);
}

/* ... its MD_TRACKS message. */
static void check_tracks_message(void)
{
    const int i = find(LB_CH_TRACKS, 0);
    mdlcm_tracks_t t;
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_tracks_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &t));
    TEST_ASSERT_EQUAL_INT(2, t.num_tracks);
    TEST_ASSERT_EQUAL_INT(56, t.wave_len);
    TEST_ASSERT_EQUAL_INT(7, t.track_id[0]);
    TEST_ASSERT_EQUAL_INT(9, t.track_id[1]);
    TEST_ASSERT_EQUAL_INT(11, t.spike_count[1]);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, -2.5f, t.mean_pc[1][0]);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 2.5f, t.mean_pc[1][1]);
    TEST_ASSERT_EQUAL_INT(2, t.missed[1]);
    TEST_ASSERT_EQUAL_INT(56, t.wave_samples[0]);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 100.0f, t.mean_wave_uv[0][0]);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 227.0f, t.mean_wave_uv[0][55]);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 827.0f, t.mean_wave_uv[1][27]);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 900.0f, t.mean_wave_uv[1][28]);
    mdlcm_tracks_t_decode_cleanup(&t);
}

/* ... its MD_HYPOTHESES message. */
static void check_hypotheses_message(void)
{
    const int i = find(LB_CH_HYPOTHESES, 0);
    mdlcm_hypotheses_t h;
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_hypotheses_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &h));
    TEST_ASSERT_EQUAL_INT(3, h.num_hypotheses);
    for (int r = 0; r < 3; ++r) {
        TEST_ASSERT_EQUAL_INT(r, h.rank[r]); /* sorted by rank whatever the arrival order */
        TEST_ASSERT_EQUAL_INT64(1000 + r, h.hyp_id[r]);
    }
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, -0.5f, h.log_prob[0]);
    TEST_ASSERT_EQUAL_INT(3, h.model_g[2]);
    mdlcm_hypotheses_t_decode_cleanup(&h);
}

/* ... its MD_SPIKES message. */
static void check_spikes_message(void)
{
    const int i = find(LB_CH_SPIKES, 0);
    mdlcm_spikes_t sp;
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_spikes_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &sp));
    TEST_ASSERT_EQUAL_INT(13, sp.num_spikes);
    TEST_ASSERT_EQUAL_INT(50, sp.sample[0]);
    TEST_ASSERT_EQUAL_INT(1050, sp.sample[10]);
    TEST_ASSERT_EQUAL_INT(5100, sp.sample[12]);
    TEST_ASSERT_EQUAL_INT(MDLCM_SPIKES_T_LABEL_OUTLIER, sp.track_id[0]);
    TEST_ASSERT_EQUAL_INT(7, sp.track_id[1]);
    TEST_ASSERT_EQUAL_INT64(-1, sp.interval_start_us); /* no TLM_CYCLE in this group */
    mdlcm_spikes_t_decode_cleanup(&sp);
}

static void test_complete_cycle_published_at_status(void)
{
    feed_clock(20000000u);
    feed_cycle(1, 42);
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_TRACKS)); /* nothing before TLM_STATUS */
    feed_status(1, 42, 2, 3, 13);
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_STATUS));
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_TRACKS));
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_HYPOTHESES));
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_SPIKES));
    check_status_message();
    check_tracks_message();
    check_hypotheses_message();
    check_spikes_message();
}

/// The controller's order (firmware/app/md_telemetry.c): TLM_STATUS first, TLM_SPIKES
/// last, one empty TLM_SPIKES part when nothing was detected.
static void test_controller_order_status_first(void)
{
    feed_status(0, 3, 1, 1, 0);
    feed_track(0, 0, 5, 3, 0.5f, 1);
    feed_wave(0, 5, 0, 10);
    feed_wave(0, 5, 1, 20);
    feed_hyp(0, 0, 3, 0.0f);
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_TRACKS)); /* waits for TLM_SPIKES */
    feed_spikes(0, 3, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_TRACKS));
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_SPIKES));
    TEST_ASSERT_EQUAL_UINT64(0, lb_stats(g_st)->late);
    feed_status(0, 4, 1, 1, 12); /* next cycle: 12 spikes in two parts */
    feed_track(0, 0, 5, 4, 0.5f, 0);
    feed_wave(0, 5, 0, 10);
    feed_hyp(0, 0, 4, 0.0f);
    feed_spikes(0, 4, 0, 11, 0);
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_SPIKES));
    feed_spikes(0, 4, 1, 1, 9000);
    TEST_ASSERT_EQUAL_INT(2, count(LB_CH_SPIKES));
    TEST_ASSERT_EQUAL_UINT64(0, lb_stats(g_st)->late);
}

static void test_new_cycle_flushes_incomplete_group_and_late_frames_counted(void)
{
    feed_track(0, 0, 3, 5, 1.0f, 0); /* no waves, no status: incomplete */
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_TRACKS));
    feed_hyp(0, 0, 6, 0.0f); /* cycle 6 starts: cycle 5 goes out as it is */
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_TRACKS));
    feed_status(0, 6, 0, 1, 0);
    feed_spikes(0, 6, 0, 0, 0); /* cycle 6 complete: 0 tracks, 1 hypothesis, one empty spike part */
    TEST_ASSERT_EQUAL_INT(2, count(LB_CH_TRACKS));
    TEST_ASSERT_EQUAL_INT(2, count(LB_CH_HYPOTHESES));
    feed_track(0, 0, 3, 6, 1.0f, 0); /* after the cycle was published */
    feed_wave(0, 3, 0, 0);
    TEST_ASSERT_EQUAL_UINT64(2, lb_stats(g_st)->late);
    TEST_ASSERT_EQUAL_INT(2, count(LB_CH_TRACKS));
    lb_flush(g_st); /* nothing open */
    TEST_ASSERT_EQUAL_INT(2, count(LB_CH_TRACKS));
}

static void test_flush_publishes_open_groups(void)
{
    feed_cycle(2, 9);
    feed_status(2, 9, 3, 3, 13); /* claims a third track that never comes */
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_TRACKS));
    lb_flush(g_st);
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_TRACKS));
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_SPIKES));
}

static void test_cycle_record_feeds_spike_times(void)
{
    struct md_can_tlm_cycle_t c = {.electrode = 0,
                                   .phase = 1,
                                   .cycle = 4,
                                   .interval_id = 4,
                                   .sample_rate_hz = 30000,
                                   .num_samples = 300000,
                                   .start_time_us = 48000000u};
    FEED(tlm_cycle, TLM_CYCLE, &c);
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_CYCLE));
    feed_status(0, 4, 0, 0, 3);
    feed_spikes(0, 4, 0, 3, 10);
    const int i = find(LB_CH_SPIKES, 0);
    TEST_ASSERT_TRUE(i >= 0);
    mdlcm_spikes_t sp;
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_spikes_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &sp));
    TEST_ASSERT_EQUAL_INT(3, sp.num_spikes);
    TEST_ASSERT_EQUAL_INT64(48000000, sp.interval_start_us);
    TEST_ASSERT_EQUAL_INT64(30000, sp.sample_rate_hz);
    mdlcm_spikes_t_decode_cleanup(&sp);
}

static void feed_calib(uint8_t e, uint8_t index, uint8_t n, float v)
{
    struct md_can_hall_calib_t c = {.electrode = e, .coeff_index = index, .coeff_count = n, .coeff_value = v};
    FEED(hall_calib, HALL_CALIB, &c);
}

static void feed_hall(uint8_t e, uint8_t seq, uint16_t code, uint32_t time_ms)
{
    struct md_can_hall_reading_t r = {.electrode = e, .seq = seq, .raw_code = code, .sample_time_ms = time_ms};
    FEED(hall_reading, HALL_READING, &r);
}

/// Decodes the k-th MD_HALL message into *h (clean up with mdlcm_hall_t_decode_cleanup).
static void decode_hall(int k, mdlcm_hall_t *h)
{
    const int i = find(LB_CH_HALL, k);
    TEST_ASSERT_TRUE(i >= 0);
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_hall_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], h));
    TEST_ASSERT_EQUAL_INT64(g_cap.utime[i], h->utime);
}

static void test_hall_calibration_and_reading(void)
{
    feed_hall(1, 9, 40000, 1234); /* before any calibration */
    feed_calib(1, 0, 3, 1000.0f);
    feed_calib(1, 1, 3, 400.0f);
    feed_calib(1, 2, 3, -8.0f);
    feed_calib(1, MD_HALL_CALIB_INDEX_CODE_MID, 3, 32768.0f);
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_HALL_CALIB));
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_HALL)); /* same clock: the reading waits for more */
    feed_calib(1, MD_HALL_CALIB_INDEX_CODE_HALF, 3, 16384.0f);
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_HALL_CALIB));
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_HALL)); /* the uncalibrated reading went out before the calibration */
    TEST_ASSERT_TRUE(find(LB_CH_HALL, 0) < find(LB_CH_HALL_CALIB, 0));
    feed_calib(1, 1, 3, 400.0f); /* the periodic repeat: unchanged, not published again */
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_HALL_CALIB));
    feed_hall(1, 10, 40000, 1244);
    feed_hall(1, 11, 40100, 1254);
    lb_flush(g_st);
    TEST_ASSERT_EQUAL_INT(2, count(LB_CH_HALL));

    mdlcm_hall_t h;
    decode_hall(0, &h);
    TEST_ASSERT_FALSE(h.calibrated);
    TEST_ASSERT_EQUAL_INT(1, h.num_readings);
    TEST_ASSERT_EQUAL_INT(9, h.seq[0]);
    TEST_ASSERT_EQUAL_INT(40000, h.raw_code[0]);
    TEST_ASSERT_EQUAL_INT64(1234, h.sample_time_ms[0]);
    TEST_ASSERT_EQUAL_DOUBLE(0.0, h.depth_um[0]);
    mdlcm_hall_t_decode_cleanup(&h);
    decode_hall(1, &h);
    TEST_ASSERT_TRUE(h.calibrated);
    TEST_ASSERT_EQUAL_INT(1, h.electrode);
    TEST_ASSERT_EQUAL_INT(2, h.num_readings);
    TEST_ASSERT_EQUAL_INT(10, h.seq[0]);
    TEST_ASSERT_EQUAL_INT(11, h.seq[1]);
    TEST_ASSERT_EQUAL_INT(40100, h.raw_code[1]);
    TEST_ASSERT_EQUAL_INT64(1254, h.sample_time_ms[1]);
    for (int k = 0; k < 2; ++k) {
        const double x = ((double)h.raw_code[k] - 32768.0) / 16384.0;
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1000.0 + 400.0 * x - 8.0 * x * x, h.depth_um[k]);
    }
    mdlcm_hall_t_decode_cleanup(&h);

    mdlcm_hall_calib_t c;
    const int i = find(LB_CH_HALL_CALIB, 0);
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_hall_calib_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &c));
    TEST_ASSERT_EQUAL_INT(3, c.num_coeffs);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, -8.0, c.coeff_um[2]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 16384.0, c.code_half);
    mdlcm_hall_calib_t_decode_cleanup(&c);
}

/* One hall_t per electrode and clock value: the readings of each electrode in
 * order, published when SIM_CLOCK moves (before anything stamped later), when
 * MAX_READINGS are held, and at lb_flush; every reading is in exactly one. */
static void test_hall_batches(void)
{
    feed_clock(1000u);
    for (uint32_t k = 0u; k < 3u; ++k) {
        feed_hall(0, (uint8_t)(254u + k), (uint16_t)(100u + k), 1u + k); /* seq wraps 254, 255, 0 */
        feed_hall(2, (uint8_t)k, (uint16_t)(200u + k), 1u + k);
    }
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_HALL));
    feed_clock(1000u); /* the same time again: nothing due */
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_HALL));
    feed_clock(2000u);
    TEST_ASSERT_EQUAL_INT(2, count(LB_CH_HALL));
    mdlcm_hall_t h;
    decode_hall(0, &h);
    TEST_ASSERT_EQUAL_INT64(1000, h.utime);
    TEST_ASSERT_EQUAL_INT(0, h.electrode);
    TEST_ASSERT_EQUAL_INT(3, h.num_readings);
    TEST_ASSERT_EQUAL_INT(254, h.seq[0]);
    TEST_ASSERT_EQUAL_INT(255, h.seq[1]);
    TEST_ASSERT_EQUAL_INT(0, h.seq[2]);
    TEST_ASSERT_EQUAL_INT(102, h.raw_code[2]);
    TEST_ASSERT_EQUAL_INT64(3, h.sample_time_ms[2]);
    mdlcm_hall_t_decode_cleanup(&h);
    decode_hall(1, &h);
    TEST_ASSERT_EQUAL_INT(2, h.electrode);
    TEST_ASSERT_EQUAL_INT(3, h.num_readings);
    TEST_ASSERT_EQUAL_INT(200, h.raw_code[0]);
    mdlcm_hall_t_decode_cleanup(&h);

    const int full = MDLCM_HALL_T_MAX_READINGS;
    for (int k = 0; k < full + 5; ++k) {
        feed_hall(0, (uint8_t)k, (uint16_t)k, (uint32_t)k);
    }
    TEST_ASSERT_EQUAL_INT(3, count(LB_CH_HALL)); /* the full one, at once */
    decode_hall(2, &h);
    TEST_ASSERT_EQUAL_INT(full, h.num_readings);
    TEST_ASSERT_EQUAL_INT64(2000, h.utime);
    TEST_ASSERT_EQUAL_INT(full - 1, h.raw_code[full - 1]);
    mdlcm_hall_t_decode_cleanup(&h);
    feed_hall(LB_MAX_ELECTRODES, 0, 0, 0); /* beyond the bridge's electrodes: counted, not kept */
    TEST_ASSERT_EQUAL_UINT64(1, lb_stats(g_st)->dropped);
    lb_flush(g_st);
    TEST_ASSERT_EQUAL_INT(4, count(LB_CH_HALL));
    decode_hall(3, &h);
    TEST_ASSERT_EQUAL_INT(5, h.num_readings);
    TEST_ASSERT_EQUAL_INT(full + 4, h.raw_code[4]);
    mdlcm_hall_t_decode_cleanup(&h);
    lb_flush(g_st);
    TEST_ASSERT_EQUAL_INT(4, count(LB_CH_HALL));
}

/* Frame time: a batch ends at the first frame of a later time, of any kind. */
static void test_hall_batches_frame_time(void)
{
    TEST_ASSERT_EQUAL_INT(0, lb_init(g_st, LB_TIME_FRAME, capture, &g_cap));
    struct md_can_hall_reading_t r = {.electrode = 0, .seq = 1, .raw_code = 5, .sample_time_ms = 7};
    uint8_t buf[8] = {0};
    TEST_ASSERT_EQUAL_INT(MD_CAN_HALL_READING_LENGTH, md_can_hall_reading_pack(buf, &r, sizeof buf));
    md_frame_t f = frame_of(MD_CAN_HALL_READING_FRAME_ID, buf, MD_CAN_HALL_READING_LENGTH);
    lb_feed_frame(g_st, &f, 500);
    lb_feed_frame(g_st, &f, 500);
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_HALL));
    uint8_t hb[8] = {5, 1, 0, 3, 0, 0, 0, 0};
    md_frame_t beat = frame_of(MD_CAN_HEARTBEAT_CTRL_FRAME_ID, hb, sizeof hb);
    lb_feed_frame(g_st, &beat, 510);
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_HALL));
    mdlcm_hall_t h;
    decode_hall(0, &h);
    TEST_ASSERT_EQUAL_INT64(500, h.utime);
    TEST_ASSERT_EQUAL_INT(2, h.num_readings);
    mdlcm_hall_t_decode_cleanup(&h);
    lb_feed_frame(g_st, &f, 520);
    lb_flush(g_st);
    TEST_ASSERT_EQUAL_INT(2, count(LB_CH_HALL));
}

static void test_actuator_status(void)
{
    feed_clock(777u);
    struct md_can_act_status_t a = {.electrode = 2,
                                    .state = MD_ACT_STALLED,
                                    .cmd_seq = 200,
                                    .end_stops = 2,
                                    .steps_done = 40000,
                                    .steps_remaining = 65535};
    FEED(act_status, ACT_STATUS, &a);
    const int i = find(LB_CH_ACTUATOR, 0);
    mdlcm_actuator_t m;
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_actuator_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &m));
    TEST_ASSERT_EQUAL_INT64(777, m.utime);
    TEST_ASSERT_EQUAL_INT(MDLCM_ACTUATOR_T_STATE_STALLED, m.state);
    TEST_ASSERT_EQUAL_INT(200, m.cmd_seq);
    TEST_ASSERT_EQUAL_INT(2, m.end_stops);
    TEST_ASSERT_EQUAL_INT(40000, m.steps_done);
    TEST_ASSERT_EQUAL_INT(65535, m.steps_remaining);
}

static void test_malformed_and_out_of_range_counted(void)
{
    uint8_t short_status[8] = {0};
    md_frame_t f = frame_of(MD_CAN_TLM_STATUS_FRAME_ID, short_status, sizeof short_status);
    lb_feed_frame(g_st, &f, 0);
    TEST_ASSERT_EQUAL_UINT64(1, lb_stats(g_st)->malformed);
    feed_track(LB_MAX_ELECTRODES, 0, 1, 1, 0.0f, 0);
    feed_track(0, LB_MAX_TRACKS, 1, 1, 0.0f, 0);
    feed_wave(0, 1, LB_MAX_WAVE_PARTS, 0);
    TEST_ASSERT_EQUAL_UINT64(3, lb_stats(g_st)->dropped);
    uint8_t hb[8] = {5, 1, 0, 3, 0, 0, 0, 0};
    f = frame_of(MD_CAN_HEARTBEAT_CTRL_FRAME_ID, hb, sizeof hb);
    lb_feed_frame(g_st, &f, 0);
    TEST_ASSERT_EQUAL_UINT64(1, lb_stats(g_st)->ignored);
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_STATUS));
}

/* Integer fields that do not fit their LCM type (int8 electrode from 0, int32
 * neuron, int64 sample, a finite t_s) refuse the record instead of being
 * converted out of range; nothing is published from it. */
static void test_truth_lines_out_of_range_refused(void)
{
    static const char *const bad[] = {
        "{\"type\":\"spike\",\"electrode\":9223372036854775807,\"sample\":1,\"neuron\":0}",
        "{\"type\":\"spike\",\"electrode\":128,\"sample\":1,\"neuron\":0}",
        "{\"type\":\"spike\",\"electrode\":-1,\"sample\":1,\"neuron\":0}",
        "{\"type\":\"spike\",\"electrode\":0.5,\"sample\":1,\"neuron\":0}",
        "{\"type\":\"spike\",\"electrode\":0,\"sample\":1e19,\"neuron\":0}",
        "{\"type\":\"spike\",\"electrode\":0,\"sample\":-1,\"neuron\":0}",
        "{\"type\":\"spike\",\"electrode\":0,\"sample\":1,\"neuron\":3000000000}",
        "{\"type\":\"neuron\",\"electrode\":1e300,\"neuron\":0}",
        "{\"type\":\"death\",\"t_s\":1e999,\"electrode\":0,\"neuron\":0}",
        "{\"type\":\"state\",\"t_s\":1,\"electrode\":0,\"tip_um\":1,\"neurons\":[{\"neuron\":-3e9}]}",
        "{\"type\":\"session\",\"seed\":1e20,\"sample_rate_hz\":30000,\"bg_rms_uv\":[]}",
        "{\"type\":\"session\",\"seed\":1,\"sample_rate_hz\":-5,\"bg_rms_uv\":[]}",
    };
    for (size_t k = 0u; k < sizeof bad / sizeof bad[0]; ++k) {
        TEST_ASSERT_EQUAL_INT_MESSAGE(-1, lb_feed_truth_line(g_st, bad[k]), bad[k]);
    }
    lb_flush(g_st);
    TEST_ASSERT_EQUAL_UINT64(sizeof bad / sizeof bad[0], lb_stats(g_st)->truth_errors);
    TEST_ASSERT_EQUAL_UINT64(0, lb_stats(g_st)->truth_records);
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_TRUTH_SPIKES) + count(LB_CH_TRUTH_DEATH) + count(LB_CH_TRUTH_STATE) +
                                 count(LB_CH_TRUTH_SESSION));
    /* a uint64 seed near 2^64 - 1 arrives as 2^64 through a double: kept as its int64 bits */
    TEST_ASSERT_EQUAL_INT(0, lb_feed_truth_line(g_st, "{\"type\":\"session\",\"seed\":18446744073709551615,"
                                                      "\"sample_rate_hz\":30000,\"bg_rms_uv\":[1]}"));
    TEST_ASSERT_EQUAL_INT64(INT64_MAX, lb_truth_time_us(g_st, "{\"type\":\"death\",\"t_s\":1e300}"));
}

static void test_truth_lines(void)
{
    TEST_ASSERT_EQUAL_INT(0, lb_feed_truth_line(g_st, "{\"type\":\"session\",\"seed\":3,\"sample_rate_hz\":30000.0,"
                                                      "\"electrodes\":2,\"bg_rms_uv\":[7.0,7.5]}"));
    TEST_ASSERT_EQUAL_INT(0, lb_feed_truth_line(g_st, "{\"type\":\"neuron\",\"electrode\":1,\"neuron\":4,\"x_um\":1,"
                                                      "\"y_um\":2,\"depth_um\":1200,\"amp_uv\":300,\"rate_hz\":5,"
                                                      "\"shape\":\"triphasic\"}"));
    TEST_ASSERT_EQUAL_INT(0, count(LB_CH_TRUTH_SESSION));
    const char *spike = "{\"type\":\"spike\",\"electrode\":1,\"sample\":60000,\"neuron\":4,\"amp_uv\":99.5}";
    TEST_ASSERT_EQUAL_INT64(2000000, lb_truth_time_us(g_st, spike));
    TEST_ASSERT_EQUAL_INT(0, lb_feed_truth_line(g_st, spike));
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_TRUTH_SESSION)); /* the first other record ends the header */
    TEST_ASSERT_EQUAL_INT(0, lb_feed_truth_line(g_st, "{\"type\":\"spike\",\"electrode\":0,\"sample\":60001,"
                                                      "\"neuron\":-1,\"amp_uv\":800}"));
    TEST_ASSERT_EQUAL_INT(1, count(LB_CH_TRUTH_SPIKES)); /* another electrode ends the batch */
    TEST_ASSERT_EQUAL_INT(0, lb_feed_truth_line(g_st, "  \n"));
    TEST_ASSERT_EQUAL_INT(-1, lb_feed_truth_line(g_st, "{\"type\":\"state\""));
    TEST_ASSERT_EQUAL_INT(-1, lb_feed_truth_line(g_st, "{\"no_type\":1}"));
    TEST_ASSERT_EQUAL_INT(0, lb_feed_truth_line(g_st, "{\"type\":\"interval\",\"electrode\":0}"));
    TEST_ASSERT_EQUAL_UINT64(2, lb_stats(g_st)->truth_errors);
    TEST_ASSERT_EQUAL_UINT64(1, lb_stats(g_st)->truth_ignored);
    const char *state = "{\"type\":\"state\",\"t_s\":20.5,\"label\":\"interval 2\",\"electrode\":1,\"tip_um\":1019.96,"
                        "\"neurons\":[{\"neuron\":4,\"depth_um\":1205.78,\"alive\":false,\"distance_um\":187.49,"
                        "\"snr\":1.92,\"snr_peak_depth_um\":1205.5,\"snr_peak\":37.72}]}";
    TEST_ASSERT_EQUAL_INT(0, lb_feed_truth_line(g_st, state));
    TEST_ASSERT_EQUAL_INT(2, count(LB_CH_TRUTH_SPIKES));

    mdlcm_truth_session_t s;
    int i = find(LB_CH_TRUTH_SESSION, 0);
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_truth_session_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &s));
    TEST_ASSERT_EQUAL_INT64(3, s.seed);
    TEST_ASSERT_EQUAL_INT(2, s.num_electrodes);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 7.5f, s.bg_rms_uv[1]);
    TEST_ASSERT_EQUAL_INT(1, s.num_neurons);
    TEST_ASSERT_EQUAL_INT(4, s.neuron[0]);
    TEST_ASSERT_EQUAL_STRING("triphasic", s.shape[0]);
    mdlcm_truth_session_t_decode_cleanup(&s);

    mdlcm_truth_spikes_t b;
    i = find(LB_CH_TRUTH_SPIKES, 0);
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_truth_spikes_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &b));
    TEST_ASSERT_EQUAL_INT(1, b.num_spikes);
    TEST_ASSERT_EQUAL_INT64(60000, b.sample[0]);
    TEST_ASSERT_EQUAL_INT64(2000000, b.utime);
    mdlcm_truth_spikes_t_decode_cleanup(&b);

    mdlcm_truth_state_t st;
    i = find(LB_CH_TRUTH_STATE, 0);
    TEST_ASSERT_EQUAL_INT((int)g_cap.len[i], mdlcm_truth_state_t_decode(g_cap.data[i], 0, (int)g_cap.len[i], &st));
    TEST_ASSERT_EQUAL_INT64(20500000, st.utime);
    TEST_ASSERT_EQUAL_STRING("interval 2", st.label);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1019.96, st.tip_um);
    TEST_ASSERT_EQUAL_INT(1, st.num_neurons);
    TEST_ASSERT_FALSE(st.alive[0]);
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 1205.5f, st.snr_peak_depth_um[0]);
    mdlcm_truth_state_t_decode_cleanup(&st);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_complete_cycle_published_at_status);
    RUN_TEST(test_controller_order_status_first);
    RUN_TEST(test_new_cycle_flushes_incomplete_group_and_late_frames_counted);
    RUN_TEST(test_flush_publishes_open_groups);
    RUN_TEST(test_cycle_record_feeds_spike_times);
    RUN_TEST(test_hall_calibration_and_reading);
    RUN_TEST(test_hall_batches);
    RUN_TEST(test_hall_batches_frame_time);
    RUN_TEST(test_actuator_status);
    RUN_TEST(test_malformed_and_out_of_range_counted);
    RUN_TEST(test_truth_lines);
    RUN_TEST(test_truth_lines_out_of_range_refused);
    return UNITY_END();
}
