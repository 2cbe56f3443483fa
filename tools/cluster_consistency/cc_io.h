/// @file cc_io.h
/// Ground truth of a simulator export (host_sim/export/sim_export.h) for the
/// clustering-consistency experiment: the spikes of ground_truth.csv. The
/// recording itself (recording.json, recording.bin) is read with
/// tools/recording (recording.h). Host code: stdio and heap are fine here.
#ifndef CC_IO_H
#define CC_IO_H

#include <stddef.h>
#include <stdint.h>

#include "md_status.h"

/// Ground-truth spikes of one channel, ascending sample index.
typedef struct {
    uint64_t *sample;  ///< trough sample (per channel) in recording.bin
    int32_t *neuron;   ///< neuron id (>= 0)
    size_t n;
    int32_t max_neuron;  ///< largest id seen, -1 if none
} cc_truth_t;

/// The exporter's header line.
#define CC_TRUTH_HEADER "sample_index,channel,neuron_id"

/// Loads the spikes of channel `ch` from DIR/ground_truth.csv (heap;
/// release with cc_truth_free). A missing file gives an empty truth (MD_OK).
/// Every line is a record SAMPLE,CHANNEL,NEURON (decimal integers that fit
/// uint64, uint32 and int32; NEURON < 0 is an artifact and left out), except
/// CC_TRUTH_HEADER as the first line and empty lines; "\r\n" endings are
/// fine. Records of channel ch must come in ascending SAMPLE order. Returns
/// MD_OK; MD_E_FRAME for a line that breaks these rules, MD_E_CAPACITY when
/// memory runs out, MD_E_IO on a read error, with "PATH:LINE: reason" in err
/// (may be NULL) and an empty truth.
md_status_t cc_read_truth(const char *dir, uint32_t ch, cc_truth_t *truth, char *err, size_t errlen);

void cc_truth_free(cc_truth_t *truth);

/// Index of the first truth spike with sample >= s (binary search).
size_t cc_truth_lower_bound(const cc_truth_t *truth, uint64_t s);

#endif
