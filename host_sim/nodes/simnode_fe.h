/// @file simnode_fe.h
/// Neural front-end node (node 4): answers REC_REQ by streaming the interval
/// as REC_DATA CAN FD frames (30 int16 samples each, the last one partial,
/// Seq 0, 1, 2... per interval) and then REC_END; FE_INFO (sampling rate,
/// gain) of every electrode when it becomes operational and then every
/// info_period (like HALL_CALIB), so a controller that restarts while the
/// front-end stays operational learns the sampling parameters again.
///
/// Timing: the samples of an interval of n samples requested at t0 are taken
/// at t0 + i / rate; frame j goes out when its last sample has been taken
/// (t0 + min(30 (j+1), n) / rate, rounded up to whole us) and REC_END with
/// it. Each frame's samples are generated when it goes out, so whatever
/// happens in the world meanwhile (realtime mode) is in the signal.
///
/// One interval per electrode at a time: a REC_REQ for an electrode that is
/// still streaming is refused with REC_END Status = overflow (2), TotalSamples
/// 0 and the new IntervalId. E-stop, NMT stop/pre-op/reset and a motion
/// started on the same electrode abort a stream: REC_END Status = aborted (1)
/// with the samples sent so far.
#ifndef SIMNODE_FE_H
#define SIMNODE_FE_H

#include <stdbool.h>
#include <stdint.h>

#include "simnode.h"
#include "simnode_world.h"

/// Longest interval: REC_DATA Seq is 16 bits.
#define SIMNODE_FE_MAX_SAMPLES (65536u * MD_REC_SAMPLES_PER_FRAME)

/// One interval being streamed.
typedef struct {
    bool active;
    uint16_t interval_id;
    uint32_t n_total;  ///< samples requested
    uint32_t n_sent;   ///< samples already in frames
    uint16_t seq;      ///< Seq of the next REC_DATA frame
    uint64_t t0_us;    ///< time of sample 0
} simnode_fe_stream_t;

typedef struct {
    simnode_t node;
    simnode_world_t *world;
    uint32_t rate_hz;
    double gain_uv;
    uint64_t intervals_done;  ///< streams that ended complete
    uint64_t info_period_us;  ///< FE_INFO repeat period (> 0)
    uint64_t next_info_us;    ///< next FE_INFO; UINT64_MAX while not operational
    simnode_fe_stream_t st[SIMNODE_MAX_ELECTRODES];
} simnode_fe_t;

/// Initialises the node (state BOOT); info_period_ms > 0.
void simnode_fe_init(simnode_fe_t *fe, simnode_world_t *world, bool autostart, bool lockstep, uint32_t info_period_ms,
                     simnode_sink_t sink);

/// Sends FE_INFO of every electrode at t_us and schedules the next ones.
void simnode_fe_announce(simnode_fe_t *fe, uint64_t t_us);

/// Handles a REC_REQ at world time t_us: validates (length, electrode,
/// 1 <= NumSamples <= SIMNODE_FE_MAX_SAMPLES), refuses silently when not
/// operational, refuses with REC_END overflow when busy, else records.
/// Returns true if a stream started.
bool simnode_fe_on_req(simnode_fe_t *fe, const md_frame_t *f, uint64_t t_us);

/// Aborts the stream of electrode e (or of all when e >= electrodes) with
/// REC_END Status = aborted, if one is active.
void simnode_fe_abort(simnode_fe_t *fe, uint32_t e);

/// Reacts to an NMT command's effect on this node.
void simnode_fe_on_nmt(simnode_fe_t *fe, simnode_nmt_effect_t effect, uint64_t t_us);

/// Earliest time of the next frame of any stream or of the next FE_INFO;
/// UINT64_MAX when idle and not operational.
uint64_t simnode_fe_next_event_us(const simnode_fe_t *fe);

/// Sends every frame due by t_us, in electrode order, ending streams, and
/// FE_INFO when it is due.
void simnode_fe_run(simnode_fe_t *fe, uint64_t t_us);

/// True while any stream is active.
bool simnode_fe_busy(const simnode_fe_t *fe);

#endif
