/// @file lb_internal.h
/// State of the bridge core, shared by lcm_bridge.c (CAN) and lb_truth.c
/// (ground truth). Private to tools/lcm_bridge.
#ifndef LB_INTERNAL_H
#define LB_INTERNAL_H

#include "lcm_bridge.h"
#include "md_can.h"

#define LB_WAVE_MAX_LEN (LB_WAVE_PART_LEN * LB_MAX_WAVE_PARTS)

/// Mean waveform parts received for one track id in the current group.
typedef struct {
    uint16_t track_id;
    uint8_t parts_mask;  ///< bit p: part p received
    int16_t wave_uv[LB_WAVE_MAX_LEN];
} lb_wave_t;

/// Everything one electrode's controller sent about one cycle
/// (TLM_CYCLE, TLM_TRACK, TLM_WAVE, TLM_HYP, TLM_SPIKES, TLM_STATUS).
typedef struct {
    bool open;    ///< a frame of this cycle arrived, group not yet published
    bool closed;  ///< published; later frames of the same cycle are late
    uint16_t cycle;
    int64_t utime;  ///< time of the last frame added
    bool have_status;
    struct md_can_tlm_status_t status;
    bool have_cycle;  ///< a TLM_CYCLE of this cycle (phase 1 preferred)
    struct md_can_tlm_cycle_t cyc;
    bool track_have[LB_MAX_TRACKS];
    struct md_can_tlm_track_t track[LB_MAX_TRACKS];
    size_t n_waves;
    lb_wave_t wave[LB_MAX_TRACKS];
    bool hyp_have[LB_MAX_HYPS];
    struct md_can_tlm_hyp_t hyp[LB_MAX_HYPS];
    uint32_t spike_frames;  ///< TLM_SPIKES parts received (the controller sends >= 1, last)
    uint8_t spike_have[LB_MAX_SPIKES];
    uint32_t spike_sample[LB_MAX_SPIKES];
    int16_t spike_track[LB_MAX_SPIKES];
} lb_group_t;

/// HALL_CALIB coefficients of one electrode as they arrive.
typedef struct {
    uint8_t count;       ///< CoeffCount of the set being collected
    uint32_t have_mask;  ///< bit k: coefficient k; bit 16 mid, bit 17 half
    float coeff[LB_MAX_CALIB_COEFFS];
    float code_mid, code_half;
    bool valid;  ///< a complete set is in `pub_*`
    uint8_t pub_count;
    double pub_coeff[LB_MAX_CALIB_COEFFS];
    double pub_mid, pub_half;
} lb_calib_t;

/// HALL_READING frames of one electrode at one bridge time, not yet published.
typedef struct {
    int16_t n;        ///< readings held (0 = none pending)
    int64_t utime;    ///< the bridge time they share
    bool calibrated;  ///< depth_um from a complete calibration
    uint8_t seq[LB_HALL_BATCH];
    int32_t raw_code[LB_HALL_BATCH];
    int64_t sample_time_ms[LB_HALL_BATCH];
    double depth_um[LB_HALL_BATCH];
} lb_hall_batch_t;

/// Truth session and neuron records, published together.
typedef struct {
    bool have_session;
    bool published;
    int64_t seed;
    double sample_rate_hz;
    int16_t n_electrodes;
    float bg_rms_uv[LB_MAX_ELECTRODES];
    int32_t n_neurons;
    int8_t electrode[LB_TRUTH_MAX_NEURONS];
    int32_t neuron[LB_TRUTH_MAX_NEURONS];
    float x_um[LB_TRUTH_MAX_NEURONS], y_um[LB_TRUTH_MAX_NEURONS], depth_um[LB_TRUTH_MAX_NEURONS];
    float amp_uv[LB_TRUTH_MAX_NEURONS], rate_hz[LB_TRUTH_MAX_NEURONS];
    char shape[LB_TRUTH_MAX_NEURONS][16];
} lb_truth_session_t;

/// A run of truth spike records of one electrode.
typedef struct {
    int32_t n;
    int8_t electrode;
    int64_t sample[LB_TRUTH_SPIKE_BATCH];
    int32_t neuron[LB_TRUTH_SPIKE_BATCH];
    float amp_uv[LB_TRUTH_SPIKE_BATCH];
} lb_truth_batch_t;

struct lb {
    lb_time_mode_t mode;
    lb_sink_fn sink;
    void *sink_ctx;
    int64_t sim_time_us;
    int64_t frame_time_us;
    lb_stats_t stats;
    lb_group_t group[LB_MAX_ELECTRODES];
    lb_calib_t calib[LB_MAX_ELECTRODES];
    lb_hall_batch_t hall[LB_MAX_ELECTRODES];
    lb_truth_session_t truth;
    lb_truth_batch_t batch;
};

/// Hands an encoded message to the sink and counts it.
void lb_emit(lb_t *st, const char *channel, int64_t utime, const uint8_t *data, int len);

/// Publishes the pending truth session and spike batch (lb_flush's truth part).
void lb_truth_flush(lb_t *st);

/// Encodes msg of lcm-gen type T into a heap buffer and emits it.
#define LB_PUBLISH(st, channel, T, msg)                       \
    do {                                                      \
        const int n_ = T##_encoded_size(msg);                 \
        uint8_t *b_ = (n_ > 0) ? malloc((size_t)n_) : NULL;   \
        if (b_ != NULL && T##_encode(b_, 0, n_, msg) == n_) { \
            lb_emit((st), (channel), (msg)->utime, b_, n_);   \
        } else {                                              \
            (st)->stats.sink_errors++;                        \
        }                                                     \
        free(b_);                                             \
    } while (0)

#endif
