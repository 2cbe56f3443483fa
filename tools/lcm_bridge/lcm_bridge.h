/// @file lcm_bridge.h
/// The decoding core of md-lcm-bridge: CAN frames of the microdrive protocol
/// (common/protocol/microdrive.dbc) in, encoded LCM messages of package
/// mdlcm (common/lcm/*.lcm) out, through a caller-provided sink. No I/O of
/// its own, so the same code serves the live bus, a candump log replay and the
/// unit test (docs/telemetry.md has the channel table and the grouping rules).
///
/// Ownership: the caller owns the lb_t (large: put it on the heap or in static
/// storage) and every buffer it passes; the sink gets the encoded bytes for the
/// duration of the call only.
#ifndef LCM_BRIDGE_H
#define LCM_BRIDGE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_frame.h"

/// LCM channel names (UPPER_SNAKE; one type per channel, docs/telemetry.md).
#define LB_CH_STATUS "MD_STATUS"                ///< mdlcm.status_t
#define LB_CH_CYCLE "MD_CYCLE"                  ///< mdlcm.cycle_t
#define LB_CH_TRACKS "MD_TRACKS"                ///< mdlcm.tracks_t
#define LB_CH_HYPOTHESES "MD_HYPOTHESES"        ///< mdlcm.hypotheses_t
#define LB_CH_SPIKES "MD_SPIKES"                ///< mdlcm.spikes_t
#define LB_CH_ACTUATOR "MD_ACTUATOR"            ///< mdlcm.actuator_t
#define LB_CH_HALL "MD_HALL"                    ///< mdlcm.hall_t (readings batched)
#define LB_CH_HALL_CALIB "MD_HALL_CALIB"        ///< mdlcm.hall_calib_t
#define LB_CH_TRUTH_SESSION "MD_TRUTH_SESSION"  ///< mdlcm.truth_session_t
#define LB_CH_TRUTH_STATE "MD_TRUTH_STATE"      ///< mdlcm.truth_state_t
#define LB_CH_TRUTH_SPIKES "MD_TRUTH_SPIKES"    ///< mdlcm.truth_spikes_t
#define LB_CH_TRUTH_DEATH "MD_TRUTH_DEATH"      ///< mdlcm.truth_death_t

/// Capacities of the per-electrode cycle group (records beyond are counted in
/// lb_stats_t.dropped and left out).
#define LB_MAX_ELECTRODES 8u
#define LB_MAX_TRACKS 64u          ///< TLM_TRACK Index 0..63
#define LB_WAVE_PART_LEN 28u       ///< samples per TLM_WAVE part (DBC)
#define LB_MAX_WAVE_PARTS 4u       ///< up to 112 samples (MD_WAVE_LEN_MAX is 48)
#define LB_MAX_HYPS 64u            ///< TLM_HYP Rank 0..63
#define LB_SPIKES_PER_PART 11u     ///< TLM_SPIKES entries per part (DBC)
#define LB_MAX_SPIKES 4096u        ///< spikes per interval kept
#define LB_MAX_CALIB_COEFFS 16u    ///< HALL_CALIB CoeffIndex 0..15
#define LB_TRUTH_MAX_NEURONS 256u  ///< neurons of a truth session / state record
#define LB_TRUTH_SPIKE_BATCH 256u  ///< = truth_spikes_t.MAX_SPIKES
#define LB_HALL_BATCH 100u         ///< = hall_t.MAX_READINGS

/// Which clock stamps utime (docs/telemetry.md, "Time").
typedef enum {
    LB_TIME_SIM = 0,   ///< the last SIM_CLOCK SimTime_us seen (0 before any): deterministic
    LB_TIME_FRAME = 1  ///< the caller's frame time (candump log stamp or wall clock)
} lb_time_mode_t;

/// Receives one encoded message. channel: one of LB_CH_*; utime: the
/// message's utime (µs). Returns 0, or negative to count a publish error.
typedef int (*lb_sink_fn)(void *ctx, const char *channel, int64_t utime, const uint8_t *data, size_t len);

/// Counters; nothing is dropped without a count.
typedef struct {
    uint64_t frames;         ///< frames fed
    uint64_t telemetry;      ///< frames decoded into a message or a group
    uint64_t ignored;        ///< frames of ids the bridge does not translate (REC_DATA, heartbeats...)
    uint64_t malformed;      ///< wrong length or unpack failure
    uint64_t dropped;        ///< records beyond a capacity (electrode, index, part)
    uint64_t late;           ///< TLM frames for a cycle group already published
    uint64_t messages;       ///< messages handed to the sink
    uint64_t sink_errors;    ///< sink returned < 0, or encoding failed
    uint64_t truth_records;  ///< truth lines consumed
    uint64_t truth_errors;   ///< truth lines that failed to parse or lacked fields
    uint64_t truth_ignored;  ///< truth records of a type the bridge does not translate
} lb_stats_t;

typedef struct lb lb_t;

/// Size of lb_t in bytes (allocate that much, aligned for max_align_t).
size_t lb_size(void);

/// Initialises *st (all groups empty, no calibration, sim time 0). sink must
/// be non-NULL. Returns 0, or -1 on a NULL argument.
int lb_init(lb_t *st, lb_time_mode_t mode, lb_sink_fn sink, void *sink_ctx);

/// Feeds one frame seen at frame_time_us (used in LB_TIME_FRAME mode only).
/// Publishes what the frame completes; updates the sim clock on SIM_CLOCK.
/// HALL_READING frames are collected per electrode into one hall_t while the
/// clock (lb_now_us) stays the same, up to LB_HALL_BATCH readings; a batch
/// goes out when the clock moves on, when it is full, before a new
/// calibration of its electrode is published, and at lb_flush.
/// O(LB_MAX_ELECTRODES) except at a group flush, O(tracks × wave + spikes).
void lb_feed_frame(lb_t *st, const md_frame_t *frame, int64_t frame_time_us);

/// The time that stamps the next message (µs): sim clock or last frame time.
int64_t lb_now_us(const lb_t *st);

/// Publishes every open cycle group (end of input), the pending Hall batches
/// and the pending truth batches. Idempotent.
void lb_flush(lb_t *st);

/// Ground truth: the time (µs) a truth JSON line stands for, without
/// publishing it (session/neuron 0, spike sample / sample rate, state/death
/// t_s); -1 if the line is not a truth record. Uses the sample rate of the
/// session record already fed.
int64_t lb_truth_time_us(const lb_t *st, const char *line);

/// Feeds one truth JSON line (docs/simulator.md section 6). Session and neuron
/// records are collected and published as one truth_session_t at the first
/// other record (or at lb_flush); spikes are batched (LB_TRUTH_SPIKE_BATCH, one
/// electrode, uninterrupted run); state and death go out at once. Blank lines
/// are skipped; records of other types are counted in truth_ignored. Returns
/// 0, or -1 on a line that failed to parse, lacks a required field, or has a
/// value its LCM field cannot hold: an electrode not a whole number 0..127, a
/// neuron id outside int32, a sample outside 0..2^63, a non-finite t_s, a
/// sample_rate_hz not > 0, a seed outside -2^63..2^64 (counted; nothing of
/// the record is published).
int lb_feed_truth_line(lb_t *st, const char *line);

/// Counters so far.
const lb_stats_t *lb_stats(const lb_t *st);

#endif
