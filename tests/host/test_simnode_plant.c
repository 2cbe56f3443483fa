/* Host unit: the simulator's plant nodes (actuator driver, position sensor,
 * front-end) driven frame by frame on the default world (3 electrodes, model
 * defaults), frames captured from the plant's sink. Lockstep unless a test
 * says realtime. */
#include <math.h>
#include <string.h>

#include "md_can.h"
#include "md_protocol.h"
#include "simnode_plant.h"
#include "simnode_world.h"
#include "unity.h"

#define CAP_MAX 65536u

static md_frame_t cap[CAP_MAX];
static size_t n_cap;
static size_t cap_overflow;
static simnode_world_t *world;
static simnode_plant_t plant;

static int capture(void *ctx, const md_frame_t *f)
{
    (void)ctx;
    if (n_cap >= CAP_MAX) {
        cap_overflow++;
        return -1;
    }
    cap[n_cap++] = *f;
    return 0;
}

static void make_plant(bool lockstep, bool autostart, uint64_t seed)
{
    char err[256];
    simnode_world_destroy(world);
    world = simnode_world_create(NULL, seed, err, sizeof err);
    TEST_ASSERT_MESSAGE(world != NULL, err);
    simnode_plant_cfg_t cfg;
    simnode_plant_cfg_default(&cfg);
    cfg.lockstep = lockstep;
    cfg.autostart = autostart;
    const simnode_sink_t sink = {capture, NULL};
    TEST_ASSERT_EQUAL_INT(MD_OK, simnode_plant_init(&plant, &cfg, world, sink));
    simnode_plant_start(&plant);
}

void setUp(void)
{
    n_cap = 0u;
    cap_overflow = 0u;
    make_plant(true, true, 7u);
    n_cap = 0u; /* the start-up batch is checked by its own test */
}

void tearDown(void)
{
    simnode_world_destroy(world);
    world = NULL;
}

/* ---- frame helpers ---------------------------------------------------- */

static void put(uint32_t id, const uint8_t *data, uint8_t len)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    memcpy(f.data, data, len);
    simnode_plant_handle(&plant, &f);
}

static void send_act(uint8_t e, uint8_t cmd, uint8_t dir, uint8_t seq, uint16_t count, uint16_t rate)
{
    const struct md_can_act_cmd_t c = {e, cmd, dir, seq, count, rate};
    uint8_t d[8];
    TEST_ASSERT_EQUAL_INT(8, md_can_act_cmd_pack(d, &c, sizeof d));
    put(MD_CAN_ACT_CMD_FRAME_ID, d, 8u);
}

static void send_rec(uint8_t e, uint16_t interval, uint32_t n)
{
    const struct md_can_rec_req_t r = {e, interval, n};
    uint8_t d[8];
    TEST_ASSERT_EQUAL_INT(8, md_can_rec_req_pack(d, &r, sizeof d));
    put(MD_CAN_REC_REQ_FRAME_ID, d, 8u);
}

static void send_nmt(uint8_t command, uint8_t target)
{
    const uint8_t d[2] = {command, target};
    put(MD_CAN_NMT_FRAME_ID, d, 2u);
}

static void send_estop(void)
{
    const uint8_t d[2] = {MD_NODE_OPER, 1u};
    put(MD_CAN_ESTOP_FRAME_ID, d, 2u);
}

static size_t count_id(uint32_t id)
{
    size_t n = 0u;
    for (size_t i = 0; i < n_cap; i++) {
        n += (cap[i].id == id) ? 1u : 0u;
    }
    return n;
}

/* Last frame with this id, or NULL. */
static const md_frame_t *last_id(uint32_t id)
{
    for (size_t i = n_cap; i > 0u; i--) {
        if (cap[i - 1u].id == id) {
            return &cap[i - 1u];
        }
    }
    return NULL;
}

static struct md_can_act_status_t act_status_of(const md_frame_t *f)
{
    struct md_can_act_status_t s;
    TEST_ASSERT_NOT_NULL(f);
    TEST_ASSERT_EQUAL_UINT8(MD_CAN_ACT_STATUS_LENGTH, f->len);
    TEST_ASSERT_EQUAL_INT(0, md_can_act_status_unpack(&s, f->data, f->len));
    return s;
}

static uint64_t clock_of(const md_frame_t *f)
{
    struct md_can_sim_clock_t c;
    TEST_ASSERT_NOT_NULL(f);
    TEST_ASSERT_EQUAL_INT(0, md_can_sim_clock_unpack(&c, f->data, f->len));
    return c.sim_time_us;
}

/* Depth (um) of electrode e from the captured calibration and its last reading. */
static double hall_depth_um(uint8_t e)
{
    double coef[16] = {0};
    double mid = 0.0, half = 0.0;
    uint32_t count = 0u;
    uint16_t code = 0u;
    bool have_code = false;
    for (size_t i = 0; i < n_cap; i++) {
        if (cap[i].id == MD_CAN_HALL_CALIB_FRAME_ID) {
            struct md_can_hall_calib_t c;
            TEST_ASSERT_EQUAL_INT(0, md_can_hall_calib_unpack(&c, cap[i].data, cap[i].len));
            if (c.electrode != e) {
                continue;
            }
            count = c.coeff_count;
            if (c.coeff_index == SIMNODE_HALL_CAL_INDEX_MID) {
                mid = (double)c.coeff_value;
            } else if (c.coeff_index == SIMNODE_HALL_CAL_INDEX_HALF) {
                half = (double)c.coeff_value;
            } else if (c.coeff_index < 16u) {
                coef[c.coeff_index] = (double)c.coeff_value;
            }
        } else if (cap[i].id == MD_CAN_HALL_READING_FRAME_ID) {
            struct md_can_hall_reading_t r;
            TEST_ASSERT_EQUAL_INT(0, md_can_hall_reading_unpack(&r, cap[i].data, cap[i].len));
            if (r.electrode == e) {
                code = r.raw_code;
                have_code = true;
            }
        }
    }
    TEST_ASSERT_TRUE(count > 0u && count <= 16u && have_code && half > 0.0);
    const double x = ((double)code - mid) / half;
    double depth = 0.0;
    for (uint32_t k = count; k > 0u; k--) {
        depth = depth * x + coef[k - 1u];
    }
    return depth;
}

/* ---- tests ------------------------------------------------------------ */

static void test_start_announces_every_node_in_one_batch(void)
{
    make_plant(true, true, 7u);
    TEST_ASSERT_TRUE(n_cap > 0u);
    TEST_ASSERT_EQUAL_HEX32(MD_CAN_SIM_CLOCK_FRAME_ID, cap[0].id);
    TEST_ASSERT_EQUAL_UINT64(0u, clock_of(&cap[0]));
    TEST_ASSERT_EQUAL_size_t(3u, count_id(MD_CAN_ACT_STATUS_FRAME_ID));
    TEST_ASSERT_EQUAL_size_t(3u, count_id(MD_CAN_HALL_READING_FRAME_ID));
    TEST_ASSERT_EQUAL_size_t(3u, count_id(MD_CAN_FE_INFO_FRAME_ID));
    TEST_ASSERT_EQUAL_size_t(3u * (10u + 2u), count_id(MD_CAN_HALL_CALIB_FRAME_ID)); /* degree 9 + mid, half */
    TEST_ASSERT_EQUAL_size_t(1u, count_id(MD_CAN_SIM_CLOCK_FRAME_ID));               /* time did not move */
    struct md_can_fe_info_t info;
    TEST_ASSERT_EQUAL_INT(0, md_can_fe_info_unpack(&info, last_id(MD_CAN_FE_INFO_FRAME_ID)->data, 12u));
    TEST_ASSERT_EQUAL_UINT32(30000u, info.sample_rate_hz);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 0.195, info.gain_u_v_per_lsb);
    /* the default electrode starts at 1000 um: the calibration must say so */
    TEST_ASSERT_DOUBLE_WITHIN(2.0, 1000.0, hall_depth_um(1u));
    for (uint32_t i = 0; i < 3u; i++) {
        static const md_node_id_t ids[3] = {MD_NODE_ACT, MD_NODE_HALL, MD_NODE_FE};
        TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_OPERATIONAL, simnode_plant_node(&plant, ids[i])->state);
    }
}

static void test_act_cmd_moves_and_reports_with_seq(void)
{
    /* 250 steps at 1 kHz on electrode 1: ~10 um deeper in 250 ms of simulated time */
    send_act(1u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 77u, 250u, 1000u);
    TEST_ASSERT_EQUAL_UINT(0u, cap_overflow);
    TEST_ASSERT_EQUAL_HEX32(MD_CAN_SIM_CLOCK_FRAME_ID, cap[0].id);
    TEST_ASSERT_EQUAL_UINT64(0u, clock_of(&cap[0]));
    const struct md_can_act_status_t first = act_status_of(&cap[1]); /* the acknowledgement */
    TEST_ASSERT_EQUAL_UINT8(1u, first.electrode);
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_MOVING, first.state);
    TEST_ASSERT_EQUAL_UINT8(77u, first.cmd_seq);
    TEST_ASSERT_EQUAL_UINT16(250u, first.steps_remaining);
    const struct md_can_act_status_t last = act_status_of(last_id(MD_CAN_ACT_STATUS_FRAME_ID));
    TEST_ASSERT_EQUAL_UINT8(1u, last.electrode);
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_IDLE, last.state);
    TEST_ASSERT_EQUAL_UINT8(77u, last.cmd_seq);
    TEST_ASSERT_EQUAL_UINT16(250u, last.steps_done);
    TEST_ASSERT_EQUAL_UINT16(0u, last.steps_remaining);
    /* the batch ends with the time at which the motion ended: step 249 at 249 ms */
    const uint64_t t_end = clock_of(&cap[n_cap - 1u]);
    TEST_ASSERT_EQUAL_HEX32(MD_CAN_SIM_CLOCK_FRAME_ID, cap[n_cap - 1u].id);
    TEST_ASSERT_TRUE(t_end >= 249000u && t_end < 249100u);
    /* periodic progress every 100 ms while moving, hall readings at 100 Hz */
    TEST_ASSERT_TRUE(count_id(MD_CAN_ACT_STATUS_FRAME_ID) >= 4u);
    TEST_ASSERT_EQUAL_size_t(3u * 24u, count_id(MD_CAN_HALL_READING_FRAME_ID));
    /* the sensor sees the motion: 250 steps of ~40 nm */
    n_cap = 0u;
    send_nmt(MD_NMT_START, MD_NODE_HALL); /* re-announce: calibration + a reading now */
    TEST_ASSERT_DOUBLE_WITHIN(3.0, 1010.0, hall_depth_um(1u));
    TEST_ASSERT_DOUBLE_WITHIN(2.0, 1000.0, hall_depth_um(0u));
}

static void test_halt_is_acknowledged_without_time(void)
{
    send_act(0u, MD_ACT_CMD_HALT, MD_ACT_DIR_ADVANCE, 9u, 0u, 0u);
    TEST_ASSERT_EQUAL_size_t(2u, n_cap); /* SIM_CLOCK + ACT_STATUS, no closing clock */
    const struct md_can_act_status_t s = act_status_of(&cap[1]);
    TEST_ASSERT_EQUAL_UINT8(9u, s.cmd_seq);
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_IDLE, s.state);
    TEST_ASSERT_EQUAL_UINT64(0u, plant.now_us);
}

static void check_stream(uint8_t e, uint16_t interval, uint32_t n)
{
    uint32_t total = 0u, frames = 0u;
    bool ended = false;
    for (size_t i = 0; i < n_cap; i++) {
        if (cap[i].id == MD_CAN_REC_DATA_FRAME_ID) {
            struct md_can_rec_data_t d;
            TEST_ASSERT_FALSE(ended);
            TEST_ASSERT_EQUAL_UINT8(64u, cap[i].len);
            TEST_ASSERT_TRUE((cap[i].flags & MD_FRAME_FLAG_FD) != 0u);
            TEST_ASSERT_EQUAL_INT(0, md_can_rec_data_unpack(&d, cap[i].data, cap[i].len));
            TEST_ASSERT_EQUAL_UINT8(e, d.electrode);
            TEST_ASSERT_EQUAL_UINT16(frames, d.seq); /* in order, from 0 */
            const uint32_t expect = (n - total < 30u) ? n - total : 30u;
            TEST_ASSERT_EQUAL_UINT8(expect, d.sample_count);
            total += d.sample_count;
            frames++;
        } else if (cap[i].id == MD_CAN_REC_END_FRAME_ID) {
            struct md_can_rec_end_t end;
            TEST_ASSERT_EQUAL_INT(0, md_can_rec_end_unpack(&end, cap[i].data, cap[i].len));
            TEST_ASSERT_EQUAL_UINT8(e, end.electrode);
            TEST_ASSERT_EQUAL_UINT8(MD_REC_COMPLETE, end.status);
            TEST_ASSERT_EQUAL_UINT16(interval, end.interval_id);
            TEST_ASSERT_EQUAL_UINT32(n, end.total_samples);
            ended = true;
        }
    }
    TEST_ASSERT_TRUE(ended);
    TEST_ASSERT_EQUAL_UINT32(n, total);
    TEST_ASSERT_EQUAL_UINT32((n + 29u) / 30u, frames);
}

static void test_rec_req_streams_exactly_n_samples_in_order(void)
{
    send_rec(2u, 42u, 1000u);
    TEST_ASSERT_EQUAL_UINT(0u, cap_overflow);
    check_stream(2u, 42u, 1000u);
    /* 1000 samples at 30 kHz: time moved by 33.334 ms, said by the closing clock */
    TEST_ASSERT_EQUAL_UINT64(33334u, plant.now_us);
    TEST_ASSERT_EQUAL_UINT64(33334u, clock_of(&cap[n_cap - 1u]));
    /* a second interval continues the clock; Seq starts again from 0 */
    n_cap = 0u;
    send_rec(0u, 43u, 61u);
    check_stream(0u, 43u, 61u);
    TEST_ASSERT_EQUAL_UINT64(33334u, clock_of(&cap[0]));
}

static void test_stream_samples_are_noise_not_zeros(void)
{
    send_rec(0u, 1u, 300u);
    double ss = 0.0;
    uint32_t n = 0u;
    for (size_t i = 0; i < n_cap; i++) {
        if (cap[i].id == MD_CAN_REC_DATA_FRAME_ID) {
            struct md_can_rec_data_t d;
            (void)md_can_rec_data_unpack(&d, cap[i].data, cap[i].len);
            const double x = (double)d.sample00 * 0.195;
            ss += x * x;
            n++;
        }
    }
    /* background ~6 uV thermal + MUA: RMS within 2..40 uV */
    const double rms = sqrt(ss / (double)n);
    TEST_ASSERT_TRUE(rms > 2.0 && rms < 40.0);
}

static void test_same_seed_same_frames_other_seed_other_frames(void)
{
    static md_frame_t first[4096];
    send_rec(1u, 5u, 2000u);
    send_act(1u, MD_ACT_CMD_STEP, MD_ACT_DIR_RETRACT, 3u, 100u, 500u);
    send_rec(1u, 6u, 2000u);
    const size_t n1 = n_cap;
    TEST_ASSERT_TRUE(n1 <= 4096u);
    memcpy(first, cap, n1 * sizeof cap[0]);
    make_plant(true, true, 7u);
    n_cap = 0u;
    send_rec(1u, 5u, 2000u);
    send_act(1u, MD_ACT_CMD_STEP, MD_ACT_DIR_RETRACT, 3u, 100u, 500u);
    send_rec(1u, 6u, 2000u);
    TEST_ASSERT_EQUAL_size_t(n1, n_cap);
    TEST_ASSERT_EQUAL_MEMORY(first, cap, n1 * sizeof cap[0]);
    make_plant(true, true, 8u);
    n_cap = 0u;
    send_rec(1u, 5u, 2000u);
    TEST_ASSERT_FALSE(memcmp(first, cap, 20u * sizeof cap[0]) == 0);
}

static void test_malformed_frames_are_counted_and_ignored(void)
{
    const uint8_t short_cmd[7] = {0, 1, 0, 1, 10, 0, 100};
    put(MD_CAN_ACT_CMD_FRAME_ID, short_cmd, 7u);                      /* length */
    send_act(3u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 1u, 10u, 100u); /* electrode 3 of 3 */
    send_act(0u, 2u, MD_ACT_DIR_ADVANCE, 1u, 10u, 100u);              /* command */
    send_act(0u, MD_ACT_CMD_STEP, 2u, 1u, 10u, 100u);                 /* direction */
    send_act(0u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 1u, 0u, 100u);  /* no steps */
    send_act(0u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 1u, 10u, 0u);   /* no rate */
    send_rec(0u, 1u, 0u);                                             /* no samples */
    send_rec(0u, 1u, SIMNODE_FE_MAX_SAMPLES + 1u);                    /* Seq would wrap */
    send_rec(5u, 1u, 100u);                                           /* electrode */
    send_nmt(77u, 0u);                                                /* NMT command */
    send_nmt(MD_NMT_STOP, 200u);                                      /* NMT target */
    const uint8_t bad_estop[1] = {5u};
    put(MD_CAN_ESTOP_FRAME_ID, bad_estop, 1u); /* length: not an e-stop */
    TEST_ASSERT_EQUAL_UINT64(12u, plant.stats.rx_malformed);
    TEST_ASSERT_EQUAL_UINT64(6u, plant.act.node.stats.rx_malformed);
    TEST_ASSERT_EQUAL_UINT64(3u, plant.fe.node.stats.rx_malformed);
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_ACT_STATUS_FRAME_ID));
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_REC_DATA_FRAME_ID));
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_REC_END_FRAME_ID));
    TEST_ASSERT_FALSE(plant.act.node.estop_latched);
    TEST_ASSERT_EQUAL_UINT64(0u, plant.now_us);
    /* EMCY PROTOCOL on the 1st, 2nd, 4th malformed frame of a node: 3 + 2 */
    TEST_ASSERT_EQUAL_size_t(3u, count_id(MD_CAN_EMCY_ACT_FRAME_ID));
    TEST_ASSERT_EQUAL_size_t(2u, count_id(MD_CAN_EMCY_FE_FRAME_ID));
    struct md_can_emcy_act_t em;
    TEST_ASSERT_EQUAL_INT(0, md_can_emcy_act_unpack(&em, last_id(MD_CAN_EMCY_ACT_FRAME_ID)->data, 8u));
    TEST_ASSERT_EQUAL_HEX16(MD_EMCY_PROTOCOL, em.error_code);
    TEST_ASSERT_EQUAL_UINT32(MD_CAN_ACT_CMD_FRAME_ID, em.info);
    /* frames that are not ours are ignored, not malformed */
    const uint8_t any[8] = {0};
    put(0x123u, any, 8u);
    put(MD_CAN_TLM_STATUS_FRAME_ID, any, 8u);
    TEST_ASSERT_EQUAL_UINT64(12u, plant.stats.rx_malformed);
    TEST_ASSERT_EQUAL_UINT64(2u, plant.stats.rx_ignored);
    /* and the nodes still work */
    n_cap = 0u;
    send_rec(0u, 2u, 30u);
    check_stream(0u, 2u, 30u);
}

static void test_estop_halts_latches_until_clear(void)
{
    send_estop();
    TEST_ASSERT_TRUE(plant.act.node.estop_latched);
    struct md_can_emcy_act_t em;
    TEST_ASSERT_EQUAL_INT(0, md_can_emcy_act_unpack(&em, last_id(MD_CAN_EMCY_ACT_FRAME_ID)->data, 8u));
    TEST_ASSERT_EQUAL_HEX16(MD_EMCY_ESTOP, em.error_code);
    TEST_ASSERT_EQUAL_UINT32(MD_NODE_OPER, em.info);
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_FAULT, act_status_of(last_id(MD_CAN_ACT_STATUS_FRAME_ID)).state);
    md_frame_t hb;
    simnode_heartbeat_frame(&plant.act.node, 1u, &hb);
    TEST_ASSERT_EQUAL_HEX32(0x702u, hb.id);
    TEST_ASSERT_EQUAL_HEX8(MD_HB_FLAG_ESTOP | MD_HB_FLAG_LOCKSTEP, hb.data[2]);
    /* a step is refused (acknowledged with State = fault), nothing moves */
    n_cap = 0u;
    send_act(0u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 12u, 100u, 1000u);
    TEST_ASSERT_EQUAL_size_t(1u, count_id(MD_CAN_ACT_STATUS_FRAME_ID));
    const struct md_can_act_status_t s = act_status_of(last_id(MD_CAN_ACT_STATUS_FRAME_ID));
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_FAULT, s.state);
    TEST_ASSERT_EQUAL_UINT8(12u, s.cmd_seq);
    TEST_ASSERT_EQUAL_UINT16(0u, s.steps_done);
    TEST_ASSERT_EQUAL_UINT64(0u, plant.now_us);
    TEST_ASSERT_EQUAL_UINT64(1u, plant.act.node.stats.rx_refused);
    /* NMT start/reset do not release it; a second e-stop sends no second EMCY */
    send_nmt(MD_NMT_RESET_NODE, 0u);
    send_estop();
    TEST_ASSERT_TRUE(plant.act.node.estop_latched);
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_EMCY_ACT_FRAME_ID));
    /* clear-e-stop (targeted) releases; the step then works */
    send_nmt(MD_NMT_CLEAR_ESTOP, MD_NODE_ACT);
    TEST_ASSERT_FALSE(plant.act.node.estop_latched);
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_IDLE, act_status_of(last_id(MD_CAN_ACT_STATUS_FRAME_ID)).state);
    send_act(0u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 13u, 100u, 1000u);
    const struct md_can_act_status_t done = act_status_of(last_id(MD_CAN_ACT_STATUS_FRAME_ID));
    TEST_ASSERT_EQUAL_UINT8(13u, done.cmd_seq);
    TEST_ASSERT_EQUAL_UINT16(100u, done.steps_done);
}

static void test_estop_interrupts_motion_in_realtime(void)
{
    make_plant(false, true, 7u);
    n_cap = 0u;
    send_act(2u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 1u, 1000u, 100u); /* 10 s */
    TEST_ASSERT_EQUAL_UINT64(0u, plant.now_us);                         /* realtime: nothing runs ahead */
    TEST_ASSERT_TRUE(simnode_plant_advance(&plant, 1000000u));
    const struct md_can_act_status_t mid = act_status_of(last_id(MD_CAN_ACT_STATUS_FRAME_ID));
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_MOVING, mid.state);
    TEST_ASSERT_TRUE(mid.steps_done >= 99u && mid.steps_done <= 101u);
    send_estop();
    TEST_ASSERT_TRUE(simnode_plant_advance(&plant, 3000000u));
    const struct md_can_act_status_t after = act_status_of(last_id(MD_CAN_ACT_STATUS_FRAME_ID));
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_FAULT, after.state);
    TEST_ASSERT_TRUE(after.steps_done <= 101u);
    TEST_ASSERT_EQUAL_UINT16(0u, after.steps_remaining);
    TEST_ASSERT_FALSE(simnode_act_busy(&plant.act));
    /* realtime sends SIM_CLOCK every 10 ms of simulated time */
    TEST_ASSERT_TRUE(count_id(MD_CAN_SIM_CLOCK_FRAME_ID) >= 300u);
    TEST_ASSERT_EQUAL_UINT64(3000000u, clock_of(last_id(MD_CAN_SIM_CLOCK_FRAME_ID)));
}

static void test_realtime_stream_follows_time(void)
{
    make_plant(false, true, 7u);
    n_cap = 0u;
    send_rec(0u, 9u, 3000u); /* 100 ms at 30 kHz */
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_REC_DATA_FRAME_ID));
    TEST_ASSERT_TRUE(simnode_plant_advance(&plant, 50000u)); /* half: frames 0..49 */
    TEST_ASSERT_EQUAL_size_t(50u, count_id(MD_CAN_REC_DATA_FRAME_ID));
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_REC_END_FRAME_ID));
    TEST_ASSERT_TRUE(simnode_plant_advance(&plant, 100000u));
    check_stream(0u, 9u, 3000u);
    /* a request while streaming is refused with Status = overflow */
    n_cap = 0u;
    send_rec(1u, 10u, 3000u);
    send_rec(1u, 11u, 30u);
    struct md_can_rec_end_t end;
    TEST_ASSERT_EQUAL_INT(0, md_can_rec_end_unpack(&end, last_id(MD_CAN_REC_END_FRAME_ID)->data, 8u));
    TEST_ASSERT_EQUAL_UINT16(11u, end.interval_id);
    TEST_ASSERT_EQUAL_UINT8(MD_REC_OVERFLOW, end.status);
    TEST_ASSERT_EQUAL_UINT32(0u, end.total_samples);
    /* a motion on that electrode aborts its stream */
    TEST_ASSERT_TRUE(simnode_plant_advance(&plant, 110000u));
    send_act(1u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 1u, 10u, 100u);
    TEST_ASSERT_EQUAL_INT(0, md_can_rec_end_unpack(&end, last_id(MD_CAN_REC_END_FRAME_ID)->data, 8u));
    TEST_ASSERT_EQUAL_UINT16(10u, end.interval_id);
    TEST_ASSERT_EQUAL_UINT8(MD_REC_ABORTED, end.status);
    TEST_ASSERT_EQUAL_UINT32(300u, end.total_samples); /* 10 ms of it went out */
    TEST_ASSERT_FALSE(simnode_fe_busy(&plant.fe));
}

static void test_retract_into_top_stop_stalls_with_emcy(void)
{
    /* 1000 um up at ~34 nm per retract step needs ~29400 steps: ask 40000 */
    send_act(0u, MD_ACT_CMD_STEP, MD_ACT_DIR_RETRACT, 4u, 40000u, 2000u);
    const struct md_can_act_status_t s = act_status_of(last_id(MD_CAN_ACT_STATUS_FRAME_ID));
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_STALLED, s.state);
    TEST_ASSERT_EQUAL_HEX8(0x01u, s.end_stops);
    TEST_ASSERT_TRUE(s.steps_done > 25000u && s.steps_done < 36000u);
    struct md_can_emcy_act_t em;
    TEST_ASSERT_EQUAL_INT(0, md_can_emcy_act_unpack(&em, last_id(MD_CAN_EMCY_ACT_FRAME_ID)->data, 8u));
    TEST_ASSERT_EQUAL_HEX16(MD_EMCY_MOTION, em.error_code);
    TEST_ASSERT_EQUAL_UINT8(0u, em.electrode);
    TEST_ASSERT_EQUAL_HEX32(0x01u, em.info & 0xFFu);
    TEST_ASSERT_EQUAL_UINT32(s.steps_done, em.info >> 8);
    TEST_ASSERT_TRUE(plant.act.node.fault);
    /* lockstep stopped at the stall, not at the planned 20 s */
    TEST_ASSERT_TRUE(plant.now_us < 18000000u);
    /* a new command clears the stall */
    send_act(0u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 5u, 10u, 1000u);
    TEST_ASSERT_EQUAL_UINT8(MD_ACT_IDLE, act_status_of(last_id(MD_CAN_ACT_STATUS_FRAME_ID)).state);
    TEST_ASSERT_FALSE(plant.act.node.fault);
}

static void test_nmt_targets_and_broadcast(void)
{
    send_nmt(MD_NMT_STOP, MD_NODE_FE);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_STOPPED, plant.fe.node.state);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_OPERATIONAL, plant.act.node.state);
    n_cap = 0u;
    send_rec(0u, 1u, 300u); /* stopped: ignored, counted */
    TEST_ASSERT_EQUAL_size_t(0u, n_cap);
    TEST_ASSERT_EQUAL_UINT64(1u, plant.fe.node.stats.rx_refused);
    send_nmt(MD_NMT_START, MD_NODE_FE); /* start re-announces FE_INFO */
    TEST_ASSERT_EQUAL_size_t(3u, count_id(MD_CAN_FE_INFO_FRAME_ID));
    n_cap = 0u;
    send_nmt(MD_NMT_RESET_NODE, MD_NODE_HALL); /* boot-up heartbeat, then announce */
    TEST_ASSERT_EQUAL_HEX32(0x703u, cap[1].id);
    TEST_ASSERT_EQUAL_HEX8(MD_NODE_STATE_BOOT, cap[1].data[0]);
    TEST_ASSERT_EQUAL_HEX8(MD_PROTOCOL_VERSION, cap[1].data[1]);
    TEST_ASSERT_EQUAL_UINT32(1u, plant.hall.node.resets);
    TEST_ASSERT_EQUAL_size_t(36u, count_id(MD_CAN_HALL_CALIB_FRAME_ID));
    send_nmt(MD_NMT_PREOP, 0u); /* broadcast */
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, plant.act.node.state);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, plant.hall.node.state);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, plant.fe.node.state);
    n_cap = 0u;
    send_act(0u, MD_ACT_CMD_STEP, MD_ACT_DIR_ADVANCE, 1u, 10u, 100u);
    TEST_ASSERT_EQUAL_size_t(0u, n_cap);
    send_nmt(MD_NMT_START, 9u); /* someone else's node */
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, plant.act.node.state);
}

static void test_no_autostart_waits_for_nmt_start(void)
{
    make_plant(true, false, 7u);
    TEST_ASSERT_EQUAL_size_t(0u, n_cap); /* nothing but heartbeats (sent by the process) */
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, plant.fe.node.state);
    send_rec(0u, 1u, 30u);
    TEST_ASSERT_EQUAL_size_t(0u, n_cap);
    send_nmt(MD_NMT_START, 0u);
    TEST_ASSERT_EQUAL_size_t(3u, count_id(MD_CAN_FE_INFO_FRAME_ID));
    n_cap = 0u;
    send_rec(0u, 1u, 30u);
    check_stream(0u, 1u, 30u);
}

static void test_hall_seq_wraps_and_time_is_simulated(void)
{
    /* 3 s of recording at 100 Hz readings: 300 per electrode, Seq mod 256 */
    send_rec(0u, 1u, 90000u);
    uint32_t k = 1u; /* the start-up reading was Seq 0 */
    for (size_t i = 0; i < n_cap; i++) {
        if (cap[i].id != MD_CAN_HALL_READING_FRAME_ID) {
            continue;
        }
        struct md_can_hall_reading_t r;
        TEST_ASSERT_EQUAL_INT(0, md_can_hall_reading_unpack(&r, cap[i].data, cap[i].len));
        if (r.electrode == 2u) {
            TEST_ASSERT_EQUAL_UINT8((uint8_t)(k & 0xFFu), r.seq);
            TEST_ASSERT_EQUAL_UINT32(k * 10u, r.sample_time_ms);
            k++;
        }
    }
    TEST_ASSERT_EQUAL_UINT32(301u, k);
    TEST_ASSERT_EQUAL_UINT64(3000000u, plant.now_us);
}

/* Fault injection (scenario node_silent): the Hall node sends nothing in
 * [1 s, 2 s) of simulated time, counted in tx_silenced, and is back after;
 * the other nodes are not affected. A launcher's later clock also counts. */
static void test_silent_node_sends_nothing_in_its_window(void)
{
    static const char y[] = "electrodes:\n  - start_um: 1000\n"
                            "faults:\n  - {kind: node_silent, node: hall, from_s: 1, to_s: 2}\n";
    static scenario_t sc;
    char err[256];
    TEST_ASSERT_EQUAL_INT(0, scenario_parse(&sc, y, sizeof y - 1u, "silent.yaml", err, sizeof err));
    simnode_world_destroy(world);
    world = simnode_world_create_scenario(&sc, 3u, err, sizeof err);
    TEST_ASSERT_MESSAGE(world != NULL, err);
    simnode_plant_cfg_t cfg;
    simnode_plant_cfg_default(&cfg);
    const simnode_sink_t sink = {capture, NULL};
    TEST_ASSERT_EQUAL_INT(MD_OK, simnode_plant_init(&plant, &cfg, world, sink));
    simnode_plant_start(&plant);
    n_cap = 0u;
    send_rec(0u, 1u, 90000u); /* 3 s of simulated time */
    uint32_t before = 0u, inside = 0u, after = 0u;
    for (size_t i = 0; i < n_cap; i++) {
        if (cap[i].id != MD_CAN_HALL_READING_FRAME_ID) {
            continue;
        }
        struct md_can_hall_reading_t r;
        TEST_ASSERT_EQUAL_INT(0, md_can_hall_reading_unpack(&r, cap[i].data, cap[i].len));
        before += (r.sample_time_ms < 1000u) ? 1u : 0u;
        inside += (r.sample_time_ms >= 1000u && r.sample_time_ms < 2000u) ? 1u : 0u;
        after += (r.sample_time_ms >= 2000u) ? 1u : 0u;
    }
    TEST_ASSERT_EQUAL_UINT32(0u, inside);
    TEST_ASSERT_GREATER_THAN_UINT(90u, before);
    TEST_ASSERT_GREATER_THAN_UINT(90u, after);
    TEST_ASSERT_EQUAL_UINT64(100u, plant.hall.node.stats.tx_silenced);
    TEST_ASSERT_EQUAL_UINT64(0u, plant.fe.node.stats.tx_silenced);
    TEST_ASSERT_EQUAL_UINT64(0u, plant.act.node.stats.tx_silenced);
    TEST_ASSERT_FALSE(plant.hall.node.silent);
    /* a launcher clock ahead of the idle lockstep plant silences at once; an
     * earlier time never undoes it (the latest time seen counts) */
    simnode_world_destroy(world);
    world = simnode_world_create_scenario(&sc, 3u, err, sizeof err);
    TEST_ASSERT_MESSAGE(world != NULL, err);
    TEST_ASSERT_EQUAL_INT(MD_OK, simnode_plant_init(&plant, &cfg, world, sink));
    simnode_plant_silence_at(&plant, 1500000u);
    TEST_ASSERT_TRUE(plant.hall.node.silent);
    TEST_ASSERT_FALSE(plant.act.node.silent);
    simnode_plant_silence_at(&plant, 500000u);
    TEST_ASSERT_TRUE(plant.hall.node.silent);
    simnode_plant_silence_at(&plant, 2000000u);
    TEST_ASSERT_FALSE(plant.hall.node.silent);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_silent_node_sends_nothing_in_its_window);
    RUN_TEST(test_start_announces_every_node_in_one_batch);
    RUN_TEST(test_act_cmd_moves_and_reports_with_seq);
    RUN_TEST(test_halt_is_acknowledged_without_time);
    RUN_TEST(test_rec_req_streams_exactly_n_samples_in_order);
    RUN_TEST(test_stream_samples_are_noise_not_zeros);
    RUN_TEST(test_same_seed_same_frames_other_seed_other_frames);
    RUN_TEST(test_malformed_frames_are_counted_and_ignored);
    RUN_TEST(test_estop_halts_latches_until_clear);
    RUN_TEST(test_estop_interrupts_motion_in_realtime);
    RUN_TEST(test_realtime_stream_follows_time);
    RUN_TEST(test_retract_into_top_stop_stalls_with_emcy);
    RUN_TEST(test_nmt_targets_and_broadcast);
    RUN_TEST(test_no_autostart_waits_for_nmt_start);
    RUN_TEST(test_hall_seq_wraps_and_time_is_simulated);
    return UNITY_END();
}
