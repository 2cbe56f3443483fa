/* Host unit: SIM_ADVANCE (lockstep settling) in the simulator's plant, and the
 * ground truth's `interval` record that aligns a recording's samples with the
 * electrode's sample clock (docs/sim-process.md, docs/session.md). Default
 * world (3 electrodes, 30 kHz, no neurons), frames captured from the sink. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "md_can.h"
#include "md_protocol.h"
#include "simnode_plant.h"
#include "simnode_world.h"
#include "unity.h"

#define CAP_MAX 16384u

static md_frame_t cap[CAP_MAX];
static size_t n_cap;
static simnode_world_t *world;
static simnode_plant_t plant;
static FILE *truth;

static int capture(void *ctx, const md_frame_t *f)
{
    (void)ctx;
    if (n_cap >= CAP_MAX) {
        return -1;
    }
    cap[n_cap++] = *f;
    return 0;
}

static void make_plant(bool lockstep, uint64_t seed)
{
    char err[256];
    simnode_world_destroy(world);
    world = simnode_world_create(NULL, seed, err, sizeof err);
    TEST_ASSERT_MESSAGE(world != NULL, err);
    if (truth != NULL) {
        (void)fclose(truth);
    }
    truth = tmpfile();
    TEST_ASSERT_NOT_NULL(truth);
    simnode_world_set_truth(world, truth);
    simnode_plant_cfg_t cfg;
    simnode_plant_cfg_default(&cfg);
    cfg.lockstep = lockstep;
    const simnode_sink_t sink = {capture, NULL};
    TEST_ASSERT_EQUAL_INT(MD_OK, simnode_plant_init(&plant, &cfg, world, sink));
    simnode_plant_start(&plant);
    n_cap = 0u;
}

void setUp(void)
{
    make_plant(true, 11u);
}

void tearDown(void)
{
    simnode_world_destroy(world);
    world = NULL;
    if (truth != NULL) {
        (void)fclose(truth);
        truth = NULL;
    }
}

static void put(uint32_t id, const uint8_t *data, uint8_t len, uint8_t flags)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    f.flags = flags;
    memcpy(f.data, data, len);
    simnode_plant_handle(&plant, &f);
}

static void send_step(uint32_t duration_us, uint8_t token)
{
    const struct md_can_sim_advance_t m = {duration_us, token};
    uint8_t d[8];
    TEST_ASSERT_EQUAL_INT(8, md_can_sim_advance_pack(d, &m, sizeof d));
    put(MD_CAN_SIM_ADVANCE_FRAME_ID, d, 8u, 0u);
}

static void send_rec(uint8_t e, uint16_t interval, uint32_t n)
{
    const struct md_can_rec_req_t r = {e, interval, n};
    uint8_t d[8];
    TEST_ASSERT_EQUAL_INT(8, md_can_rec_req_pack(d, &r, sizeof d));
    put(MD_CAN_REC_REQ_FRAME_ID, d, 8u, 0u);
}

static uint64_t clock_of(const md_frame_t *f)
{
    struct md_can_sim_clock_t c;
    TEST_ASSERT_EQUAL_UINT32(MD_CAN_SIM_CLOCK_FRAME_ID, f->id);
    TEST_ASSERT_EQUAL_INT(0, md_can_sim_clock_unpack(&c, f->data, f->len));
    return c.sim_time_us;
}

static size_t count_id(uint32_t id)
{
    size_t n = 0u;
    for (size_t i = 0; i < n_cap; i++) {
        n += (cap[i].id == id) ? 1u : 0u;
    }
    return n;
}

/* start_sample of the k-th `interval` record (0-based) in the truth file. */
static uint64_t truth_interval_start(unsigned k, uint64_t *t_us)
{
    char line[4096];
    unsigned seen = 0u;
    TEST_ASSERT_EQUAL_INT(0, fflush(truth));
    rewind(truth);
    while (fgets(line, sizeof line, truth) != NULL) {
        const char *p = strstr(line, "\"type\":\"interval\"");
        if (p == NULL || seen++ != k) {
            continue;
        }
        const char *s = strstr(line, "\"start_sample\":");
        const char *t = strstr(line, "\"t_us\":");
        TEST_ASSERT_NOT_NULL(s);
        TEST_ASSERT_NOT_NULL(t);
        *t_us = strtoull(t + 7, NULL, 10);
        (void)fseek(truth, 0, SEEK_END);
        return strtoull(s + 15, NULL, 10);
    }
    (void)fseek(truth, 0, SEEK_END);
    TEST_FAIL_MESSAGE("interval record missing");
    return 0u;
}

/* ---- tests ------------------------------------------------------------ */

static void test_step_moves_time_and_is_answered_with_clocks(void)
{
    send_step(2500000u, 7u); /* 2.5 s */
    TEST_ASSERT_TRUE(n_cap >= 2u);
    TEST_ASSERT_EQUAL_UINT64(0u, clock_of(&cap[0]));
    TEST_ASSERT_EQUAL_UINT64(2500000u, clock_of(&cap[n_cap - 1u]));
    TEST_ASSERT_EQUAL_UINT64(2500000u, plant.now_us);
    TEST_ASSERT_EQUAL_UINT64(2500000u, simnode_world_time_us(world));
    TEST_ASSERT_EQUAL_UINT64(1u, plant.stats.steps);
    /* only two clocks, no recording, no acknowledgement of its own */
    TEST_ASSERT_EQUAL_size_t(2u, count_id(MD_CAN_SIM_CLOCK_FRAME_ID));
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_REC_DATA_FRAME_ID));
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_REC_END_FRAME_ID));
    /* the periodic frames of (0, 2.5 s] go out in time order: 250 readings of
     * each electrode at 100 Hz, time stamps 10..2500 ms */
    TEST_ASSERT_EQUAL_size_t(3u * 250u, count_id(MD_CAN_HALL_READING_FRAME_ID));
    uint32_t last_ms = 0u;
    for (size_t i = 1; i + 1u < n_cap; i++) {
        TEST_ASSERT_TRUE(cap[i].id != MD_CAN_SIM_CLOCK_FRAME_ID);
        if (cap[i].id == MD_CAN_HALL_READING_FRAME_ID) {
            struct md_can_hall_reading_t r;
            TEST_ASSERT_EQUAL_INT(0, md_can_hall_reading_unpack(&r, cap[i].data, cap[i].len));
            TEST_ASSERT_TRUE(r.sample_time_ms >= last_ms && r.sample_time_ms > 0u && r.sample_time_ms <= 2500u);
            last_ms = r.sample_time_ms;
        }
    }
    TEST_ASSERT_EQUAL_UINT32(2500u, last_ms);
    /* idle ACT_STATUS every second of simulated time: at 1 s and 2 s */
    TEST_ASSERT_EQUAL_size_t(2u * 3u, count_id(MD_CAN_ACT_STATUS_FRAME_ID));
}

static void test_zero_step_is_answered_with_the_current_clock(void)
{
    send_step(1000u, 1u);
    n_cap = 0u;
    send_step(0u, 2u);
    TEST_ASSERT_EQUAL_size_t(1u, n_cap);
    TEST_ASSERT_EQUAL_UINT64(1000u, clock_of(&cap[0]));
    TEST_ASSERT_EQUAL_UINT64(1000u, plant.now_us);
}

static void test_recording_after_a_step_starts_at_its_end(void)
{
    send_step(1000000u, 3u);
    n_cap = 0u;
    send_rec(1u, 9u, 300u);
    TEST_ASSERT_EQUAL_UINT64(1000000u, clock_of(&cap[0]));
    TEST_ASSERT_EQUAL_UINT64(1010000u, clock_of(&cap[n_cap - 1u]));
    uint64_t t_us = 0u;
    TEST_ASSERT_EQUAL_UINT64(30000u, truth_interval_start(0u, &t_us)); /* 1 s at 30 kHz */
    TEST_ASSERT_EQUAL_UINT64(1000000u, t_us);
}

static void test_malformed_refused_and_realtime_steps_get_no_answer(void)
{
    const uint8_t d[8] = {0x10, 0x27, 0, 0, 5, 0, 0, 0};
    put(MD_CAN_SIM_ADVANCE_FRAME_ID, d, 7u, 0u);               /* wrong length */
    put(MD_CAN_SIM_ADVANCE_FRAME_ID, d, 8u, MD_FRAME_FLAG_FD); /* FD flag */
    TEST_ASSERT_EQUAL_size_t(2u, plant.fe.node.stats.rx_malformed);
    TEST_ASSERT_EQUAL_UINT64(2u, plant.stats.rx_malformed);
    TEST_ASSERT_EQUAL_size_t(2u, count_id(MD_CAN_EMCY_FE_FRAME_ID)); /* 1st and 2nd */
    /* each EMCY is a batch of its own, opened by the (unmoved) clock */
    TEST_ASSERT_EQUAL_size_t(4u, n_cap);
    TEST_ASSERT_EQUAL_size_t(2u, count_id(MD_CAN_SIM_CLOCK_FRAME_ID));
    TEST_ASSERT_EQUAL_UINT64(0u, plant.stats.steps);
    TEST_ASSERT_EQUAL_UINT64(0u, plant.now_us);
    /* front-end stopped by NMT: refused without an answer */
    const uint8_t stop[2] = {MD_NMT_STOP, MD_NODE_FE};
    put(MD_CAN_NMT_FRAME_ID, stop, 2u, 0u);
    n_cap = 0u;
    send_step(5000u, 4u);
    TEST_ASSERT_EQUAL_size_t(0u, n_cap);
    TEST_ASSERT_EQUAL_UINT64(1u, plant.fe.node.stats.rx_refused);
    TEST_ASSERT_EQUAL_UINT64(0u, plant.now_us);
    /* realtime: the wall clock moves time, SIM_ADVANCE is ignored */
    make_plant(false, 11u);
    send_step(5000u, 5u);
    TEST_ASSERT_EQUAL_size_t(0u, n_cap);
    TEST_ASSERT_EQUAL_UINT64(0u, plant.stats.steps);
    TEST_ASSERT_EQUAL_UINT64(1u, plant.stats.rx_ignored);
}

/* Time passed in one step or in several gives the same plant: the same
 * readings of the sensor and the same samples afterwards. */
static void test_one_long_step_equals_several_short_ones(void)
{
    static md_frame_t a[CAP_MAX];
    send_step(3000000u, 1u);
    send_rec(0u, 1u, 3000u);
    const size_t na = n_cap;
    memcpy(a, cap, na * sizeof cap[0]);
    make_plant(true, 11u);
    send_step(1000000u, 1u);
    send_step(500000u, 2u);
    send_step(1500000u, 3u);
    send_rec(0u, 1u, 3000u);
    /* drop the SIM_CLOCK frames, which differ by construction */
    size_t ia = 0u, ib = 0u, compared = 0u;
    for (; ia < na && ib < n_cap; ia++, ib++) {
        while (ia < na && a[ia].id == MD_CAN_SIM_CLOCK_FRAME_ID) {
            ia++;
        }
        while (ib < n_cap && cap[ib].id == MD_CAN_SIM_CLOCK_FRAME_ID) {
            ib++;
        }
        if (ia == na || ib == n_cap) {
            break;
        }
        TEST_ASSERT_EQUAL_UINT32(a[ia].id, cap[ib].id);
        TEST_ASSERT_EQUAL_MEMORY(a[ia].data, cap[ib].data, a[ia].len);
        compared++;
    }
    TEST_ASSERT_EQUAL_size_t(na, ia);
    TEST_ASSERT_EQUAL_size_t(n_cap, ib);
    TEST_ASSERT_TRUE(compared > 100u + 900u); /* 100 REC_DATA + 3 x 300 readings */
}

/* Back-to-back recordings on an electrode whose clock is off the sample grid:
 * its sample clock lags floor(t * fs) by one sample, so only the recorded
 * start_sample aligns detections with the truth's spikes. */
static void test_interval_record_gives_the_exact_start_sample(void)
{
    send_step(33u, 1u);   /* 0.99 samples at 30 kHz */
    send_rec(2u, 1u, 1u); /* sample 0; ends at 33 + 34 us */
    send_rec(2u, 2u, 1u); /* starts at 67 us, ends at 101 us */
    uint64_t t0 = 0u, t1 = 0u;
    TEST_ASSERT_EQUAL_UINT64(0u, truth_interval_start(0u, &t0));
    TEST_ASSERT_EQUAL_UINT64(33u, t0);
    TEST_ASSERT_EQUAL_UINT64(1u, truth_interval_start(1u, &t1));
    TEST_ASSERT_EQUAL_UINT64(67u, t1);
    TEST_ASSERT_EQUAL_UINT64(2u, t1 * 30000u / 1000000u); /* what the time alone would say */
    /* once time passes unrecorded, the clock is back on the grid */
    send_step(1000u, 2u);
    send_rec(2u, 3u, 30u);
    uint64_t t2 = 0u;
    TEST_ASSERT_EQUAL_UINT64(1101u * 30000u / 1000000u, truth_interval_start(2u, &t2));
    TEST_ASSERT_EQUAL_UINT64(1101u, t2);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_step_moves_time_and_is_answered_with_clocks);
    RUN_TEST(test_zero_step_is_answered_with_the_current_clock);
    RUN_TEST(test_recording_after_a_step_starts_at_its_end);
    RUN_TEST(test_malformed_refused_and_realtime_steps_get_no_answer);
    RUN_TEST(test_one_long_step_equals_several_short_ones);
    RUN_TEST(test_interval_record_gives_the_exact_start_sample);
    return UNITY_END();
}
