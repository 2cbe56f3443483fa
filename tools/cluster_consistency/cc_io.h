/// @file cc_io.h
/// Reading a simulator export (host_sim/export/sim_export.h) for the
/// clustering-consistency experiment: the JSON sidecar (parsed with cJSON),
/// one channel of one interval from recording.bin, and ground_truth.csv.
/// Host code: stdio and heap are fine here.
#ifndef CC_IO_H
#define CC_IO_H

#include <stddef.h>
#include <stdint.h>

#include "common/md_status.h"

#define CC_MAX_INTERVALS 512u ///< intervals read from one sidecar
#define CC_MAX_CHANNELS 16u   ///< channels of one recording

/// One recording interval of the sidecar.
typedef struct {
    uint64_t start_sample;             ///< first sample (per channel) in recording.bin
    uint32_t num_samples;              ///< samples per channel
    double start_s;                    ///< simulated time of its start
    double duration_s;
    double depth_um[CC_MAX_CHANNELS];  ///< true tip depth per channel at its start
} cc_interval_t;

/// The sidecar recording.json.
typedef struct {
    double fs_hz;
    uint32_t n_channels;
    double gain_uv;                    ///< microvolts per ADC count
    char scenario[64];
    uint64_t seed;
    uint32_t n_intervals;
    cc_interval_t iv[CC_MAX_INTERVALS];
} cc_recording_t;

/// Ground-truth spikes of one channel, ascending sample index.
typedef struct {
    uint64_t *sample;   ///< trough sample (per channel) in recording.bin
    int32_t *neuron;    ///< neuron id (>= 0)
    size_t n;
    int32_t max_neuron; ///< largest id seen, -1 if none
} cc_truth_t;

/// Parses DIR/recording.json. MD_E_IO if unreadable, MD_E_FRAME if a field
/// is missing or out of range (message in err).
md_status_t cc_read_sidecar(const char *dir, cc_recording_t *rec, char *err, size_t errlen);

/// Reads channel `ch` of interval `k` into x (rec->iv[k].num_samples values,
/// caller-owned). MD_E_IO on a short file.
md_status_t cc_read_interval(const char *dir, const cc_recording_t *rec, uint32_t k, uint32_t ch, int16_t *x,
                             size_t cap);

/// Loads the spikes of channel `ch` from DIR/ground_truth.csv (heap;
/// release with cc_truth_free). A missing file gives an empty truth (MD_OK).
md_status_t cc_read_truth(const char *dir, uint32_t ch, cc_truth_t *truth);

void cc_truth_free(cc_truth_t *truth);

/// Index of the first truth spike with sample >= s (binary search).
size_t cc_truth_lower_bound(const cc_truth_t *truth, uint64_t s);

#endif
