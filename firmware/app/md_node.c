/// @file md_node.c
/// The controller node: NMT, heartbeat, e-stop, EMCY, frame validation (the
/// parameter service is md_node_params.c). See md_node.h for the contract and docs/protocol.md for the
/// behaviour on the bus.
#include "md_node.h"

#include <math.h>
#include <string.h>
#include <stddef.h>

#include "md_can.h"
#include "md_node_params.h"

#define US_PER_MS 1000u
#define US_PER_S 1000000u

/* ------------------------------------------------------------------ */
/* Receive rules: what the controller accepts, and from whom.          */
/* ------------------------------------------------------------------ */

typedef enum {
    RX_CONSUME = 0,  ///< addressed to (or useful for) the controller
    RX_OWN = 1       ///< an id only the controller transmits: receiving it is an id conflict
} rx_role_t;

typedef struct {
    uint16_t id;
    uint8_t len;
    bool fd;
    rx_role_t role;
} rx_rule_t;

/* Every id of microdrive.dbc. Length and FD flag (VFrameFormat 14) are the
 * DBC's; a frame of a known id with any other length or flag is malformed. */
static const rx_rule_t RX_RULES[] = {
    {MD_CAN_ESTOP_FRAME_ID, MD_CAN_ESTOP_LENGTH, false, RX_CONSUME},
    {MD_CAN_NMT_FRAME_ID, MD_CAN_NMT_LENGTH, false, RX_CONSUME},
    {MD_CAN_SIM_CLOCK_FRAME_ID, MD_CAN_SIM_CLOCK_LENGTH, false, RX_CONSUME},
    {MD_CAN_SIM_ADVANCE_FRAME_ID, MD_CAN_SIM_ADVANCE_LENGTH, false, RX_OWN},
    {MD_CAN_EMCY_CTRL_FRAME_ID, MD_CAN_EMCY_CTRL_LENGTH, false, RX_OWN},
    {MD_CAN_EMCY_ACT_FRAME_ID, MD_CAN_EMCY_ACT_LENGTH, false, RX_CONSUME},
    {MD_CAN_EMCY_HALL_FRAME_ID, MD_CAN_EMCY_HALL_LENGTH, false, RX_CONSUME},
    {MD_CAN_EMCY_FE_FRAME_ID, MD_CAN_EMCY_FE_LENGTH, false, RX_CONSUME},
    {MD_CAN_EMCY_OPER_FRAME_ID, MD_CAN_EMCY_OPER_LENGTH, false, RX_CONSUME},
    {MD_CAN_ACT_CMD_FRAME_ID, MD_CAN_ACT_CMD_LENGTH, false, RX_OWN},
    {MD_CAN_REC_REQ_FRAME_ID, MD_CAN_REC_REQ_LENGTH, false, RX_OWN},
    {MD_CAN_ACT_STATUS_FRAME_ID, MD_CAN_ACT_STATUS_LENGTH, false, RX_CONSUME},
    {MD_CAN_HALL_READING_FRAME_ID, MD_CAN_HALL_READING_LENGTH, false, RX_CONSUME},
    {MD_CAN_HALL_CALIB_FRAME_ID, MD_CAN_HALL_CALIB_LENGTH, false, RX_CONSUME},
    {MD_CAN_REC_DATA_FRAME_ID, MD_CAN_REC_DATA_LENGTH, true, RX_CONSUME},
    {MD_CAN_REC_END_FRAME_ID, MD_CAN_REC_END_LENGTH, false, RX_CONSUME},
    {MD_CAN_FE_INFO_FRAME_ID, MD_CAN_FE_INFO_LENGTH, true, RX_CONSUME},
    {MD_CAN_TLM_STATUS_FRAME_ID, MD_CAN_TLM_STATUS_LENGTH, true, RX_OWN},
    {MD_CAN_TLM_CYCLE_FRAME_ID, MD_CAN_TLM_CYCLE_LENGTH, true, RX_OWN},
    {MD_CAN_TLM_SPIKES_FRAME_ID, MD_CAN_TLM_SPIKES_LENGTH, true, RX_OWN},
    {MD_CAN_TLM_TRACK_FRAME_ID, MD_CAN_TLM_TRACK_LENGTH, true, RX_OWN},
    {MD_CAN_TLM_WAVE_FRAME_ID, MD_CAN_TLM_WAVE_LENGTH, true, RX_OWN},
    {MD_CAN_TLM_HYP_FRAME_ID, MD_CAN_TLM_HYP_LENGTH, true, RX_OWN},
    {MD_CAN_PARAM_RESP_CTRL_FRAME_ID, MD_CAN_PARAM_RESP_CTRL_LENGTH, false, RX_OWN},
    {MD_CAN_PARAM_REQ_CTRL_FRAME_ID, MD_CAN_PARAM_REQ_CTRL_LENGTH, false, RX_CONSUME},
    {MD_CAN_HEARTBEAT_CTRL_FRAME_ID, MD_CAN_HEARTBEAT_CTRL_LENGTH, false, RX_OWN},
    {MD_CAN_HEARTBEAT_ACT_FRAME_ID, MD_CAN_HEARTBEAT_ACT_LENGTH, false, RX_CONSUME},
    {MD_CAN_HEARTBEAT_HALL_FRAME_ID, MD_CAN_HEARTBEAT_HALL_LENGTH, false, RX_CONSUME},
    {MD_CAN_HEARTBEAT_FE_FRAME_ID, MD_CAN_HEARTBEAT_FE_LENGTH, false, RX_CONSUME},
    {MD_CAN_HEARTBEAT_OPER_FRAME_ID, MD_CAN_HEARTBEAT_OPER_LENGTH, false, RX_CONSUME},
};
#define RX_RULE_COUNT (sizeof(RX_RULES) / sizeof(RX_RULES[0]))

/// Outcome of a frame handler.
typedef enum { RX_OK = 0, RX_BAD_RANGE, RX_BAD_SEQ } rx_result_t;

static const rx_rule_t *find_rule(uint32_t id)
{
    for (size_t i = 0u; i < RX_RULE_COUNT; ++i) {
        if (RX_RULES[i].id == id) {
            return &RX_RULES[i];
        }
    }
    return NULL;
}

/* ------------------------------------------------------------------ */
/* Sending                                                             */
/* ------------------------------------------------------------------ */

static md_status_t send_frame_flags(md_node_t *node, uint32_t id, const uint8_t *data, int len, uint8_t flags)
{
    if (len <= 0 || len > (int)MD_FRAME_MAX_DATA) {
        return MD_E_ARG; /* a pack function failed: cannot happen with the generated sizes */
    }
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = (uint8_t)len;
    f.flags = flags;
    memcpy(f.data, data, (size_t)len);
    const md_status_t st = node->port.send(node->port.ctx, &f);
    if (st != MD_OK) {
        node->counters.tx_failures++;
        return MD_E_IO;
    }
    node->counters.tx_frames++;
    return MD_OK;
}

static md_status_t send_frame(md_node_t *node, uint32_t id, const uint8_t *data, int len)
{
    return send_frame_flags(node, id, data, len, 0u);
}

md_status_t md_node_send(md_node_t *node, uint32_t id, const uint8_t *data, int len, bool fd)
{
    if (node == NULL || data == NULL) {
        return MD_E_ARG;
    }
    return send_frame_flags(node, id, data, len, fd ? (uint8_t)MD_FRAME_FLAG_FD : 0u);
}

static bool any_lost(const md_node_t *node)
{
    for (size_t i = 0u; i < MD_NODE_MONITORED; ++i) {
        if (node->monitor[i].lost) {
            return true;
        }
    }
    return false;
}

static uint8_t error_register(const md_node_t *node, bool communication)
{
    uint8_t reg = 0u;
    if (any_lost(node) || communication) {
        reg |= MD_NODE_ERREG_COMMUNICATION;
    }
    if (node->estop_latched) {
        reg |= MD_NODE_ERREG_MANUFACTURER;
    }
    if (reg != 0u) {
        reg |= MD_NODE_ERREG_GENERIC;
    }
    return reg;
}

/* CANopen EMCY layout: error code, error register, then manufacturer bytes
 * (here: electrode and a 32-bit info word), as the DBC defines EMCY_CTRL. */
static md_status_t send_emcy(md_node_t *node, md_emcy_code_t code, uint8_t electrode, uint32_t info)
{
    struct md_can_emcy_ctrl_t m;
    uint8_t buf[MD_CAN_EMCY_CTRL_LENGTH];
    (void)md_can_emcy_ctrl_init(&m);
    m.error_code = (uint16_t)code;
    m.error_register = error_register(node, code == MD_EMCY_PROTOCOL);
    m.electrode = electrode;
    m.info = info;
    const md_status_t st = send_frame(node, MD_CAN_EMCY_CTRL_FRAME_ID, buf, md_can_emcy_ctrl_pack(buf, &m, sizeof buf));
    if (st == MD_OK) {
        node->counters.emcy_sent++;
    }
    return st;
}

md_status_t md_node_emcy(md_node_t *node, md_emcy_code_t code, uint8_t electrode, uint32_t info)
{
    return (node == NULL) ? MD_E_ARG : send_emcy(node, code, electrode, info);
}

/* Protocol errors can come in floods; their EMCY is inhibited for
 * emcy_inhibit_ms after the last one (CANopen 0x1015). Counters see every one. */
static void protocol_emcy(md_node_t *node, uint32_t frame_id, uint64_t now_us)
{
    const uint64_t inhibit_us = (uint64_t)md_params_get_u32(&node->params, MD_P_EMCY_INHIBIT_MS) * US_PER_MS;
    if (node->protocol_emcy_sent && now_us - node->protocol_emcy_us < inhibit_us) {
        return;
    }
    if (send_emcy(node, MD_EMCY_PROTOCOL, MD_NODE_EMCY_NO_ELECTRODE, frame_id) == MD_OK) {
        node->protocol_emcy_sent = true;
        node->protocol_emcy_us = now_us;
    }
}

static md_status_t send_act_cmd(md_node_t *node, uint8_t e, uint8_t command, uint8_t direction, uint16_t steps,
                                uint16_t rate_hz)
{
    struct md_can_act_cmd_t m;
    uint8_t buf[MD_CAN_ACT_CMD_LENGTH];
    (void)md_can_act_cmd_init(&m);
    m.electrode = e;
    m.command = command;
    m.direction = direction;
    m.seq = (uint8_t)(node->electrode[e].act_seq + 1u);
    m.step_count = steps;
    m.step_rate_hz = rate_hz;
    const md_status_t st = send_frame(node, MD_CAN_ACT_CMD_FRAME_ID, buf, md_can_act_cmd_pack(buf, &m, sizeof buf));
    if (st == MD_OK) {
        node->electrode[e].act_seq = m.seq;
    }
    return st;
}

/* Halt every electrode now; an electrode whose halt could not be sent stays
 * in halt_pending and poll retries it. */
static md_status_t halt_all(md_node_t *node)
{
    node->halt_pending = (uint8_t)((1u << MD_ELECTRODES) - 1u);
    md_status_t result = MD_OK;
    for (uint8_t e = 0u; e < (uint8_t)MD_ELECTRODES; ++e) {
        if (send_act_cmd(node, e, MD_ACT_CMD_HALT, MD_ACT_DIR_ADVANCE, 0u, 0u) == MD_OK) {
            node->halt_pending &= (uint8_t) ~(1u << e);
        } else {
            result = MD_E_IO;
        }
    }
    return result;
}

static md_status_t retry_halts(md_node_t *node)
{
    md_status_t result = MD_OK;
    for (uint8_t e = 0u; e < (uint8_t)MD_ELECTRODES; ++e) {
        if ((node->halt_pending & (1u << e)) == 0u) {
            continue;
        }
        if (send_act_cmd(node, e, MD_ACT_CMD_HALT, MD_ACT_DIR_ADVANCE, 0u, 0u) == MD_OK) {
            node->halt_pending &= (uint8_t) ~(1u << e);
        } else {
            result = MD_E_IO;
        }
    }
    return result;
}

static md_status_t send_heartbeat(md_node_t *node, uint64_t now_us)
{
    struct md_can_heartbeat_ctrl_t m;
    uint8_t buf[MD_CAN_HEARTBEAT_CTRL_LENGTH];
    (void)md_can_heartbeat_ctrl_init(&m);
    m.node_state = (uint8_t)node->state;
    m.protocol_version = (uint8_t)MD_PROTOCOL_VERSION;
    m.flags = md_node_heartbeat_flags(node);
    m.electrodes = (uint8_t)MD_ELECTRODES;
    m.uptime_s = (uint32_t)((now_us - node->boot_us) / US_PER_S);
    return send_frame(node, MD_CAN_HEARTBEAT_CTRL_FRAME_ID, buf, md_can_heartbeat_ctrl_pack(buf, &m, sizeof buf));
}

/* ------------------------------------------------------------------ */
/* State                                                               */
/* ------------------------------------------------------------------ */

static void forget_monitor(md_node_monitor_t *m)
{
    m->seen = false;
    m->lost = false;
    m->last_state = (uint8_t)MD_NODE_STATE_BOOT;
    m->last_us = 0u;
}

/* Application state back to power-on values; the e-stop latch, the counters
 * and the uptime origin survive (see md_node.h). */
static void reset_application(md_node_t *node)
{
    (void)md_params_init(&node->params);
    static const uint8_t MONITORED_IDS[MD_NODE_MONITORED] = {MD_NODE_ACT, MD_NODE_HALL, MD_NODE_FE};
    for (size_t i = 0u; i < MD_NODE_MONITORED; ++i) {
        forget_monitor(&node->monitor[i]);
        node->monitor[i].node_id = MONITORED_IDS[i];
    }
    for (size_t e = 0u; e < MD_ELECTRODES; ++e) {
        const uint8_t act_seq = node->electrode[e].act_seq; /* keep ACT_CMD Seq monotonic across resets */
        memset(&node->electrode[e], 0, sizeof node->electrode[e]);
        node->electrode[e].act_seq = act_seq;
    }
    node->state = MD_NODE_STATE_BOOT;
    node->boot_pending = true;
    node->protocol_emcy_sent = false;
}

md_status_t md_node_init(md_node_t *node, const md_port_t *port, uint64_t now_us)
{
    if (node == NULL || port == NULL || port->send == NULL) {
        return MD_E_ARG;
    }
    memset(node, 0, sizeof *node);
    node->port = *port;
    node->boot_us = now_us;
    reset_application(node);
    return md_params_table_check();
}

static void enter_state(md_node_t *node, md_node_state_t next)
{
    /* Leaving operational stops motion: only operational may move. */
    if (node->state == MD_NODE_STATE_OPERATIONAL && next != MD_NODE_STATE_OPERATIONAL) {
        (void)halt_all(node);
    }
    node->state = next;
}

static md_status_t do_boot(md_node_t *node, uint64_t now_us)
{
    node->boot_pending = false;
    /* CANopen boot-up: one heartbeat with state 0, then pre-operational. */
    const md_status_t st = send_heartbeat(node, now_us);
    const bool auto_start = md_params_get_u32(&node->params, MD_P_AUTO_START) != 0u;
    enter_state(node, (auto_start && !node->estop_latched) ? MD_NODE_STATE_OPERATIONAL : MD_NODE_STATE_PREOP);
    node->next_heartbeat_us = now_us + (uint64_t)md_params_get_u32(&node->params, MD_P_HEARTBEAT_PERIOD_MS) * US_PER_MS;
    return st;
}

static void latch_estop(md_node_t *node, uint8_t source, uint8_t reason)
{
    node->counters.estop_events++;
    const bool was_latched = node->estop_latched;
    node->estop_latched = true;
    node->estop_source = source;
    node->estop_reason = reason;
    if (node->state != MD_NODE_STATE_BOOT) {
        node->state = MD_NODE_STATE_PREOP;
    }
    /* Halt on every ESTOP frame, latched or not (cheap, and the actuator may
     * have missed the first); the EMCY goes out once per latch. */
    (void)halt_all(node);
    if (!was_latched) {
        (void)send_emcy(node, MD_EMCY_ESTOP, MD_NODE_EMCY_NO_ELECTRODE, source);
    }
}

static void apply_nmt(md_node_t *node, uint8_t command)
{
    /* Until its boot-up heartbeat is out (first poll) the node is initialising
     * and, as in CANopen, takes no state command: a start applied now would be
     * overwritten by do_boot without a halt (found by fuzz_node). Reset and
     * clear-e-stop stay valid. */
    const bool state_command = command == (uint8_t)MD_NMT_START || command == (uint8_t)MD_NMT_STOP ||
                               command == (uint8_t)MD_NMT_PREOP;
    if (node->boot_pending && state_command) {
        node->counters.nmt_refused++;
        return;
    }
    switch ((md_nmt_command_t)command) {
    case MD_NMT_START:
        if (node->estop_latched) {
            node->counters.nmt_refused++;
        } else {
            enter_state(node, MD_NODE_STATE_OPERATIONAL);
        }
        break;
    case MD_NMT_STOP: enter_state(node, MD_NODE_STATE_STOPPED); break;
    case MD_NMT_PREOP: enter_state(node, MD_NODE_STATE_PREOP); break;
    case MD_NMT_RESET_NODE:
        enter_state(node, MD_NODE_STATE_BOOT);
        reset_application(node);
        break;
    case MD_NMT_CLEAR_ESTOP:
        /* Unlatches only; the node stays where it is (pre-operational after
         * an e-stop), so motion needs an explicit NMT start. */
        node->estop_latched = false;
        break;
    default: break; /* unreachable: handle_nmt validated the command */
    }
}

/* ------------------------------------------------------------------ */
/* Frame handlers: unpack, check ranges and sequence, then act.        */
/* A handler returns before changing anything when a check fails.      */
/* ------------------------------------------------------------------ */

static rx_result_t handle_estop(md_node_t *node, const md_frame_t *f)
{
    struct md_can_estop_t m;
    if (md_can_estop_unpack(&m, f->data, f->len) != 0 || !md_can_estop_estop_source_is_in_range(m.estop_source) ||
        !md_can_estop_estop_reason_is_in_range(m.estop_reason)) {
        return RX_BAD_RANGE;
    }
    latch_estop(node, m.estop_source, m.estop_reason);
    return RX_OK;
}

static bool nmt_command_known(uint8_t c)
{
    return c == (uint8_t)MD_NMT_START || c == (uint8_t)MD_NMT_STOP || c == (uint8_t)MD_NMT_PREOP ||
           c == (uint8_t)MD_NMT_RESET_NODE || c == (uint8_t)MD_NMT_CLEAR_ESTOP;
}

static rx_result_t handle_nmt(md_node_t *node, const md_frame_t *f)
{
    struct md_can_nmt_t m;
    if (md_can_nmt_unpack(&m, f->data, f->len) != 0 || !md_can_nmt_nmt_command_is_in_range(m.nmt_command) ||
        !md_can_nmt_nmt_target_is_in_range(m.nmt_target) || !nmt_command_known(m.nmt_command)) {
        return RX_BAD_RANGE;
    }
    if (m.nmt_target == 0u || m.nmt_target == (uint8_t)MD_NODE_CTRL) {
        apply_nmt(node, m.nmt_command);
    }
    return RX_OK; /* valid NMT for another node: accepted, nothing to do */
}

static rx_result_t handle_sim_clock(md_node_t *node, const md_frame_t *f)
{
    struct md_can_sim_clock_t m;
    if (md_can_sim_clock_unpack(&m, f->data, f->len) != 0 || !md_can_sim_clock_sim_time_us_is_in_range(m.sim_time_us)) {
        return RX_BAD_RANGE;
    }
    node->sim_time_us = m.sim_time_us;
    return RX_OK;
}

/* The remote EMCYs share one layout; EMCY_ACT's generated code decodes all four. */
static rx_result_t handle_remote_emcy(const md_frame_t *f)
{
    struct md_can_emcy_act_t m;
    if (md_can_emcy_act_unpack(&m, f->data, f->len) != 0 || !md_can_emcy_act_error_code_is_in_range(m.error_code) ||
        !md_can_emcy_act_info_is_in_range(m.info)) {
        return RX_BAD_RANGE;
    }
    return RX_OK; /* for the operator; the controller reacts to heartbeats and status frames */
}

static rx_result_t handle_act_status(md_node_t *node, const md_frame_t *f)
{
    struct md_can_act_status_t m;
    if (md_can_act_status_unpack(&m, f->data, f->len) != 0 || m.electrode >= MD_ELECTRODES ||
        m.state > (uint8_t)MD_ACT_FAULT || m.end_stops > 3u ||
        !md_can_act_status_steps_done_is_in_range(m.steps_done) ||
        !md_can_act_status_steps_remaining_is_in_range(m.steps_remaining)) {
        return RX_BAD_RANGE;
    }
    node->electrode[m.electrode].act_state = m.state;
    return RX_OK;
}

static rx_result_t handle_hall_reading(md_node_t *node, const md_frame_t *f)
{
    struct md_can_hall_reading_t m;
    if (md_can_hall_reading_unpack(&m, f->data, f->len) != 0 || m.electrode >= MD_ELECTRODES ||
        !md_can_hall_reading_raw_code_is_in_range(m.raw_code) || !md_can_hall_reading_seq_is_in_range(m.seq)) {
        return RX_BAD_RANGE;
    }
    md_node_electrode_t *el = &node->electrode[m.electrode];
    const bool in_sequence = !el->hall_seen || m.seq == (uint8_t)(el->hall_seq + 1u); /* Seq wraps at 256 */
    if (!in_sequence) {
        /* Loss, duplicate or reordering: drop this reading but resynchronise,
         * so the stream is accepted again from its next frame. */
        el->hall_seq = m.seq;
        return RX_BAD_SEQ;
    }
    el->hall_seen = true;
    el->hall_seq = m.seq;
    el->hall_code = m.raw_code;
    return RX_OK;
}

/* Coefficients act on the normalised code x = (code - code_mid) / code_half;
 * two extra indices carry code_mid and code_half (DBC comment on HALL_CALIB). */
static rx_result_t handle_hall_calib(const md_frame_t *f)
{
    struct md_can_hall_calib_t m;
    if (md_can_hall_calib_unpack(&m, f->data, f->len) != 0 || m.electrode >= MD_ELECTRODES ||
        !md_can_hall_calib_coeff_value_is_in_range(m.coeff_value)) {
        return RX_BAD_RANGE; /* is_in_range also rejects NaN and inf */
    }
    const bool coeff = m.coeff_index < m.coeff_count;
    const bool mid = m.coeff_index == MD_HALL_CALIB_INDEX_CODE_MID;
    const bool half = m.coeff_index == MD_HALL_CALIB_INDEX_CODE_HALF && m.coeff_value > 0.0f;
    if (!coeff && !mid && !half) {
        return RX_BAD_RANGE;
    }
    return RX_OK; /* stored by the position servo once it exists */
}

static rx_result_t handle_rec_data(md_node_t *node, const md_frame_t *f)
{
    struct md_can_rec_data_t m;
    if (md_can_rec_data_unpack(&m, f->data, f->len) != 0 || m.electrode >= MD_ELECTRODES ||
        !md_can_rec_data_sample_count_is_in_range(m.sample_count) || !md_can_rec_data_seq_is_in_range(m.seq)) {
        return RX_BAD_RANGE;
    }
    md_node_electrode_t *el = &node->electrode[m.electrode];
    if (m.seq != el->rec_next_seq) {
        el->rec_next_seq = (uint16_t)(m.seq + 1u); /* resynchronise on the next frame */
        return RX_BAD_SEQ;
    }
    el->rec_next_seq = (uint16_t)(m.seq + 1u);
    el->rec_samples += m.sample_count;
    return RX_OK;
}

static rx_result_t handle_rec_end(md_node_t *node, const md_frame_t *f)
{
    struct md_can_rec_end_t m;
    if (md_can_rec_end_unpack(&m, f->data, f->len) != 0 || m.electrode >= MD_ELECTRODES || m.status > MD_REC_OVERFLOW) {
        return RX_BAD_RANGE;
    }
    /* Seq counts frames of one interval from 0 (DBC comment on REC_DATA). */
    node->electrode[m.electrode].rec_next_seq = 0u;
    node->electrode[m.electrode].rec_samples = 0u;
    return RX_OK;
}

static rx_result_t handle_fe_info(const md_frame_t *f)
{
    struct md_can_fe_info_t m;
    if (md_can_fe_info_unpack(&m, f->data, f->len) != 0 || m.electrode >= MD_ELECTRODES ||
        !md_can_fe_info_gain_u_v_per_lsb_is_in_range(m.gain_u_v_per_lsb)) {
        return RX_BAD_RANGE;
    }
    return RX_OK;
}

static bool node_state_known(uint8_t s)
{
    return s == (uint8_t)MD_NODE_STATE_BOOT || s == (uint8_t)MD_NODE_STATE_STOPPED ||
           s == (uint8_t)MD_NODE_STATE_OPERATIONAL || s == (uint8_t)MD_NODE_STATE_PREOP;
}

static md_node_monitor_t *monitor_of(md_node_t *node, uint8_t node_id)
{
    for (size_t i = 0u; i < MD_NODE_MONITORED; ++i) {
        if (node->monitor[i].node_id == node_id) {
            return &node->monitor[i];
        }
    }
    return NULL;
}

static bool monitor_enabled(const md_node_t *node, uint8_t node_id)
{
    const md_param_id_t p = (node_id == (uint8_t)MD_NODE_ACT)    ? MD_P_MONITOR_ACT
                            : (node_id == (uint8_t)MD_NODE_HALL) ? MD_P_MONITOR_HALL
                                                                 : MD_P_MONITOR_FE;
    return md_params_get_u32(&node->params, p) != 0u;
}

void md_node_monitor_refresh(md_node_t *node, uint8_t node_id)
{
    md_node_monitor_t *mon = monitor_of(node, node_id);
    if (mon != NULL && !monitor_enabled(node, node_id)) {
        forget_monitor(mon);
    }
}

/* Every heartbeat shares HEARTBEAT_ACT's layout; the sender is id - 0x700. */
static rx_result_t handle_heartbeat(md_node_t *node, const md_frame_t *f, uint64_t now_us)
{
    struct md_can_heartbeat_act_t m;
    if (md_can_heartbeat_act_unpack(&m, f->data, f->len) != 0 || !node_state_known(m.node_state) ||
        m.protocol_version != (uint8_t)MD_PROTOCOL_VERSION) {
        return RX_BAD_RANGE; /* a node speaking another protocol version is not "alive" for us */
    }
    const uint8_t sender = (uint8_t)(f->id - MD_CAN_HEARTBEAT_CTRL_FRAME_ID + (uint32_t)MD_NODE_CTRL);
    md_node_monitor_t *mon = monitor_of(node, sender);
    if (mon == NULL || !monitor_enabled(node, sender)) {
        return RX_OK;
    }
    if (mon->lost) {
        mon->lost = false;
        node->counters.node_back++;
        /* CANopen "error reset" EMCY: the condition behind an earlier EMCY has cleared. */
        (void)send_emcy(node, MD_EMCY_NONE, MD_NODE_EMCY_NO_ELECTRODE, sender);
    }
    mon->seen = true;
    mon->last_state = m.node_state;
    mon->last_us = now_us;
    return RX_OK;
}

/* ------------------------------------------------------------------ */
/* Entry points                                                        */
/* ------------------------------------------------------------------ */

static rx_result_t dispatch(md_node_t *node, const md_frame_t *f, uint64_t now_us)
{
    switch (f->id) {
    case MD_CAN_ESTOP_FRAME_ID: return handle_estop(node, f);
    case MD_CAN_NMT_FRAME_ID: return handle_nmt(node, f);
    case MD_CAN_SIM_CLOCK_FRAME_ID: return handle_sim_clock(node, f);
    case MD_CAN_EMCY_ACT_FRAME_ID:
    case MD_CAN_EMCY_HALL_FRAME_ID:
    case MD_CAN_EMCY_FE_FRAME_ID:
    case MD_CAN_EMCY_OPER_FRAME_ID: return handle_remote_emcy(f);
    case MD_CAN_ACT_STATUS_FRAME_ID: return handle_act_status(node, f);
    case MD_CAN_HALL_READING_FRAME_ID: return handle_hall_reading(node, f);
    case MD_CAN_HALL_CALIB_FRAME_ID: return handle_hall_calib(f);
    case MD_CAN_REC_DATA_FRAME_ID: return handle_rec_data(node, f);
    case MD_CAN_REC_END_FRAME_ID: return handle_rec_end(node, f);
    case MD_CAN_FE_INFO_FRAME_ID: return handle_fe_info(f);
    case MD_CAN_PARAM_REQ_CTRL_FRAME_ID: return md_node_param_request(node, f, now_us) ? RX_OK : RX_BAD_RANGE;
    case MD_CAN_HEARTBEAT_ACT_FRAME_ID:
    case MD_CAN_HEARTBEAT_HALL_FRAME_ID:
    case MD_CAN_HEARTBEAT_FE_FRAME_ID:
    case MD_CAN_HEARTBEAT_OPER_FRAME_ID: return handle_heartbeat(node, f, now_us);
    default: return RX_OK; /* unreachable: only RX_CONSUME ids get here */
    }
}

/* Form checks that need no decoding: validity, id, role, length, FD flag.
 * Returns true if the frame may be decoded; counts the reason otherwise. */
static bool frame_form_ok(md_node_t *node, const md_frame_t *f)
{
    if (!md_frame_valid(f)) {
        node->counters.rx_malformed++;
        return false;
    }
    const rx_rule_t *rule = ((f->flags & MD_FRAME_FLAG_EXT) != 0u) ? NULL : find_rule(f->id);
    if (rule == NULL) {
        node->counters.rx_unknown_id++;
        return false;
    }
    if (rule->role == RX_OWN) {
        node->counters.rx_id_conflict++;
        return false;
    }
    const bool fd = (f->flags & MD_FRAME_FLAG_FD) != 0u;
    if (f->len != rule->len || fd != rule->fd) {
        node->counters.rx_malformed++;
        node->counters.rx_bad_length++;
        return false;
    }
    return true;
}

md_status_t md_node_on_frame(md_node_t *node, const md_frame_t *frame, uint64_t now_us)
{
    if (node == NULL || frame == NULL) {
        return MD_E_ARG;
    }
    node->counters.rx_frames++;
    rx_result_t r = RX_BAD_RANGE;
    const bool form_ok = frame_form_ok(node, frame);
    if (!form_ok && frame->id == MD_CAN_ESTOP_FRAME_ID && (frame->flags & MD_FRAME_FLAG_EXT) == 0u) {
        /* The one exception to "a malformed frame changes nothing": id 0 is
         * only ever an e-stop, and a garbled stop request must still stop
         * (fail-safe). It is counted as malformed all the same. */
        latch_estop(node, MD_NODE_ESTOP_SOURCE_UNKNOWN, 0u);
    }
    if (form_ok) {
        r = dispatch(node, frame, now_us);
        if (r == RX_OK) {
            return MD_OK;
        }
        if (r == RX_BAD_SEQ) {
            node->counters.rx_bad_sequence++;
        } else {
            node->counters.rx_malformed++;
            node->counters.rx_bad_range++;
        }
    }
    protocol_emcy(node, frame->id, now_us);
    return MD_E_FRAME;
}

static void supervise(md_node_t *node, uint64_t now_us)
{
    const uint64_t timeout_us = (uint64_t)md_params_get_u32(&node->params, MD_P_HEARTBEAT_TIMEOUT_MS) * US_PER_MS;
    for (size_t i = 0u; i < MD_NODE_MONITORED; ++i) {
        md_node_monitor_t *mon = &node->monitor[i];
        if (!mon->seen || mon->lost || now_us <= mon->last_us || now_us - mon->last_us <= timeout_us) {
            continue;
        }
        mon->lost = true;
        node->counters.heartbeat_lost++;
        (void)halt_all(node);
        (void)send_emcy(node, MD_EMCY_HEARTBEAT_LOST, MD_NODE_EMCY_NO_ELECTRODE, mon->node_id);
    }
}

md_status_t md_node_poll(md_node_t *node, uint64_t now_us)
{
    if (node == NULL) {
        return MD_E_ARG;
    }
    const uint32_t failures_before = node->counters.tx_failures;
    if (node->boot_pending) {
        (void)do_boot(node, now_us);
    }
    if (now_us >= node->next_heartbeat_us) {
        (void)send_heartbeat(node, now_us);
        const uint64_t period_us = (uint64_t)md_params_get_u32(&node->params, MD_P_HEARTBEAT_PERIOD_MS) * US_PER_MS;
        node->next_heartbeat_us += period_us;
        if (node->next_heartbeat_us <= now_us) {
            node->next_heartbeat_us = now_us + period_us; /* late poll: no burst of catch-up heartbeats */
        }
    }
    supervise(node, now_us);
    (void)retry_halts(node);
    return (node->counters.tx_failures == failures_before) ? MD_OK : MD_E_IO;
}

uint64_t md_node_next_deadline_us(const md_node_t *node, uint64_t now_us)
{
    if (node == NULL || node->boot_pending || node->halt_pending != 0u) {
        return now_us;
    }
    uint64_t deadline = node->next_heartbeat_us;
    const uint64_t timeout_us = (uint64_t)md_params_get_u32(&node->params, MD_P_HEARTBEAT_TIMEOUT_MS) * US_PER_MS;
    for (size_t i = 0u; i < MD_NODE_MONITORED; ++i) {
        const md_node_monitor_t *mon = &node->monitor[i];
        if (mon->seen && !mon->lost && mon->last_us + timeout_us + 1u < deadline) {
            deadline = mon->last_us + timeout_us + 1u; /* first instant that is "longer than" the timeout */
        }
    }
    return deadline;
}

bool md_node_motion_allowed(const md_node_t *node)
{
    if (node == NULL || node->state != MD_NODE_STATE_OPERATIONAL || node->estop_latched || any_lost(node)) {
        return false;
    }
    /* Never command an actuator driver we have not heard from. */
    for (size_t i = 0u; i < MD_NODE_MONITORED; ++i) {
        if (node->monitor[i].node_id == (uint8_t)MD_NODE_ACT && !node->monitor[i].seen) {
            return !monitor_enabled(node, (uint8_t)MD_NODE_ACT);
        }
    }
    return true;
}

md_status_t md_node_step(md_node_t *node, uint8_t electrode, uint8_t direction, uint16_t steps, uint16_t rate_hz)
{
    if (node == NULL || electrode >= MD_ELECTRODES ||
        (direction != MD_ACT_DIR_ADVANCE && direction != MD_ACT_DIR_RETRACT)) {
        return MD_E_ARG;
    }
    if (!md_node_motion_allowed(node)) {
        return MD_E_STATE;
    }
    return send_act_cmd(node, electrode, MD_ACT_CMD_STEP, direction, steps, rate_hz);
}

uint8_t md_node_heartbeat_flags(const md_node_t *node)
{
    uint8_t flags = 0u;
    if (node->estop_latched) {
        flags |= MD_HB_FLAG_ESTOP;
    }
    if (any_lost(node)) {
        flags |= MD_HB_FLAG_FAULT;
    }
    return flags;
}
