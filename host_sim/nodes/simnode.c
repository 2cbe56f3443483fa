#include "simnode.h"

#include <string.h>

#include "md_can.h"

void simnode_init(simnode_t *n, md_node_id_t id, uint32_t electrodes, bool autostart, bool lockstep,
                  simnode_sink_t sink)
{
    memset(n, 0, sizeof *n);
    n->id = (uint8_t)id;
    n->state = MD_NODE_STATE_BOOT;
    n->autostart = autostart;
    n->lockstep = lockstep;
    n->electrodes = electrodes;
    n->sink = sink;
}

bool simnode_boot_done(simnode_t *n)
{
    n->state = n->autostart ? MD_NODE_STATE_OPERATIONAL : MD_NODE_STATE_PREOP;
    return n->state == MD_NODE_STATE_OPERATIONAL;
}

bool simnode_operational(const simnode_t *n)
{
    return n->state == MD_NODE_STATE_OPERATIONAL;
}

simnode_nmt_effect_t simnode_nmt_apply(simnode_t *n, uint8_t command, uint8_t target)
{
    if (target != 0u && target != n->id) {
        return SIMNODE_NMT_NOT_ADDRESSED;
    }
    switch ((md_nmt_command_t)command) {
    case MD_NMT_START: n->state = MD_NODE_STATE_OPERATIONAL; return SIMNODE_NMT_ENTER_OP;
    case MD_NMT_STOP: n->state = MD_NODE_STATE_STOPPED; return SIMNODE_NMT_LEAVE_OP;
    case MD_NMT_PREOP: n->state = MD_NODE_STATE_PREOP; return SIMNODE_NMT_LEAVE_OP;
    case MD_NMT_RESET_NODE: {
        md_frame_t hb;
        n->state = MD_NODE_STATE_BOOT;
        n->fault = false;
        n->resets++;
        simnode_heartbeat_frame(n, 0u, &hb); /* CANopen boot-up message */
        (void)simnode_send(n, &hb);          /* failure already counted */
        (void)simnode_boot_done(n);
        return SIMNODE_NMT_RESET;
    }
    case MD_NMT_CLEAR_ESTOP: n->estop_latched = false; return SIMNODE_NMT_CLEAR_ESTOP;
    default: return SIMNODE_NMT_NOT_ADDRESSED; /* the plant validates commands first */
    }
}

void simnode_heartbeat_frame(const simnode_t *n, uint32_t uptime_s, md_frame_t *out)
{
    /* The heartbeats of all nodes share one layout; HEARTBEAT_ACT's packer
     * serves every node and the id selects the node. */
    struct md_can_heartbeat_act_t hb;
    uint8_t flags = 0u;
    flags = (uint8_t)(flags | (n->estop_latched ? MD_HB_FLAG_ESTOP : 0u));
    flags = (uint8_t)(flags | (n->fault ? MD_HB_FLAG_FAULT : 0u));
    flags = (uint8_t)(flags | (n->lockstep ? MD_HB_FLAG_LOCKSTEP : 0u));
    hb.node_state = (uint8_t)n->state;
    hb.protocol_version = (uint8_t)MD_PROTOCOL_VERSION;
    hb.flags = flags;
    hb.electrodes = (uint8_t)n->electrodes;
    hb.uptime_s = uptime_s;
    simnode_frame_init(out, 0x700u + n->id, (uint8_t)MD_CAN_HEARTBEAT_ACT_LENGTH);
    (void)md_can_heartbeat_act_pack(out->data, &hb, sizeof out->data);
}

int simnode_send(simnode_t *n, const md_frame_t *frame)
{
    if (n->silent) {
        n->stats.tx_silenced++;
        return 0;
    }
    const int rc = n->sink.send(n->sink.ctx, frame);
    if (rc < 0) {
        n->stats.tx_errors++;
    } else {
        n->stats.tx_frames++;
    }
    return rc;
}

int simnode_emcy(simnode_t *n, uint16_t code, uint8_t electrode, uint32_t info)
{
    struct md_can_emcy_act_t e; /* every EMCY shares this layout; the id selects the node */
    md_frame_t f;
    uint8_t reg = 0x01u;
    if ((code & 0xFF00u) == 0x8100u || (code & 0xFF00u) == 0x8200u) {
        reg = (uint8_t)(reg | 0x10u);
    }
    if (code == (uint16_t)MD_EMCY_MOTION) {
        reg = (uint8_t)(reg | 0x80u);
    }
    e.error_code = code;
    e.error_register = reg;
    e.electrode = electrode;
    e.info = info;
    simnode_frame_init(&f, 0x080u + n->id, (uint8_t)MD_CAN_EMCY_ACT_LENGTH);
    (void)md_can_emcy_act_pack(f.data, &e, sizeof f.data);
    const int rc = simnode_send(n, &f);
    if (rc >= 0) {
        n->stats.emcy_sent++;
    }
    return rc;
}

void simnode_malformed(simnode_t *n, uint32_t frame_id)
{
    const uint64_t count = ++n->stats.rx_malformed;
    if ((count & (count - 1u)) == 0u) {
        (void)simnode_emcy(n, (uint16_t)MD_EMCY_PROTOCOL, 0xFFu, frame_id);
    }
}

void simnode_frame_init(md_frame_t *f, uint32_t id, uint8_t len)
{
    memset(f, 0, sizeof *f);
    f->id = id;
    f->len = len;
    f->flags = (len > 8u) ? (uint8_t)(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_BRS) : 0u;
}

bool simnode_frame_is(const md_frame_t *f, uint32_t id)
{
    return (f->flags & MD_FRAME_FLAG_EXT) == 0u && f->id == id;
}
