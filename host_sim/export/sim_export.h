/// @file sim_export.h
/// Export a simulated recording in the binary convention of Kilosort, Phy and
/// SpikeInterface.
///
/// In export mode no firmware drives the electrodes: the simulator moves every
/// electrode along the scenario's scripted trajectory — record
/// export.interval_s, move by export.step_um (actuator at its max rate), wait
/// for the move to end plus export.settle_s, repeat export.intervals times.
/// Files written into `dir` (created if missing):
///  - recording.bin: int16 little-endian, channels interleaved
///    (sample 0 of ch 0, ch 1, ..., sample 1 of ch 0, ...), only the recorded
///    intervals, back to back;
///  - recording.json: sampling_frequency, num_channels, num_samples, dtype
///    "int16", gain_uV, offset_uV, seed, scenario name, and per interval its
///    start sample in the file, num_samples, start_s (simulated time),
///    duration_s, true depth_um per channel at its start and end, and the
///    depth read from the Hall sensor through its calibration;
///  - ground_truth.csv: `sample_index,channel,neuron_id` (sample index into
///    recording.bin), one row per neuron spike, ordered by sample, channel,
///    neuron (large artifacts are not neuron spikes: they are in the jsonl);
///  - ground_truth.jsonl: the session's full truth (see sim_world.h), with a
///    `state` record at the start of every interval.
/// Same scenario + seed -> byte-identical files.
#ifndef SIM_EXPORT_H
#define SIM_EXPORT_H

#include <stddef.h>
#include <stdint.h>

#include "scenario/scenario.h"

/// Writes the recording of `sc` with `seed` into `dir`. Returns MD_OK, or
/// MD_E_ARG / MD_E_IO / a model error with a one-line reason in err.
md_status_t sim_export_recording(const scenario_t *sc, uint64_t seed, const char *dir, char *err, size_t errlen);

#endif
