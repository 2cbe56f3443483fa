/// @file rp_io.h
/// Input of mhtc-replay: the JSON sidecar of a raw int16 recording (parsed
/// with cJSON), one channel of one interval from the binary file, and the
/// optional ground truth. Host code: stdio and heap are fine here.
#ifndef RP_IO_H
#define RP_IO_H

#include <stddef.h>
#include <stdint.h>

#define RP_MAX_INTERVALS 4096u  ///< intervals of one recording
#define RP_PATH_MAX 1024u

/// One interval of the recording (per-channel sample indices).
typedef struct {
    uint64_t start_sample;
    uint64_t num_samples;
    double duration_s;
    double depth_um;          ///< NaN when the sidecar has no depth
} rp_interval_t;

/// The sidecar and where the samples are.
typedef struct {
    char bin_path[RP_PATH_MAX];
    char dir[RP_PATH_MAX];
    double fs_hz;
    uint32_t n_channels;
    double gain_uv;
    uint64_t total_samples;   ///< per channel, from the file size
    uint32_t n_intervals;
    rp_interval_t iv[RP_MAX_INTERVALS];
} rp_recording_t;

/// Reads `json_path` and sizes the binary next to it (recording.bin, or the
/// sidecar's "file"). Without an "intervals" list, the signal is cut into
/// consecutive intervals of interval_s seconds (a last partial one is kept if
/// it is at least half as long). Returns 0, or -1 with "file: field: reason" in err.
int rp_read_recording(const char *json_path, double interval_s, uint32_t channel, rp_recording_t *rec, char *err,
                      size_t errlen);

/// Reads channel `ch` of interval k into x (rec->iv[k].num_samples values). 0 or -1 (err).
int rp_read_interval(const rp_recording_t *rec, uint32_t k, uint32_t ch, int16_t *x, char *err, size_t errlen);

#endif
