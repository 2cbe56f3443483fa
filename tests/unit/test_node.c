/// Unit tests of the controller node (md_node): NMT, heartbeat producer and
/// consumer, e-stop latch, EMCY, parameters over the bus, frame validation.
/// The node is driven through a fake md_port_t that records every sent frame
/// and a fake clock (the test owns `now`); no host-only facility is used, so
/// the same file runs on the Cortex-M7 target.
#include <math.h>
#include <string.h>

#include "md_can.h"
#include "md_node.h"
#include "unity.h"

#define SENT_MAX 400u
#define T0_US 5000000u /* arbitrary non-zero power-on time */
#define MS 1000u

static md_frame_t g_sent[SENT_MAX];
static uint64_t g_sent_at[SENT_MAX];
static size_t g_n_sent;
static bool g_fail_send;
static uint64_t g_now;
static md_node_t g_node;

static md_status_t fake_send(void *ctx, const md_frame_t *f)
{
    (void)ctx;
    if (g_fail_send) {
        return MD_E_IO;
    }
    if (g_n_sent < SENT_MAX) {
        g_sent[g_n_sent] = *f;
        g_sent_at[g_n_sent] = g_now;
    }
    g_n_sent++;
    return MD_OK;
}

static uint64_t fake_now(void *ctx)
{
    (void)ctx;
    return g_now;
}

void setUp(void)
{
    g_n_sent = 0u;
    g_fail_send = false;
    g_now = T0_US;
    const md_port_t port = {fake_send, fake_now, NULL, NULL, NULL};
    TEST_ASSERT_EQUAL_INT(MD_OK, md_node_init(&g_node, &port, g_now));
}
void tearDown(void) {}

/* ---- helpers ---------------------------------------------------------- */

static void poll_until(uint64_t t_us, uint64_t step_us)
{
    for (uint32_t guard = 0u; g_now < t_us && guard < 2000000u; ++guard) {
        g_now += step_us;
        (void)md_node_poll(&g_node, g_now);
    }
}

static void boot(void)
{
    TEST_ASSERT_EQUAL_INT(MD_OK, md_node_poll(&g_node, g_now));
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
}

static size_t count_id(uint32_t id, size_t from)
{
    size_t n = 0u;
    for (size_t i = from; i < g_n_sent && i < SENT_MAX; ++i) {
        n += (g_sent[i].id == id) ? 1u : 0u;
    }
    return n;
}

static const md_frame_t *last_of(uint32_t id)
{
    for (size_t i = (g_n_sent < SENT_MAX ? g_n_sent : SENT_MAX); i > 0u; --i) {
        if (g_sent[i - 1u].id == id) {
            return &g_sent[i - 1u];
        }
    }
    return NULL;
}

static md_frame_t frame_of(uint32_t id, const uint8_t *data, int len)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = (uint8_t)len;
    if (len > 8) {
        f.flags = MD_FRAME_FLAG_FD;
    }
    memcpy(f.data, data, (size_t)len);
    return f;
}

static md_status_t rx(const md_frame_t *f)
{
    return md_node_on_frame(&g_node, f, g_now);
}

static md_status_t nmt(uint8_t cmd, uint8_t target)
{
    const struct md_can_nmt_t m = {cmd, target};
    uint8_t b[8];
    const md_frame_t f = frame_of(MD_CAN_NMT_FRAME_ID, b, md_can_nmt_pack(b, &m, sizeof b));
    return rx(&f);
}

static md_status_t estop(uint8_t source)
{
    const struct md_can_estop_t m = {source, 1u};
    uint8_t b[8];
    const md_frame_t f = frame_of(MD_CAN_ESTOP_FRAME_ID, b, md_can_estop_pack(b, &m, sizeof b));
    return rx(&f);
}

static md_status_t heartbeat_from(uint8_t node_id, uint8_t version)
{
    const struct md_can_heartbeat_act_t m = {(uint8_t)MD_NODE_STATE_OPERATIONAL, version, 0u, 3u, 1u};
    uint8_t b[8];
    const md_frame_t f = frame_of(0x700u + node_id, b, md_can_heartbeat_act_pack(b, &m, sizeof b));
    return rx(&f);
}

static md_frame_t param_req_frame(uint8_t op, uint16_t index, float value)
{
    const struct md_can_param_req_ctrl_t m = {op, 0u, index, value};
    uint8_t b[8];
    return frame_of(MD_CAN_PARAM_REQ_CTRL_FRAME_ID, b, md_can_param_req_ctrl_pack(b, &m, sizeof b));
}

/* Sends a request and returns the decoded response (fails the test if none). */
static struct md_can_param_resp_ctrl_t param(uint8_t op, md_param_id_t id_or_count, uint16_t raw_index, float value)
{
    const uint16_t index = (id_or_count < MD_P_COUNT) ? md_params_def((size_t)id_or_count)->index : raw_index;
    const size_t before = g_n_sent;
    const md_frame_t f = param_req_frame(op, index, value);
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    TEST_ASSERT_EQUAL_size_t(1u, count_id(MD_CAN_PARAM_RESP_CTRL_FRAME_ID, before));
    struct md_can_param_resp_ctrl_t r;
    memset(&r, 0, sizeof r);
    const md_frame_t *resp = last_of(MD_CAN_PARAM_RESP_CTRL_FRAME_ID);
    if (resp == NULL) {
        TEST_FAIL_MESSAGE("no PARAM_RESP_CTRL");
        return r;
    }
    TEST_ASSERT_EQUAL_UINT8(MD_CAN_PARAM_RESP_CTRL_LENGTH, resp->len);
    TEST_ASSERT_EQUAL_INT(0, md_can_param_resp_ctrl_unpack(&r, resp->data, resp->len));
    TEST_ASSERT_EQUAL_UINT16(index, r.index);
    TEST_ASSERT_EQUAL_UINT8(op, r.op);
    return r;
}

static struct md_can_heartbeat_ctrl_t decode_hb(const md_frame_t *f)
{
    struct md_can_heartbeat_ctrl_t m;
    memset(&m, 0, sizeof m);
    if (f == NULL) {
        TEST_FAIL_MESSAGE("frame not sent");
        return m;
    }
    TEST_ASSERT_EQUAL_UINT8(MD_CAN_HEARTBEAT_CTRL_LENGTH, f->len);
    TEST_ASSERT_EQUAL_INT(0, md_can_heartbeat_ctrl_unpack(&m, f->data, f->len));
    return m;
}

static struct md_can_emcy_ctrl_t decode_emcy(const md_frame_t *f)
{
    struct md_can_emcy_ctrl_t m;
    memset(&m, 0, sizeof m);
    if (f == NULL) {
        TEST_FAIL_MESSAGE("frame not sent");
        return m;
    }
    TEST_ASSERT_EQUAL_INT(0, md_can_emcy_ctrl_unpack(&m, f->data, f->len));
    return m;
}

/* Every electrode received exactly one halt since `from`. */
static void assert_halts_since(size_t from)
{
    uint32_t seen = 0u;
    for (size_t i = from; i < g_n_sent && i < SENT_MAX; ++i) {
        if (g_sent[i].id != MD_CAN_ACT_CMD_FRAME_ID) {
            continue;
        }
        struct md_can_act_cmd_t m;
        TEST_ASSERT_EQUAL_INT(0, md_can_act_cmd_unpack(&m, g_sent[i].data, g_sent[i].len));
        TEST_ASSERT_EQUAL_UINT8(MD_ACT_CMD_HALT, m.command);
        TEST_ASSERT_TRUE(m.electrode < MD_ELECTRODES);
        TEST_ASSERT_TRUE_MESSAGE((seen & (1u << m.electrode)) == 0u, "one halt per electrode");
        seen |= 1u << m.electrode;
    }
    TEST_ASSERT_EQUAL_UINT32((1u << MD_ELECTRODES) - 1u, seen);
}

/* ---- NMT and heartbeat producer --------------------------------------- */

static void test_boot_up_heartbeat_then_preop(void)
{
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_BOOT, g_node.state);
    TEST_ASSERT_EQUAL_size_t(0u, g_n_sent);
    boot();
    TEST_ASSERT_EQUAL_size_t(1u, g_n_sent);
    const struct md_can_heartbeat_ctrl_t hb = decode_hb(&g_sent[0]);
    TEST_ASSERT_EQUAL_UINT8(MD_NODE_STATE_BOOT, hb.node_state);
    TEST_ASSERT_EQUAL_UINT8(MD_PROTOCOL_VERSION, hb.protocol_version);
    TEST_ASSERT_EQUAL_UINT8(MD_ELECTRODES, hb.electrodes);
    TEST_ASSERT_EQUAL_UINT8(0u, hb.flags);
}

static void test_heartbeat_period_and_content(void)
{
    boot();
    const size_t from = g_n_sent;
    poll_until(T0_US + 2000u * MS, 1u * MS);
    TEST_ASSERT_EQUAL_size_t(20u, count_id(MD_CAN_HEARTBEAT_CTRL_FRAME_ID, from));
    uint64_t prev = T0_US;
    for (size_t i = from; i < g_n_sent; ++i) {
        const struct md_can_heartbeat_ctrl_t hb = decode_hb(&g_sent[i]);
        TEST_ASSERT_EQUAL_UINT64(prev + 100u * MS, g_sent_at[i]); /* exactly one period apart */
        TEST_ASSERT_EQUAL_UINT8(MD_NODE_STATE_PREOP, hb.node_state);
        TEST_ASSERT_EQUAL_UINT8(MD_PROTOCOL_VERSION, hb.protocol_version);
        TEST_ASSERT_EQUAL_UINT32((uint32_t)((g_sent_at[i] - T0_US) / 1000000u), hb.uptime_s);
        prev = g_sent_at[i];
    }
    TEST_ASSERT_EQUAL_UINT64(T0_US + 2100u * MS, md_node_next_deadline_us(&g_node, g_now));
}

static void test_heartbeat_period_parameter_applies(void)
{
    boot();
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OK, param(MD_PARAM_OP_SET, MD_P_HEARTBEAT_PERIOD_MS, 0u, 250.0f).status);
    const size_t from = g_n_sent;
    poll_until(T0_US + 1000u * MS, 1u * MS);
    TEST_ASSERT_EQUAL_size_t(4u, count_id(MD_CAN_HEARTBEAT_CTRL_FRAME_ID, from));
}

/* Regression (fuzz_node, tests/fuzz/crashes/fuzz_node): an NMT start that
 * arrives after init but before the first poll must not make the node
 * operational (it would step, then be overwritten by the boot-up without a
 * halt): the initialising node refuses state commands. */
static void test_nmt_start_before_bootup_is_refused(void)
{
    const uint32_t refused = g_node.counters.nmt_refused;
    TEST_ASSERT_EQUAL_INT(MD_OK, nmt((uint8_t)MD_NMT_START, 0u));
    TEST_ASSERT_EQUAL_UINT(refused + 1u, g_node.counters.nmt_refused);
    TEST_ASSERT_TRUE(g_node.state != MD_NODE_STATE_OPERATIONAL);
    TEST_ASSERT_TRUE(md_node_step(&g_node, 0u, MD_ACT_DIR_ADVANCE, 10u, 100u) < 0);
    TEST_ASSERT_EQUAL_UINT(0u, count_id(MD_CAN_ACT_CMD_FRAME_ID, 0u));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_node_poll(&g_node, g_now));
    const md_frame_t *hb = last_of(MD_CAN_HEARTBEAT_CTRL_FRAME_ID);
    TEST_ASSERT_NOT_NULL(hb);
    TEST_ASSERT_EQUAL_UINT(MD_NODE_STATE_BOOT, hb->data[0]); /* the boot-up says "boot", not "operational" */
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
}

static void test_nmt_transitions(void)
{
    boot();
    TEST_ASSERT_EQUAL_INT(MD_OK, nmt(MD_NMT_START, MD_NODE_CTRL));
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_OPERATIONAL, g_node.state);
    TEST_ASSERT_EQUAL_INT(MD_OK, nmt(MD_NMT_STOP, 0u)); /* broadcast */
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_STOPPED, g_node.state);
    TEST_ASSERT_EQUAL_INT(MD_OK, nmt(MD_NMT_START, 0u));
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_OPERATIONAL, g_node.state);
    TEST_ASSERT_EQUAL_INT(MD_OK, nmt(MD_NMT_PREOP, MD_NODE_CTRL));
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
    TEST_ASSERT_EQUAL_INT(MD_OK, nmt(MD_NMT_START, MD_NODE_ACT)); /* for another node: ignored */
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
    poll_until(g_now + 100u * MS, 1u * MS);
    TEST_ASSERT_EQUAL_UINT8(MD_NODE_STATE_PREOP, decode_hb(last_of(MD_CAN_HEARTBEAT_CTRL_FRAME_ID)).node_state);
}

static void test_leaving_operational_halts_every_electrode(void)
{
    boot();
    (void)nmt(MD_NMT_START, 0u);
    size_t from = g_n_sent;
    (void)nmt(MD_NMT_STOP, 0u);
    assert_halts_since(from);
    (void)nmt(MD_NMT_START, 0u);
    from = g_n_sent;
    (void)nmt(MD_NMT_PREOP, 0u);
    assert_halts_since(from);
}

static void test_reset_node_reboots_with_defaults(void)
{
    boot();
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OK, param(MD_PARAM_OP_SET, MD_P_INTERVAL_S, 0u, 20.0f).status);
    (void)nmt(MD_NMT_START, 0u);
    const size_t from = g_n_sent;
    TEST_ASSERT_EQUAL_INT(MD_OK, nmt(MD_NMT_RESET_NODE, MD_NODE_CTRL));
    assert_halts_since(from); /* it was operational */
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_BOOT, g_node.state);
    (void)md_node_poll(&g_node, g_now);
    TEST_ASSERT_EQUAL_UINT8(MD_NODE_STATE_BOOT, decode_hb(last_of(MD_CAN_HEARTBEAT_CTRL_FRAME_ID)).node_state);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 10.0, md_params_get(&g_node.params, MD_P_INTERVAL_S));
}

static void test_auto_start(void)
{
    g_node.params.value[MD_P_AUTO_START] = 1.0;
    (void)md_node_poll(&g_node, g_now);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_OPERATIONAL, g_node.state);
}

/* ---- heartbeat consumer ------------------------------------------------ */

static void feed_act_heartbeats(uint64_t until_us)
{
    for (uint32_t guard = 0u; g_now < until_us && guard < 100000u; ++guard) {
        if ((g_now - T0_US) % (100u * MS) == 0u) {
            TEST_ASSERT_EQUAL_INT(MD_OK, heartbeat_from(MD_NODE_ACT, MD_PROTOCOL_VERSION));
        }
        g_now += MS;
        (void)md_node_poll(&g_node, g_now);
    }
}

static void test_lost_heartbeat_one_emcy_within_timeout_and_halts(void)
{
    boot();
    (void)nmt(MD_NMT_START, 0u);
    feed_act_heartbeats(T0_US + 1000u * MS);
    TEST_ASSERT_TRUE(md_node_motion_allowed(&g_node));
    const uint64_t last_hb = g_node.monitor[0].last_us;
    const size_t from = g_n_sent;
    poll_until(g_now + 3000u * MS, 1u * MS);
    TEST_ASSERT_EQUAL_size_t(1u, count_id(MD_CAN_EMCY_CTRL_FRAME_ID, from));
    size_t k = from;
    while (g_sent[k].id != MD_CAN_EMCY_CTRL_FRAME_ID) {
        ++k;
    }
    const struct md_can_emcy_ctrl_t e = decode_emcy(&g_sent[k]);
    TEST_ASSERT_EQUAL_UINT16(MD_EMCY_HEARTBEAT_LOST, e.error_code);
    TEST_ASSERT_EQUAL_UINT32(MD_NODE_ACT, e.info);
    TEST_ASSERT_TRUE((e.error_register & MD_NODE_ERREG_COMMUNICATION) != 0u);
    /* "silence longer than the timeout": after last + 500 ms, within one poll step */
    const uint64_t timeout_us = 500u * MS;
    TEST_ASSERT_GREATER_THAN_UINT(last_hb + timeout_us, g_sent_at[k]);
    TEST_ASSERT_LESS_OR_EQUAL_UINT(last_hb + timeout_us + MS, g_sent_at[k]);
    assert_halts_since(from);
    TEST_ASSERT_FALSE(md_node_motion_allowed(&g_node));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, md_node_step(&g_node, 0u, MD_ACT_DIR_ADVANCE, 10u, 100u));
    TEST_ASSERT_TRUE((md_node_heartbeat_flags(&g_node) & MD_HB_FLAG_FAULT) != 0u);
    TEST_ASSERT_EQUAL_UINT32(1u, g_node.counters.heartbeat_lost);
}

static void test_node_back_lifts_inhibit(void)
{
    boot();
    (void)nmt(MD_NMT_START, 0u);
    feed_act_heartbeats(T0_US + 500u * MS);
    poll_until(g_now + 1000u * MS, 1u * MS);
    TEST_ASSERT_FALSE(md_node_motion_allowed(&g_node));
    const size_t from = g_n_sent;
    TEST_ASSERT_EQUAL_INT(MD_OK, heartbeat_from(MD_NODE_ACT, MD_PROTOCOL_VERSION));
    TEST_ASSERT_EQUAL_size_t(1u, count_id(MD_CAN_EMCY_CTRL_FRAME_ID, from));
    const struct md_can_emcy_ctrl_t e = decode_emcy(last_of(MD_CAN_EMCY_CTRL_FRAME_ID));
    TEST_ASSERT_EQUAL_UINT16(MD_EMCY_NONE, e.error_code);
    TEST_ASSERT_EQUAL_UINT32(MD_NODE_ACT, e.info);
    TEST_ASSERT_EQUAL_UINT32(1u, g_node.counters.node_back);
    TEST_ASSERT_TRUE(md_node_motion_allowed(&g_node));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_node_step(&g_node, 1u, MD_ACT_DIR_ADVANCE, 10u, 100u));
    TEST_ASSERT_EQUAL_UINT8(0u, md_node_heartbeat_flags(&g_node));
}

static void test_never_seen_or_unmonitored_node_is_not_lost(void)
{
    boot();
    poll_until(T0_US + 5000u * MS, 10u * MS); /* nobody ever sent a heartbeat */
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_EMCY_CTRL_FRAME_ID, 0u));
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OK, param(MD_PARAM_OP_SET, MD_P_MONITOR_HALL, 0u, 0.0f).status);
    TEST_ASSERT_EQUAL_INT(MD_OK, heartbeat_from(MD_NODE_HALL, MD_PROTOCOL_VERSION));
    poll_until(g_now + 5000u * MS, 10u * MS);
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_EMCY_CTRL_FRAME_ID, 0u));
    /* motion also needs the (monitored) actuator to have been heard */
    (void)nmt(MD_NMT_START, 0u);
    TEST_ASSERT_FALSE(md_node_motion_allowed(&g_node));
}

static void test_deadline_tracks_heartbeat_timeout(void)
{
    boot();
    (void)heartbeat_from(MD_NODE_FE, MD_PROTOCOL_VERSION);
    g_node.next_heartbeat_us = g_now + 10000u * MS; /* make the monitor the earliest deadline */
    TEST_ASSERT_EQUAL_UINT64(g_now + 500u * MS + 1u, md_node_next_deadline_us(&g_node, g_now));
}

/* ---- e-stop ------------------------------------------------------------ */

static void test_estop_latches_until_clear_even_through_reset(void)
{
    boot();
    (void)nmt(MD_NMT_START, 0u);
    feed_act_heartbeats(T0_US + 300u * MS);
    size_t from = g_n_sent;
    TEST_ASSERT_EQUAL_INT(MD_OK, estop(MD_NODE_OPER));
    assert_halts_since(from);
    TEST_ASSERT_EQUAL_size_t(1u, count_id(MD_CAN_EMCY_CTRL_FRAME_ID, from));
    const struct md_can_emcy_ctrl_t e = decode_emcy(last_of(MD_CAN_EMCY_CTRL_FRAME_ID));
    TEST_ASSERT_EQUAL_UINT16(MD_EMCY_ESTOP, e.error_code);
    TEST_ASSERT_EQUAL_UINT32(MD_NODE_OPER, e.info);
    TEST_ASSERT_TRUE((e.error_register & MD_NODE_ERREG_MANUFACTURER) != 0u);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
    /* refused while latched: start, motion, motion parameters */
    (void)nmt(MD_NMT_START, 0u);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
    TEST_ASSERT_EQUAL_UINT32(1u, g_node.counters.nmt_refused);
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, md_node_step(&g_node, 0u, MD_ACT_DIR_ADVANCE, 1u, 1u));
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_REFUSED, param(MD_PARAM_OP_SET, MD_P_MOVE_MAX_UM, 0u, 40.0f).status);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OK, param(MD_PARAM_OP_SET, MD_P_HEARTBEAT_TIMEOUT_MS, 0u, 800.0f).status);
    /* a second ESTOP halts again but does not repeat the EMCY */
    from = g_n_sent;
    (void)estop(MD_NODE_OPER);
    assert_halts_since(from);
    TEST_ASSERT_EQUAL_size_t(0u, count_id(MD_CAN_EMCY_CTRL_FRAME_ID, from));
    /* time does not clear it, nor does reset-node */
    feed_act_heartbeats(g_now + 600000u * MS / 60u);
    (void)nmt(MD_NMT_RESET_NODE, 0u);
    (void)md_node_poll(&g_node, g_now);
    TEST_ASSERT_TRUE(g_node.estop_latched);
    TEST_ASSERT_EQUAL_UINT8(MD_HB_FLAG_ESTOP,
                            decode_hb(last_of(MD_CAN_HEARTBEAT_CTRL_FRAME_ID)).flags & MD_HB_FLAG_ESTOP);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
    /* clear-e-stop for another node does nothing; for us it unlatches but does not start */
    (void)nmt(MD_NMT_CLEAR_ESTOP, MD_NODE_ACT);
    TEST_ASSERT_TRUE(g_node.estop_latched);
    (void)nmt(MD_NMT_CLEAR_ESTOP, MD_NODE_CTRL);
    TEST_ASSERT_FALSE(g_node.estop_latched);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
    TEST_ASSERT_FALSE(md_node_motion_allowed(&g_node));
    (void)nmt(MD_NMT_START, 0u);
    feed_act_heartbeats(g_now + 200u * MS);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_node_step(&g_node, 2u, MD_ACT_DIR_RETRACT, 5u, 50u));
}

static void test_malformed_estop_still_latches(void)
{
    boot();
    const uint8_t one = 5u;
    const md_frame_t f = frame_of(MD_CAN_ESTOP_FRAME_ID, &one, 1);
    TEST_ASSERT_EQUAL_INT(MD_E_FRAME, rx(&f));
    TEST_ASSERT_TRUE(g_node.estop_latched);
    TEST_ASSERT_EQUAL_UINT32(1u, g_node.counters.rx_bad_length);
}

/* ---- parameters over the bus ------------------------------------------- */

static void test_param_get_set_and_errors(void)
{
    boot();
    struct md_can_param_resp_ctrl_t r = param(MD_PARAM_OP_GET, MD_P_HEARTBEAT_PERIOD_MS, 0u, 0.0f);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OK, r.status);
    TEST_ASSERT_FLOAT_WITHIN(0.0f, 100.0f, r.value);
    r = param(MD_PARAM_OP_SET, MD_P_HEARTBEAT_TIMEOUT_MS, 0u, 300.0f);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OK, r.status);
    TEST_ASSERT_FLOAT_WITHIN(0.0f, 300.0f, r.value);
    r = param(MD_PARAM_OP_SET, MD_P_HEARTBEAT_TIMEOUT_MS, 0u, 1e9f);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OUT_OF_RANGE, r.status);
    TEST_ASSERT_FLOAT_WITHIN(0.0f, 300.0f, r.value); /* unchanged, and the answer says so */
    r = param(MD_PARAM_OP_SET, MD_P_HEARTBEAT_TIMEOUT_MS, 0u, NAN);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OUT_OF_RANGE, r.status);
    r = param(MD_PARAM_OP_SET, MD_P_HEARTBEAT_TIMEOUT_MS, 0u, INFINITY);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OUT_OF_RANGE, r.status);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 300.0, md_params_get(&g_node.params, MD_P_HEARTBEAT_TIMEOUT_MS));
    r = param(MD_PARAM_OP_SET, MD_P_RX_FRAMES, 0u, 0.0f);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_READ_ONLY, r.status);
    r = param(MD_PARAM_OP_GET, MD_P_COUNT, 0x7777u, 0.0f);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_UNKNOWN_INDEX, r.status);
    r = param(MD_PARAM_OP_SET, MD_P_COUNT, 0x7777u, 1.0f);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_UNKNOWN_INDEX, r.status);
    r = param(9u, MD_P_HEARTBEAT_PERIOD_MS, 0u, 0.0f);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_BAD_OP, r.status);
    (void)nmt(MD_NMT_START, 0u);
    r = param(MD_PARAM_OP_SET, MD_P_INTERVAL_S, 0u, 5.0f); /* config row while operational */
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_REFUSED, r.status);
    TEST_ASSERT_FLOAT_WITHIN(0.0f, 10.0f, r.value);
}

static void test_counters_readable_as_parameters(void)
{
    boot();
    const md_frame_t bad = frame_of(0x123u, (const uint8_t *)"\x01\x02", 2);
    (void)rx(&bad);
    (void)rx(&bad);
    const struct md_can_param_resp_ctrl_t r = param(MD_PARAM_OP_GET, MD_P_RX_UNKNOWN_ID, 0u, 0.0f);
    TEST_ASSERT_EQUAL_UINT8(MD_PARAM_OK, r.status);
    TEST_ASSERT_FLOAT_WITHIN(0.0f, 2.0f, r.value);
    const struct md_can_param_resp_ctrl_t n = param(MD_PARAM_OP_GET, MD_P_RX_FRAMES, 0u, 0.0f);
    TEST_ASSERT_FLOAT_WITHIN(0.0f, 4.0f, n.value); /* two bad frames + two requests */
}

/* ---- malformed frames: counted by kind, nothing else changes ------------ */

static md_node_t g_before;

static void snapshot(void)
{
    g_before = g_node;
}

static void assert_unchanged_except_counters(void)
{
    md_node_t now = g_node;
    now.counters = g_before.counters;
    now.protocol_emcy_sent = g_before.protocol_emcy_sent;
    now.protocol_emcy_us = g_before.protocol_emcy_us;
    TEST_ASSERT_EQUAL_MEMORY(&g_before, &now, sizeof now);
}

static void expect_rejected(const md_frame_t *f)
{
    const size_t from = g_n_sent;
    snapshot();
    TEST_ASSERT_EQUAL_INT(MD_E_FRAME, rx(f));
    assert_unchanged_except_counters();
    /* nothing but (at most) one protocol EMCY goes out */
    TEST_ASSERT_EQUAL_size_t(g_n_sent - from, count_id(MD_CAN_EMCY_CTRL_FRAME_ID, from));
    TEST_ASSERT_LESS_OR_EQUAL_UINT(1u, g_n_sent - from);
}

static void test_malformed_frames_counted_and_ignored(void)
{
    boot();
    (void)nmt(MD_NMT_START, 0u);
    feed_act_heartbeats(T0_US + 200u * MS);
    const md_node_counters_t c0 = g_node.counters;
    md_frame_t f = param_req_frame(MD_PARAM_OP_SET, 0x1017u, 500.0f);
    f.len = 7u; /* wrong length */
    expect_rejected(&f);
    f = param_req_frame(MD_PARAM_OP_SET, 0x1017u, 500.0f);
    f.flags = MD_FRAME_FLAG_FD; /* classic frame sent as FD */
    expect_rejected(&f);
    uint8_t b[64];
    memset(b, 0, sizeof b);
    f = frame_of(MD_CAN_REC_DATA_FRAME_ID, b, 64);
    f.flags = 0u; /* FD frame without the FD flag: not even a valid frame */
    expect_rejected(&f);
    f = frame_of(MD_CAN_NMT_FRAME_ID, (const uint8_t *)"\x02\x00", 2);
    f.id = 0x7FFu; /* unknown id */
    expect_rejected(&f);
    f.id = MD_CAN_NMT_FRAME_ID;
    f.flags = MD_FRAME_FLAG_EXT; /* 29-bit id 1 is not our NMT */
    expect_rejected(&f);
    const md_node_counters_t c1 = g_node.counters;
    TEST_ASSERT_EQUAL_UINT32(c0.rx_bad_length + 2u, c1.rx_bad_length);
    TEST_ASSERT_EQUAL_UINT32(c0.rx_malformed + 3u, c1.rx_malformed);
    TEST_ASSERT_EQUAL_UINT32(c0.rx_unknown_id + 2u, c1.rx_unknown_id);
    TEST_ASSERT_EQUAL_UINT32(c0.rx_frames + 5u, c1.rx_frames);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_OPERATIONAL, g_node.state);
}

static void test_out_of_range_signals_rejected(void)
{
    boot();
    const md_node_counters_t c0 = g_node.counters;
    md_frame_t f = frame_of(MD_CAN_NMT_FRAME_ID, (const uint8_t *)"\x07\x00", 2); /* no NMT command 7 */
    expect_rejected(&f);
    uint8_t b[64];
    memset(b, 0, sizeof b);
    b[1] = 31u; /* REC_DATA SampleCount > 30 */
    f = frame_of(MD_CAN_REC_DATA_FRAME_ID, b, 64);
    expect_rejected(&f);
    memset(b, 0, sizeof b);
    b[0] = (uint8_t)MD_ELECTRODES; /* HALL_READING for an electrode that does not exist */
    f = frame_of(MD_CAN_HALL_READING_FRAME_ID, b, 8);
    expect_rejected(&f);
    memset(b, 0, sizeof b);
    b[1] = 9u; /* ACT_STATUS State 9 */
    f = frame_of(MD_CAN_ACT_STATUS_FRAME_ID, b, 8);
    expect_rejected(&f);
    const struct md_can_hall_calib_t cal = {0u, 0u, 2u, NAN};
    f = frame_of(MD_CAN_HALL_CALIB_FRAME_ID, b, md_can_hall_calib_pack(b, &cal, sizeof b));
    expect_rejected(&f);
    snapshot();
    TEST_ASSERT_EQUAL_INT(MD_E_FRAME, heartbeat_from(MD_NODE_ACT, MD_PROTOCOL_VERSION + 1u));
    assert_unchanged_except_counters();
    TEST_ASSERT_FALSE(g_node.monitor[0].seen);
    TEST_ASSERT_EQUAL_UINT32(c0.rx_bad_range + 6u, g_node.counters.rx_bad_range);
    TEST_ASSERT_EQUAL_UINT32(c0.rx_malformed + 6u, g_node.counters.rx_malformed);
}

static void test_hall_calib_normalisation_indices(void)
{
    boot();
    uint8_t b[8];
    struct md_can_hall_calib_t cal = {0u, MD_HALL_CALIB_INDEX_CODE_MID, 4u, 2048.0f};
    md_frame_t f = frame_of(MD_CAN_HALL_CALIB_FRAME_ID, b, md_can_hall_calib_pack(b, &cal, sizeof b));
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    cal.coeff_index = MD_HALL_CALIB_INDEX_CODE_HALF;
    f = frame_of(MD_CAN_HALL_CALIB_FRAME_ID, b, md_can_hall_calib_pack(b, &cal, sizeof b));
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    cal.coeff_value = 0.0f; /* code_half divides: must be > 0 */
    f = frame_of(MD_CAN_HALL_CALIB_FRAME_ID, b, md_can_hall_calib_pack(b, &cal, sizeof b));
    expect_rejected(&f);
    cal.coeff_index = 3u;
    cal.coeff_value = -1.5f;
    f = frame_of(MD_CAN_HALL_CALIB_FRAME_ID, b, md_can_hall_calib_pack(b, &cal, sizeof b));
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    cal.coeff_index = 4u; /* == CoeffCount */
    f = frame_of(MD_CAN_HALL_CALIB_FRAME_ID, b, md_can_hall_calib_pack(b, &cal, sizeof b));
    expect_rejected(&f);
    TEST_ASSERT_EQUAL_UINT32(2u, g_node.counters.rx_bad_range);
}

static md_frame_t hall(uint8_t e, uint8_t seq)
{
    const struct md_can_hall_reading_t m = {e, seq, 1234u, 0u};
    uint8_t b[8];
    return frame_of(MD_CAN_HALL_READING_FRAME_ID, b, md_can_hall_reading_pack(b, &m, sizeof b));
}

static md_frame_t rec(uint8_t e, uint16_t seq)
{
    struct md_can_rec_data_t m;
    (void)md_can_rec_data_init(&m);
    m.electrode = e;
    m.sample_count = 30u;
    m.seq = seq;
    uint8_t b[64];
    return frame_of(MD_CAN_REC_DATA_FRAME_ID, b, md_can_rec_data_pack(b, &m, sizeof b));
}

static void test_sequence_errors_counted_and_resynchronised(void)
{
    boot();
    md_frame_t f = hall(0u, 254u);
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    f = hall(0u, 255u);
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    f = hall(0u, 0u); /* wraps at 256 */
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    f = hall(0u, 2u); /* 1 lost */
    TEST_ASSERT_EQUAL_INT(MD_E_FRAME, rx(&f));
    TEST_ASSERT_EQUAL_UINT32(1u, g_node.counters.rx_bad_sequence);
    f = hall(0u, 3u); /* stream continues */
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    f = hall(1u, 77u); /* per electrode: another electrode starts anywhere */
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    f = rec(2u, 0u);
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    f = rec(2u, 1u);
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    TEST_ASSERT_EQUAL_UINT32(60u, g_node.electrode[2].rec_samples);
    f = rec(2u, 1u); /* duplicate */
    snapshot();
    TEST_ASSERT_EQUAL_INT(MD_E_FRAME, rx(&f));
    TEST_ASSERT_EQUAL_UINT32(60u, g_node.electrode[2].rec_samples);
    TEST_ASSERT_EQUAL_UINT32(2u, g_node.counters.rx_bad_sequence);
    const struct md_can_rec_end_t end = {2u, MD_REC_COMPLETE, 0u, 60u};
    uint8_t b[8];
    f = frame_of(MD_CAN_REC_END_FRAME_ID, b, md_can_rec_end_pack(b, &end, sizeof b));
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
    f = rec(2u, 0u); /* next interval restarts at 0 */
    TEST_ASSERT_EQUAL_INT(MD_OK, rx(&f));
}

static void test_own_ids_from_others_are_conflicts(void)
{
    boot();
    uint8_t b[8] = {0};
    const md_frame_t f = frame_of(MD_CAN_ACT_CMD_FRAME_ID, b, 8);
    expect_rejected(&f);
    const md_frame_t hb = frame_of(MD_CAN_HEARTBEAT_CTRL_FRAME_ID, b, 8);
    expect_rejected(&hb);
    const md_frame_t step = frame_of(MD_CAN_SIM_ADVANCE_FRAME_ID, b, 8);
    expect_rejected(&step);
    TEST_ASSERT_EQUAL_UINT32(3u, g_node.counters.rx_id_conflict);
}

static void test_protocol_emcy_is_inhibited(void)
{
    boot();
    const md_frame_t bad = frame_of(0x123u, (const uint8_t *)"\x01", 1);
    const size_t from = g_n_sent;
    for (uint32_t i = 0u; i < 50u; ++i) {
        (void)rx(&bad);
        g_now += 10u * MS;
    }
    /* 500 ms of garbage, inhibit 1000 ms: one EMCY; every frame counted */
    TEST_ASSERT_EQUAL_size_t(1u, count_id(MD_CAN_EMCY_CTRL_FRAME_ID, from));
    TEST_ASSERT_EQUAL_UINT16(MD_EMCY_PROTOCOL, decode_emcy(last_of(MD_CAN_EMCY_CTRL_FRAME_ID)).error_code);
    TEST_ASSERT_EQUAL_UINT32(0x123u, decode_emcy(last_of(MD_CAN_EMCY_CTRL_FRAME_ID)).info);
    TEST_ASSERT_EQUAL_UINT32(50u, g_node.counters.rx_unknown_id);
    g_now += 600u * MS;
    (void)rx(&bad);
    TEST_ASSERT_EQUAL_size_t(2u, count_id(MD_CAN_EMCY_CTRL_FRAME_ID, from));
}

/* Random frames (known ids with random lengths/flags/bytes, and random ids):
 * nothing crashes (run under ASan/UBSan in the dev-asan preset), every frame
 * is counted exactly once, and only ESTOP/NMT/PARAM_REQ may change the state
 * (they are left out of the state check by design). */
static void test_random_frames_never_crash(void)
{
    static const uint16_t IDS[] = {0x020u, 0x021u, 0x081u, 0x082u, 0x085u, 0x210u, 0x290u, 0x300u, 0x310u, 0x400u,
                                   0x410u, 0x420u, 0x500u, 0x581u, 0x702u, 0x703u, 0x704u, 0x705u, 0x123u, 0x7FFu};
    boot();
    uint32_t x = 0x12345678u; /* xorshift32: deterministic */
    uint32_t rejected = 0u;
    uint32_t accepted = 0u;
    for (uint32_t i = 0u; i < 3000u; ++i) {
        md_frame_t f;
        memset(&f, 0, sizeof f);
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        f.id = ((x & 1u) != 0u) ? IDS[(x >> 1) % (sizeof IDS / sizeof IDS[0])] : ((x >> 8) & 0x7FFu);
        f.len = (uint8_t)((x >> 20) % 66u); /* includes invalid lengths */
        f.flags = (uint8_t)((x >> 28) & 0x7u);
        for (size_t k = 0u; k < MD_FRAME_MAX_DATA; ++k) {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            f.data[k] = (uint8_t)x;
        }
        if (f.id == MD_CAN_ESTOP_FRAME_ID || f.id == MD_CAN_NMT_FRAME_ID || f.id == MD_CAN_PARAM_REQ_CTRL_FRAME_ID) {
            f.id = 0x123u;
        }
        snapshot();
        const md_status_t st = rx(&f);
        if (st == MD_OK) {
            accepted++;
        } else {
            TEST_ASSERT_EQUAL_INT(MD_E_FRAME, st);
            rejected++;
            assert_unchanged_except_counters();
        }
    }
    const md_node_counters_t *c = &g_node.counters;
    TEST_ASSERT_EQUAL_UINT32(3000u, c->rx_frames);
    TEST_ASSERT_EQUAL_UINT32(rejected, c->rx_malformed + c->rx_unknown_id + c->rx_bad_sequence + c->rx_id_conflict);
    TEST_ASSERT_GREATER_THAN_UINT(0u, accepted); /* the generator reaches the handlers */
    TEST_ASSERT_FALSE(g_node.estop_latched);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_PREOP, g_node.state);
}

/* ---- platform failures -------------------------------------------------- */

static void test_send_failures_counted_and_halts_retried(void)
{
    boot();
    (void)nmt(MD_NMT_START, 0u);
    g_fail_send = true;
    (void)estop(MD_NODE_OPER);
    TEST_ASSERT_TRUE(g_node.counters.tx_failures >= MD_ELECTRODES + 1u); /* halts + EMCY */
    TEST_ASSERT_EQUAL_UINT8((1u << MD_ELECTRODES) - 1u, g_node.halt_pending);
    TEST_ASSERT_EQUAL_UINT64(g_now, md_node_next_deadline_us(&g_node, g_now));
    TEST_ASSERT_EQUAL_INT(MD_E_IO, md_node_poll(&g_node, g_now));
    g_fail_send = false;
    const size_t from = g_n_sent;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_node_poll(&g_node, g_now));
    assert_halts_since(from);
    TEST_ASSERT_EQUAL_UINT8(0u, g_node.halt_pending);
}

static void test_bad_arguments(void)
{
    const md_port_t no_send = {NULL, fake_now, NULL, NULL, NULL};
    md_node_t n;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_node_init(&n, &no_send, 0u));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_node_init(NULL, &no_send, 0u));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_node_on_frame(&g_node, NULL, 0u));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_node_poll(NULL, 0u));
    boot();
    (void)nmt(MD_NMT_START, 0u);
    feed_act_heartbeats(T0_US + 200u * MS);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_node_step(&g_node, MD_ELECTRODES, MD_ACT_DIR_ADVANCE, 1u, 1u));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_node_step(&g_node, 0u, 7u, 1u, 1u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_boot_up_heartbeat_then_preop);
    RUN_TEST(test_heartbeat_period_and_content);
    RUN_TEST(test_heartbeat_period_parameter_applies);
    RUN_TEST(test_nmt_start_before_bootup_is_refused);
    RUN_TEST(test_nmt_transitions);
    RUN_TEST(test_leaving_operational_halts_every_electrode);
    RUN_TEST(test_reset_node_reboots_with_defaults);
    RUN_TEST(test_auto_start);
    RUN_TEST(test_lost_heartbeat_one_emcy_within_timeout_and_halts);
    RUN_TEST(test_node_back_lifts_inhibit);
    RUN_TEST(test_never_seen_or_unmonitored_node_is_not_lost);
    RUN_TEST(test_deadline_tracks_heartbeat_timeout);
    RUN_TEST(test_estop_latches_until_clear_even_through_reset);
    RUN_TEST(test_malformed_estop_still_latches);
    RUN_TEST(test_param_get_set_and_errors);
    RUN_TEST(test_counters_readable_as_parameters);
    RUN_TEST(test_malformed_frames_counted_and_ignored);
    RUN_TEST(test_out_of_range_signals_rejected);
    RUN_TEST(test_hall_calib_normalisation_indices);
    RUN_TEST(test_sequence_errors_counted_and_resynchronised);
    RUN_TEST(test_own_ids_from_others_are_conflicts);
    RUN_TEST(test_protocol_emcy_is_inhibited);
    RUN_TEST(test_random_frames_never_crash);
    RUN_TEST(test_send_failures_counted_and_halts_retried);
    RUN_TEST(test_bad_arguments);
    return UNITY_END();
}
