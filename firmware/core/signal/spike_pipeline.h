/// @file spike_pipeline.h
/// One channel's streaming signal chain front end: detection
/// (spike_detect.h) and extraction (spike_extract.h) driven together, chunk
/// by chunk, as CAN FD frames of samples arrive.
///
/// The pipeline feeds the detector in steps that end on multiples of
/// SD_STEP_SAMPLES of the sample index and services the extractor after
/// every step, so windows, snippets and counters are identical whatever the
/// chunk sizes (1, 30, 4096 samples ... all give the same result).
///
/// Memory: sp_channel_t (~26 kB) per channel plus the caller's outputs
/// sx_windows_t (~50 kB) and sx_snippets_t (~25 kB) at the default
/// capacities; nothing else.
///
/// Use: sp_init() once per channel; per interval sp_push() every chunk,
/// sp_finish(), read sp_events() and the bound outputs, then sp_restart().
#ifndef SPIKE_PIPELINE_H
#define SPIKE_PIPELINE_H

#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "signal/spike_detect.h"
#include "signal/spike_extract.h"

/// Streaming detector and extractor of one channel (caller-owned; private).
typedef struct {
    sd_stream_t det;
    sx_stream_t ext;
    int16_t
        stage[8u *
              SD_STEP_SAMPLES]; /* step slots: samples waiting for a full step (frames of 30 do not align with 32) */
    uint32_t n_stage;           /* samples of the current step in slot `slot` */
    uint32_t slot;              /* the current step's slot; the next step follows it in the stage */
    int state;
} sp_channel_t;

/// Validates both configurations and binds the outputs, which must outlive
/// the channel. MD_E_ARG on an invalid parameter (see sd_stream_init,
/// sx_stream_init). O(scales * box).
md_status_t sp_init(sp_channel_t *ch, const sd_config_t *dcfg, const sx_config_t *xcfg, sx_windows_t *win,
                    sx_snippets_t *noise);

/// Starts a new interval (clears events and outputs). O(1).
md_status_t sp_restart(sp_channel_t *ch);

/// Streams a chunk (any length, n == 0 allowed). Samples are staged until a
/// whole SD_STEP_SAMPLES step is available, so the detector always runs
/// full steps (the per-step overhead is paid once per 32 samples). MD_E_DEGENERATE if the
/// warm-up was flat (the chunk is consumed, nothing is detected);
/// MD_E_CAPACITY beyond SD_MAX_INTERVAL_SAMPLES; MD_E_STATE after
/// sp_finish(). O(n * scales), plus the warm-up replay once per interval.
md_status_t sp_push(sp_channel_t *ch, const int16_t *x, size_t n);

/// Ends the interval: flushes the detector, cuts the last windows and
/// confirms the last snippets. MD_E_DEGENERATE if the interval was too short
/// or flat, or no noise snippet could be placed (outputs are still valid).
md_status_t sp_finish(sp_channel_t *ch);

/// Events of the interval (final after sp_finish; committed ones before).
const sd_events_t *sp_events(const sp_channel_t *ch);

#endif
