/// @file md_node_params.h
/// The controller's parameter service: PARAM_REQ_CTRL read or set one row of
/// the parameter table (md_params.h) and are answered with PARAM_RESP_CTRL.
/// Reads see live values (node state, e-stop latch, uptime, the diagnostic
/// counters of md_node_counters_t); a set passes the node's state rules
/// (read-only rows, motion rows while the e-stop is latched, configuration
/// rows while operational: MD_PARAM_REFUSED) and then md_params_set's value
/// rules, and its side effects on the node follow (heartbeat period,
/// supervision). docs/protocol.md lists the parameters.
#ifndef MD_NODE_PARAMS_H
#define MD_NODE_PARAMS_H

#include <stdbool.h>
#include <stdint.h>

#include "md_frame.h"
#include "md_node.h"
#include "md_params.h"

/// Value of any parameter row as an operator would read it (live rows from the
/// node's state and counters). 0.0 for an id out of range. O(rows).
double md_node_param_read(const md_node_t *node, md_param_id_t id, uint64_t now_us);

/// Serves one PARAM_REQ_CTRL frame `f` (get or set) and sends the answer
/// (its send failure is counted in tx_failures). False, with nothing changed
/// or sent, when the frame does not unpack or its index is out of the DBC's
/// range: the caller counts it as out of range. O(rows).
bool md_node_param_request(md_node_t *node, const md_frame_t *f, uint64_t now_us);

#endif
