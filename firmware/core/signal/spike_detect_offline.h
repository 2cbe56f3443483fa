/// @file spike_detect_offline.h
/// The OFFLINE CONVENIENCE PATH of the spike detector: sd_detector_t streams
/// an interval through an sd_stream_t (spike_detect.h) and also copies it
/// into a caller-owned buffer, so that the buffer-based extractors of
/// spike_extract.h can be used afterwards. For tests and offline tools; the
/// firmware runs the stream (spike_pipeline.h).
#ifndef SPIKE_DETECT_OFFLINE_H
#define SPIKE_DETECT_OFFLINE_H

#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "signal/spike_detect.h"

/// Detector with an interval copy. Caller-owned; treat members as private.
typedef struct {
    sd_stream_t s;
    int16_t *buf;
    size_t cap;
    size_t n;
    uint32_t n_dropped;
    int state;
} sd_detector_t;

/// OFFLINE CONVENIENCE PATH. Validates `cfg` and binds the caller's interval
/// buffer `buf` of `cap` samples (1..SD_MAX_INTERVAL_SAMPLES), which must
/// outlive the detector. MD_E_ARG on an invalid parameter.
md_status_t sd_init(sd_detector_t *det, const sd_config_t *cfg, int16_t *buf, size_t cap);

/// OFFLINE CONVENIENCE PATH. Starts a new interval. O(1).
md_status_t sd_restart(sd_detector_t *det);

/// OFFLINE CONVENIENCE PATH. Copies a chunk into the buffer and streams it
/// into the detector. If the buffer fills, the samples that fit are kept,
/// the rest are counted as dropped and MD_E_CAPACITY is returned (sd_finish
/// then sets SD_FLAG_TRUNCATED). MD_E_STATE after sd_finish(). O(n).
md_status_t sd_push(sd_detector_t *det, const int16_t *samples, size_t n);

/// OFFLINE CONVENIENCE PATH. Ends the interval and copies the events into
/// `ev`. MD_E_DEGENERATE if the interval is too short for the filters or
/// its noise level is zero (a flat channel); MD_E_STATE if called twice.
md_status_t sd_finish(sd_detector_t *det, sd_events_t *ev);

/// OFFLINE CONVENIENCE PATH. The buffered samples of the current interval
/// and their count (NULL if `det` is NULL). Valid until sd_restart().
const int16_t *sd_samples(const sd_detector_t *det, size_t *n);

#endif
