/// @file fuzz_node.c
/// Fuzz target 1: the controller node (firmware/app/md_node.h) fed arbitrary
/// frame sequences, polls, step requests and send failures on an advancing
/// fake clock. Besides ASan/UBSan it checks the node's safety promises after
/// every operation (a violation traps):
///  - e-stop: any standard-id 0 frame latches; only an accepted NMT
///    clear-e-stop (target 0 or the controller) unlatches; while latched no
///    ACT_CMD step leaves the node, the node is never operational, and at most
///    one EMCY e-stop goes out per latch; every latch halts every electrode
///    (sent, or pending for retry when the port refused);
///  - leaving operational, or a monitored node falling silent, halts every
///    electrode (sent, or pending for retry); a lost node inhibits motion;
///  - ACT_CMD Seq of each electrode goes up by one per frame sent, across resets;
///  - counters never decrease;
///  - every parameter is finite, in [min, max], integral when flagged, and
///    depth_min_um < depth_max_um;
///  - every frame sent is valid, has a DBC id the controller owns, and the
///    DBC length of that id; return codes are the documented ones.
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "fuzz_input.h"
#include "fuzz_protocol_table.h"
#include "md_can.h"
#include "md_node.h"
#include "md_node_params.h"

/* Every id of the DBC, so that most generated frames are well-formed and the
 * fuzzer spends its time in the handlers rather than in the form check. */
typedef struct {
    uint16_t id;
    uint8_t len;
    bool fd;
} known_id_t;

/* Every id of the DBC (generated list, so new messages are fuzzed too); the
 * DBC's FD frames are exactly those longer than 8 bytes. */
#define FRAME(id, len) {(uint16_t)(id), (uint8_t)(len), (len) > 8u},
static const known_id_t KNOWN[] = {FUZZ_FRAMES};
#undef FRAME
#define KNOWN_COUNT (sizeof(KNOWN) / sizeof(KNOWN[0]))

/* Ids the controller itself transmits, with their lengths. */
static const known_id_t OWN_TX[] = {
    {MD_CAN_SIM_ADVANCE_FRAME_ID, MD_CAN_SIM_ADVANCE_LENGTH, false},
    {MD_CAN_EMCY_CTRL_FRAME_ID, MD_CAN_EMCY_CTRL_LENGTH, false},
    {MD_CAN_ACT_CMD_FRAME_ID, MD_CAN_ACT_CMD_LENGTH, false},
    {MD_CAN_REC_REQ_FRAME_ID, MD_CAN_REC_REQ_LENGTH, false},
    {MD_CAN_PARAM_RESP_CTRL_FRAME_ID, MD_CAN_PARAM_RESP_CTRL_LENGTH, false},
    {MD_CAN_HEARTBEAT_CTRL_FRAME_ID, MD_CAN_HEARTBEAT_CTRL_LENGTH, false},
    {MD_CAN_TLM_STATUS_FRAME_ID, MD_CAN_TLM_STATUS_LENGTH, true},
    {MD_CAN_TLM_TRACK_FRAME_ID, MD_CAN_TLM_TRACK_LENGTH, true},
    {MD_CAN_TLM_WAVE_FRAME_ID, MD_CAN_TLM_WAVE_LENGTH, true},
    {MD_CAN_TLM_HYP_FRAME_ID, MD_CAN_TLM_HYP_LENGTH, true},
};
#define OWN_TX_COUNT (sizeof(OWN_TX) / sizeof(OWN_TX[0]))

/* What the harness knows independently of the node (the shadow model). */
typedef struct {
    bool fail_sends;  ///< the port refuses every frame while set
    bool estop;       ///< expected latch state
    uint32_t estop_emcy_in_latch;
    bool act_seq_known[MD_ELECTRODES];
    uint8_t act_seq[MD_ELECTRODES];
    uint8_t halts_sent_mask;  ///< electrodes halted since the current op began
} shadow_t;

static shadow_t g_shadow;

#define ALL_ELECTRODES ((uint8_t)((1u << MD_ELECTRODES) - 1u))

/* The reproducers in crashes/fuzz_node/ (docs/fuzzing.md, "Findings") send an
 * NMT start after init/reset-node but before the first poll: the node must
 * refuse it, or the boot-up would leave operational without halting, which the
 * halt check below catches. */
static void check_sent_frame(const md_frame_t *f)
{
    FUZZ_CHECK(md_frame_valid(f));
    FUZZ_CHECK((f->flags & MD_FRAME_FLAG_EXT) == 0u);
    bool own = false;
    for (size_t i = 0u; i < OWN_TX_COUNT; ++i) {
        if (OWN_TX[i].id == f->id) {
            FUZZ_CHECK(f->len == OWN_TX[i].len);
            own = true;
        }
    }
    FUZZ_CHECK(own);
    if (f->id == MD_CAN_ACT_CMD_FRAME_ID) {
        struct md_can_act_cmd_t m;
        FUZZ_CHECK(md_can_act_cmd_unpack(&m, f->data, f->len) == 0);
        FUZZ_CHECK(m.electrode < MD_ELECTRODES);
        FUZZ_CHECK(m.command == MD_ACT_CMD_HALT || m.command == MD_ACT_CMD_STEP);
        if (m.command == MD_ACT_CMD_STEP) {
            FUZZ_CHECK(!g_shadow.estop); /* the central safety promise */
        } else {
            g_shadow.halts_sent_mask = (uint8_t)(g_shadow.halts_sent_mask | (1u << m.electrode));
        }
    }
    if (f->id == MD_CAN_EMCY_CTRL_FRAME_ID) {
        struct md_can_emcy_ctrl_t m;
        FUZZ_CHECK(md_can_emcy_ctrl_unpack(&m, f->data, f->len) == 0);
        if (m.error_code == (uint16_t)MD_EMCY_ESTOP) {
            g_shadow.estop_emcy_in_latch++;
            FUZZ_CHECK(g_shadow.estop_emcy_in_latch <= 1u);
        }
    }
}

/* The port: checks every frame, records ACT_CMD sequence numbers, and refuses
 * frames while the fuzzer says so. A refused frame has not left the node. */
static md_status_t port_send(void *ctx, const md_frame_t *frame)
{
    (void)ctx;
    if (g_shadow.fail_sends) {
        return MD_E_IO;
    }
    check_sent_frame(frame);
    if (frame->id == MD_CAN_ACT_CMD_FRAME_ID) {
        const uint8_t e = frame->data[0];
        const uint8_t seq = frame->data[3];
        if (g_shadow.act_seq_known[e]) {
            FUZZ_CHECK(seq == (uint8_t)(g_shadow.act_seq[e] + 1u));
        }
        g_shadow.act_seq_known[e] = true;
        g_shadow.act_seq[e] = seq;
    }
    return MD_OK;
}

static uint64_t port_now(void *ctx)
{
    (void)ctx;
    return 0u; /* the node takes time as an argument; never called */
}

static void check_params(const md_node_t *node)
{
    for (size_t id = 0u; id < md_params_count(); ++id) {
        const md_param_def_t *d = md_params_def(id);
        FUZZ_CHECK(d != NULL);
        if ((d->flags & MD_PARAM_F_LIVE) != 0u) {
            continue;
        }
        const double v = node->params.value[id];
        FUZZ_CHECK(isfinite(v));
        FUZZ_CHECK(v >= d->min && v <= d->max);
        if ((d->flags & MD_PARAM_F_INTEGER) != 0u) {
            FUZZ_CHECK(!(fabs(v - floor(v)) > 0.0));
        }
    }
    FUZZ_CHECK(node->params.value[MD_P_DEPTH_MIN_UM] < node->params.value[MD_P_DEPTH_MAX_UM]);
}

static void check_counters(const md_node_counters_t *before, const md_node_counters_t *after)
{
    uint32_t b[sizeof *before / sizeof(uint32_t)];
    uint32_t a[sizeof *after / sizeof(uint32_t)];
    _Static_assert(sizeof b == sizeof(md_node_counters_t), "counters are all uint32_t");
    memcpy(b, before, sizeof b);
    memcpy(a, after, sizeof a);
    for (size_t i = 0u; i < sizeof b / sizeof b[0]; ++i) {
        FUZZ_CHECK(a[i] >= b[i]);
    }
}

static void check_node(const md_node_t *node)
{
    FUZZ_CHECK(node->estop_latched == g_shadow.estop);
    for (size_t i = 0u; i < MD_NODE_MONITORED; ++i) {
        if (node->monitor[i].lost) {
            FUZZ_CHECK(!md_node_motion_allowed(node)); /* a silent node inhibits motion */
        }
    }
    if (node->estop_latched) {
        FUZZ_CHECK(node->state != MD_NODE_STATE_OPERATIONAL);
        FUZZ_CHECK(!md_node_motion_allowed(node));
    }
    check_params(node);
}

static void put_le(uint8_t *p, uint32_t v, size_t n)
{
    for (size_t i = 0u; i < n; ++i) {
        p[i] = (uint8_t)(v >> (8u * i));
    }
}

/* A parameter value worth trying for row `row`: its bounds, just outside
 * them, its default, a fraction, or a non-finite/raw float. */
static float param_value(fz_t *in, const md_param_def_t *d)
{
    switch (fz_u8(in) % 10u) {
    case 0u: return (float)d->min;
    case 1u: return (float)d->max;
    case 2u: return (float)(d->min - 1.0);
    case 3u: return (float)(d->max + 1.0);
    case 4u: return (float)d->def;
    case 5u: return (float)(d->min + (d->max - d->min) * (double)fz_u8(in) / 255.0);
    case 6u: return (float)(d->min + 0.5);
    case 7u: return NAN;
    case 8u: return ((fz_u8(in) & 1u) != 0u) ? INFINITY : -INFINITY;
    default: {
        const uint32_t bits = fz_u32(in);
        float v;
        memcpy(&v, &bits, sizeof v);
        return v;
    }
    }
}

/* Payloads that get past the range checks of the frames that change state
 * (NMT, parameter requests, heartbeats); the random bytes rarely would. */
static void smart_payload(fz_t *in, md_frame_t *f)
{
    static const uint8_t NMT_CMDS[] = {MD_NMT_START,      MD_NMT_STOP,        MD_NMT_PREOP,
                                       MD_NMT_RESET_NODE, MD_NMT_CLEAR_ESTOP, 7u};
    static const uint8_t STATES[] = {MD_NODE_STATE_BOOT, MD_NODE_STATE_STOPPED, MD_NODE_STATE_OPERATIONAL,
                                     MD_NODE_STATE_PREOP, 9u};
    if (f->id == MD_CAN_NMT_FRAME_ID) {
        f->data[0] = NMT_CMDS[fz_u8(in) % sizeof NMT_CMDS];
        f->data[1] = (uint8_t)(fz_u8(in) % 4u); /* all, controller, actuator, sensor */
    } else if (f->id == MD_CAN_PARAM_REQ_CTRL_FRAME_ID) {
        const uint8_t op = fz_u8(in);
        const size_t row = fz_u8(in) % (md_params_count() + 1u);
        const md_param_def_t *d = md_params_def(row < md_params_count() ? row : 0u);
        f->data[0] = (uint8_t)(((op & 3u) == 0u) ? MD_PARAM_OP_GET : MD_PARAM_OP_SET);
        put_le(&f->data[2], (row < md_params_count()) ? d->index : fz_u16(in), 2u);
        const float v = param_value(in, d);
        uint32_t bits;
        memcpy(&bits, &v, sizeof bits);
        put_le(&f->data[4], bits, 4u);
    } else if (f->id >= MD_CAN_HEARTBEAT_ACT_FRAME_ID && f->id <= MD_CAN_HEARTBEAT_OPER_FRAME_ID) {
        f->data[0] = STATES[fz_u8(in) % sizeof STATES];
        f->data[1] = (uint8_t)MD_PROTOCOL_VERSION;
    }
}

/* Builds one frame from the input: mostly a known id with its DBC length and
 * FD flag (payload from the input), sometimes anything at all. */
static void make_frame(fz_t *in, md_frame_t *f)
{
    memset(f, 0, sizeof *f);
    const uint8_t shape = fz_u8(in);
    const known_id_t *k = &KNOWN[fz_u8(in) % KNOWN_COUNT];
    if (shape < 200u) {
        f->id = k->id;
        f->len = k->len;
        f->flags = k->fd ? MD_FRAME_FLAG_FD : 0u;
    } else if (shape < 230u) {
        f->id = k->id; /* known id, any length and flags */
        f->len = fz_u8(in);
        f->flags = fz_u8(in);
    } else {
        f->id = fz_u32(in);
        f->len = fz_u8(in);
        f->flags = fz_u8(in);
    }
    fz_bytes(in, f->data, (f->len < MD_FRAME_MAX_DATA) ? f->len : MD_FRAME_MAX_DATA);
    if (shape < 120u) {
        smart_payload(in, f);
    }
}

static bool is_estop_frame(const md_frame_t *f)
{
    return f->id == MD_CAN_ESTOP_FRAME_ID && (f->flags & MD_FRAME_FLAG_EXT) == 0u;
}

static bool is_accepted_clear(const md_frame_t *f, md_status_t st)
{
    return st == MD_OK && f->id == MD_CAN_NMT_FRAME_ID && (f->flags & MD_FRAME_FLAG_EXT) == 0u &&
           f->data[0] == (uint8_t)MD_NMT_CLEAR_ESTOP && (f->data[1] == 0u || f->data[1] == (uint8_t)MD_NODE_CTRL);
}

static void op_frame(md_node_t *node, fz_t *in, uint64_t now_us)
{
    md_frame_t f;
    make_frame(in, &f);
    const md_frame_t copy = f;
    const bool estop = is_estop_frame(&f);
    if (estop && !g_shadow.estop) {
        g_shadow.estop_emcy_in_latch = 0u;
    }
    if (estop) {
        g_shadow.estop = true; /* set before the call: the halt and EMCY go out inside it */
    }
    const md_status_t st = md_node_on_frame(node, &f, now_us);
    FUZZ_CHECK(st == MD_OK || st == MD_E_FRAME);
    FUZZ_CHECK(memcmp(&f, &copy, sizeof f) == 0); /* input is const in spirit: never modified */
    if (estop) {
        /* Every electrode halted now, or queued for poll to retry. */
        FUZZ_CHECK((uint8_t)(g_shadow.halts_sent_mask | node->halt_pending) == ALL_ELECTRODES);
    }
    if (is_accepted_clear(&f, st)) {
        g_shadow.estop = false;
    }
}

static void op_step(md_node_t *node, fz_t *in)
{
    const uint8_t e = fz_u8(in);
    const uint8_t dir = fz_u8(in);
    const uint16_t steps = fz_u16(in);
    const uint16_t rate = fz_u16(in);
    const bool allowed = md_node_motion_allowed(node);
    const md_status_t st = md_node_step(node, (uint8_t)(e % 4u), (uint8_t)(dir % 3u), steps, rate);
    FUZZ_CHECK(st == MD_OK || st == MD_E_STATE || st == MD_E_ARG || st == MD_E_IO);
    if (st == MD_OK) {
        FUZZ_CHECK(allowed && !g_shadow.estop);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_t in;
    fz_init(&in, data, size);
    memset(&g_shadow, 0, sizeof g_shadow);
    const md_port_t port = {port_send, port_now, NULL, NULL, NULL};
    static md_node_t node;
    uint64_t now_us = fz_u32(&in);
    FUZZ_CHECK(md_node_init(&node, &port, now_us) == MD_OK);
    check_node(&node);
    for (size_t ops = 0u; ops < 256u && fz_left(&in) > 0u; ++ops) {
        const md_node_counters_t before = node.counters;
        const bool was_operational = node.state == MD_NODE_STATE_OPERATIONAL;
        const uint32_t lost_before = node.counters.heartbeat_lost;
        g_shadow.halts_sent_mask = 0u;
        const uint8_t op = fz_u8(&in);
        switch (op & 7u) {
        case 0u:
        case 1u:
        case 2u:
        case 3u: op_frame(&node, &in, now_us); break;
        case 4u: {
            /* Advance the clock: short steps mostly, sometimes past every timeout. */
            const uint32_t dt = fz_u16(&in);
            now_us += ((op & 0x80u) != 0u) ? (uint64_t)dt * 1000u : dt;
            const md_status_t st = md_node_poll(&node, now_us);
            FUZZ_CHECK(st == MD_OK || st == MD_E_IO);
            FUZZ_CHECK(md_node_next_deadline_us(&node, now_us) >= now_us); /* nothing overdue after a poll */
            break;
        }
        case 5u: op_step(&node, &in); break;
        case 6u: g_shadow.fail_sends = !g_shadow.fail_sends; break;
        default: {
            const uint8_t pid = fz_u8(&in);
            const double v = md_node_param_read(&node, (md_param_id_t)(pid % (MD_P_COUNT + 2u)), now_us);
            FUZZ_CHECK(isfinite(v));
            (void)md_node_heartbeat_flags(&node);
            break;
        }
        }
        check_counters(&before, &node.counters);
        if ((was_operational && node.state != MD_NODE_STATE_OPERATIONAL) ||
            node.counters.heartbeat_lost != lost_before) {
            /* Leaving operational or losing a node halts every electrode (sent or queued). */
            FUZZ_CHECK((uint8_t)(g_shadow.halts_sent_mask | node.halt_pending) == ALL_ELECTRODES);
        }
        check_node(&node);
    }
    return 0;
}
