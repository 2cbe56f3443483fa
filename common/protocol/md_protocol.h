/// @file md_protocol.h
/// Protocol constants that the DBC describes in comments and value tables:
/// node ids, node states, NMT commands, error codes, parameter-response status.
/// Frame layouts and packing come from generated/md_can.h (cantools, from
/// microdrive.dbc); this header only names the values carried in those frames.
#ifndef MD_PROTOCOL_H
#define MD_PROTOCOL_H

/// Bumped on any incompatible change of microdrive.dbc; carried in every heartbeat.
#define MD_PROTOCOL_VERSION 1u

/// Node ids (CANopen-style: heartbeat 0x700 + id, EMCY 0x080 + id).
typedef enum {
    MD_NODE_CTRL = 1,  ///< the controller firmware
    MD_NODE_ACT = 2,   ///< actuator driver (simulator)
    MD_NODE_HALL = 3,  ///< position sensor (simulator)
    MD_NODE_FE = 4,    ///< neural front-end (simulator)
    MD_NODE_OPER = 5   ///< operator tools
} md_node_id_t;

/// Heartbeat NodeState values (CANopen NMT states).
typedef enum {
    MD_NODE_STATE_BOOT = 0,
    MD_NODE_STATE_STOPPED = 4,
    MD_NODE_STATE_OPERATIONAL = 5,
    MD_NODE_STATE_PREOP = 127
} md_node_state_t;

/// Heartbeat Flags bits.
#define MD_HB_FLAG_ESTOP 0x01u
#define MD_HB_FLAG_FAULT 0x02u
#define MD_HB_FLAG_LOCKSTEP 0x04u

/// NMT NmtCommand values; NmtTarget 0 addresses every node.
typedef enum {
    MD_NMT_START = 1,
    MD_NMT_STOP = 2,
    MD_NMT_PREOP = 128,
    MD_NMT_RESET_NODE = 129,
    MD_NMT_CLEAR_ESTOP = 131
} md_nmt_command_t;

/// EMCY ErrorCode values (CANopen error classes in the high byte).
typedef enum {
    MD_EMCY_NONE = 0x0000,
    MD_EMCY_GENERIC = 0x1000,
    MD_EMCY_SOFTWARE = 0x6100,        ///< internal software error (Info = md_status_t)
    MD_EMCY_ESTOP = 0x6200,           ///< e-stop latched (Info = source node)
    MD_EMCY_COMM_OVERRUN = 0x8110,    ///< frames lost or queue overflow
    MD_EMCY_HEARTBEAT_LOST = 0x8130,  ///< a monitored node's heartbeat timed out (Info = node id)
    MD_EMCY_PROTOCOL = 0x8200,        ///< malformed frame / bad sequence (Info = frame id)
    MD_EMCY_MOTION = 0x8400,          ///< actuator stall, end stop, depth window
    MD_EMCY_SENSOR = 0x5000           ///< position sensor reading invalid
} md_emcy_code_t;

/// ACT_STATUS State values.
typedef enum { MD_ACT_IDLE = 0, MD_ACT_MOVING = 1, MD_ACT_STALLED = 2, MD_ACT_FAULT = 3 } md_act_state_t;

/// ACT_CMD Command and Direction values.
#define MD_ACT_CMD_HALT 0u
#define MD_ACT_CMD_STEP 1u
#define MD_ACT_DIR_ADVANCE 0u
#define MD_ACT_DIR_RETRACT 1u

/// PARAM_REQ Op values and PARAM_RESP Status values.
#define MD_PARAM_OP_GET 1u
#define MD_PARAM_OP_SET 2u
typedef enum {
    MD_PARAM_OK = 0,
    MD_PARAM_UNKNOWN_INDEX = 1,
    MD_PARAM_OUT_OF_RANGE = 2,
    MD_PARAM_READ_ONLY = 3,
    MD_PARAM_REFUSED = 4,
    MD_PARAM_BAD_OP = 5
} md_param_status_t;

/// REC_END Status values.
#define MD_REC_COMPLETE 0u
#define MD_REC_ABORTED 1u
#define MD_REC_OVERFLOW 2u

/// HALL_CALIB: coefficients c_k (CoeffIndex k < CoeffCount) act on the
/// normalised code x = (code - code_mid) / code_half; two extra indices carry
/// code_mid and code_half.
#define MD_HALL_CALIB_INDEX_CODE_MID 0xF0u
#define MD_HALL_CALIB_INDEX_CODE_HALF 0xF1u

/// Samples carried by one REC_DATA frame.
#define MD_REC_SAMPLES_PER_FRAME 30u

#endif
