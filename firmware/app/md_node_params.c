/// @file md_node_params.c
/// The controller's parameter service on the bus (see md_node_params.h).
#include "md_node_params.h"

#include <stddef.h>
#include <string.h>

#include "md_can.h"

#define US_PER_MS 1000u
#define US_PER_S 1000000u

/* The diagnostic counters readable as parameters, by their place in
 * md_node_counters_t (all uint32_t). */
typedef struct {
    md_param_id_t id;
    size_t offset;
} node_counter_param_t;

static const node_counter_param_t NODE_COUNTER_PARAMS[] = {
    {MD_P_RX_FRAMES, offsetof(md_node_counters_t, rx_frames)},
    {MD_P_RX_MALFORMED, offsetof(md_node_counters_t, rx_malformed)},
    {MD_P_RX_UNKNOWN_ID, offsetof(md_node_counters_t, rx_unknown_id)},
    {MD_P_RX_BAD_LENGTH, offsetof(md_node_counters_t, rx_bad_length)},
    {MD_P_RX_BAD_RANGE, offsetof(md_node_counters_t, rx_bad_range)},
    {MD_P_RX_BAD_SEQUENCE, offsetof(md_node_counters_t, rx_bad_sequence)},
    {MD_P_RX_ID_CONFLICT, offsetof(md_node_counters_t, rx_id_conflict)},
    {MD_P_TX_FRAMES, offsetof(md_node_counters_t, tx_frames)},
    {MD_P_TX_FAILURES, offsetof(md_node_counters_t, tx_failures)},
    {MD_P_EMCY_SENT, offsetof(md_node_counters_t, emcy_sent)},
    {MD_P_HEARTBEAT_LOST, offsetof(md_node_counters_t, heartbeat_lost)},
    {MD_P_NODE_BACK, offsetof(md_node_counters_t, node_back)},
    {MD_P_ESTOP_EVENTS, offsetof(md_node_counters_t, estop_events)},
    {MD_P_NMT_REFUSED, offsetof(md_node_counters_t, nmt_refused)},
    {MD_P_CYCLES_DONE, offsetof(md_node_counters_t, cycles_done)},
    {MD_P_CYCLES_SKIPPED, offsetof(md_node_counters_t, cycles_skipped)},
    {MD_P_RECORDINGS_FAILED, offsetof(md_node_counters_t, rec_failed)},
    {MD_P_MOVES_FAILED, offsetof(md_node_counters_t, moves_failed)},
};
_Static_assert(sizeof(md_node_counters_t) ==
                   sizeof(NODE_COUNTER_PARAMS) / sizeof(NODE_COUNTER_PARAMS[0]) * sizeof(uint32_t),
               "every counter is readable as a parameter");

/* A counter's value, or false if `id` names no counter. */
static bool node_counter_read(const md_node_counters_t *c, md_param_id_t id, uint32_t *value)
{
    const unsigned char *bytes = (const unsigned char *)c;
    for (size_t i = 0u; i < sizeof(NODE_COUNTER_PARAMS) / sizeof(NODE_COUNTER_PARAMS[0]); ++i) {
        if (NODE_COUNTER_PARAMS[i].id == id) {
            /* cppcheck-suppress misra-c2012-21.15 ; deliberate: a uint32_t member from its bytes at its offsetof */
            (void)memcpy(value, &bytes[NODE_COUNTER_PARAMS[i].offset], sizeof *value);
            return true;
        }
    }
    return false;
}

/* Live values are read from the node; every other parameter is the value set. */
double md_node_param_read(const md_node_t *node, md_param_id_t id, uint64_t now_us)
{
    uint32_t counter = 0u;
    if (id == MD_P_NODE_STATE) {
        return (double)node->state;
    }
    if (id == MD_P_ESTOP_LATCHED) {
        return node->estop_latched ? 1.0 : 0.0;
    }
    if (id == MD_P_UPTIME_S) {
        return (double)((now_us - node->boot_us) / US_PER_S);
    }
    if (node_counter_read(&node->counters, id, &counter)) {
        return (double)counter;
    }
    return md_params_get(&node->params, id);
}

/* State rules of a set (MD_PARAM_REFUSED); value rules are md_params_set's. */
static bool set_refused(const md_node_t *node, const md_param_def_t *d)
{
    if ((d->flags & MD_PARAM_F_READ_ONLY) != 0u) {
        return false; /* answered READ_ONLY, the more precise status */
    }
    if ((d->flags & MD_PARAM_F_MOTION) != 0u && node->estop_latched) {
        return true;
    }
    return (d->flags & MD_PARAM_F_CONFIG) != 0u && node->state == MD_NODE_STATE_OPERATIONAL;
}

/* Side effects of a successful set that the node owns. */
static void after_set(md_node_t *node, md_param_id_t id, uint64_t now_us)
{
    if (id == MD_P_HEARTBEAT_PERIOD_MS && !node->boot_pending) {
        node->next_heartbeat_us = now_us +
                                  (uint64_t)md_params_get_u32(&node->params, MD_P_HEARTBEAT_PERIOD_MS) * US_PER_MS;
    }
    /* Disabling supervision forgets the node (and lifts its motion inhibit). */
    const uint8_t node_id = (id == MD_P_MONITOR_ACT)    ? (uint8_t)MD_NODE_ACT
                            : (id == MD_P_MONITOR_HALL) ? (uint8_t)MD_NODE_HALL
                            : (id == MD_P_MONITOR_FE)   ? (uint8_t)MD_NODE_FE
                                                        : 0u;
    md_node_monitor_refresh(node, node_id);
}

static md_param_status_t param_set(md_node_t *node, uint16_t index, double value, uint64_t now_us)
{
    const int found = md_params_find(index);
    if (found < 0) {
        return MD_PARAM_UNKNOWN_INDEX;
    }
    if (set_refused(node, md_params_def((size_t)found))) {
        return MD_PARAM_REFUSED;
    }
    const md_param_status_t st = md_params_set(&node->params, index, value);
    if (st == MD_PARAM_OK) {
        after_set(node, (md_param_id_t)found, now_us);
    }
    return st;
}

bool md_node_param_request(md_node_t *node, const md_frame_t *f, uint64_t now_us)
{
    struct md_can_param_req_ctrl_t req;
    if (md_can_param_req_ctrl_unpack(&req, f->data, f->len) != 0 ||
        !md_can_param_req_ctrl_index_is_in_range(req.index)) {
        return false;
    }
    /* A NaN/inf Value is not a malformed frame but a set out of range: it is
     * answered, so the operator learns why nothing changed. */
    md_param_status_t status = MD_PARAM_BAD_OP;
    if (req.op == MD_PARAM_OP_SET) {
        status = param_set(node, req.index, (double)req.value, now_us);
    } else if (req.op == MD_PARAM_OP_GET) {
        status = (md_params_find(req.index) < 0) ? MD_PARAM_UNKNOWN_INDEX : MD_PARAM_OK;
    }
    struct md_can_param_resp_ctrl_t resp;
    uint8_t buf[MD_CAN_PARAM_RESP_CTRL_LENGTH];
    (void)md_can_param_resp_ctrl_init(&resp);
    resp.op = req.op;
    resp.status = (uint8_t)status;
    resp.index = req.index;
    const int found = md_params_find(req.index);
    /* Value: the current value (after a set, whatever its outcome), 0 if unknown. */
    resp.value = (found < 0) ? 0.0f : (float)md_node_param_read(node, (md_param_id_t)found, now_us);
    (void)md_node_send(node, MD_CAN_PARAM_RESP_CTRL_FRAME_ID, buf, md_can_param_resp_ctrl_pack(buf, &resp, sizeof buf),
                       false);
    return true;
}
