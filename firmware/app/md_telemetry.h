/// @file md_telemetry.h
/// Telemetry of the electrode cycle (DBC TLM_*; docs/protocol.md,
/// docs/controller.md): what the operator and the session scorer see of every
/// cycle. Every function packs frames exactly as the DBC (and its comments)
/// define them and sends them through md_node_send (counted there); the
/// return value is MD_OK or the first send failure (MD_E_IO).
#ifndef MD_TELEMETRY_H
#define MD_TELEMETRY_H

#include <stdint.h>

#include "md_status.h"
#include "md_cycle.h"
#include "md_node.h"

#define MD_TLM_PHASE_REQUESTED 0u     ///< TLM_CYCLE Phase: recording requested
#define MD_TLM_PHASE_PROCESSED 1u     ///< TLM_CYCLE Phase: interval processed (or skipped)
#define MD_TLM_SPIKES_PER_PART 11u    ///< TLM_SPIKES entries per frame
#define MD_TLM_WAVE_PER_PART 28u      ///< TLM_WAVE samples per frame
#define MD_TLM_TRACK_OUTLIER (-1)     ///< TLM_SPIKES Track: outlier or false cluster
#define MD_TLM_TRACK_UNLABELLED (-2)  ///< TLM_SPIKES Track: no label for this spike

/// TLM_CYCLE of electrode e.
md_status_t md_tlm_cycle(md_node_t *node, uint8_t e, const md_electrode_t *el, uint8_t phase, uint32_t num_samples);

/// TLM_STATUS of electrode e after its decision (num_hyp: tracker survivors).
md_status_t md_tlm_status(md_node_t *node, uint8_t e, const md_electrode_t *el, uint32_t num_spikes);

/// TLM_TRACK and TLM_WAVE (mean waveform of the track's Kalman state, µV)
/// for every live track of the leading hypothesis, TLM_HYP for every
/// surviving hypothesis, TLM_SPIKES with the leading hypothesis' label of
/// every spike given to the tracker (at least one frame, Count 0 if none).
md_status_t md_tlm_interval(md_node_t *node, uint8_t e, const md_electrode_t *el, const md_workspace_t *ws);

/// TLM_SPIKES for a skipped cycle: the interval's detections, all unlabelled.
md_status_t md_tlm_spikes_unlabelled(md_node_t *node, uint8_t e, const md_electrode_t *el, const md_workspace_t *ws);

#endif
