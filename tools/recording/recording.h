/// @file recording.h
/// The one reader of a raw recording and its JSON sidecar for the host tools
/// (mhtc-replay, cluster-consistency). Host code: stdio and heap are fine.
///
/// A recording is a headerless binary of interleaved little-endian samples
/// (`recording.bin` next to the sidecar, or the sidecar's `"file"`) and a JSON
/// sidecar (`recording.json`, the Kilosort/SpikeInterface binary convention the
/// simulator's export writes; parsed with Debian's cJSON). Sidecar fields:
///
/// | field | | meaning |
/// |---|---|---|
/// | `sampling_frequency` | required | Hz, 1000..200000 |
/// | `num_channels` | required | integer 1..REC_MAX_CHANNELS |
/// | `dtype` | required | `"int16"` or `"float32"` |
/// | `gain_uV` | optional, 1 | µV per unit of a stored sample, finite and > 0 |
/// | `offset_uV` | optional | finite; not applied (the signal chain removes each window's offset) |
/// | `byte_order` | optional | `"little"` only |
/// | `layout` | optional | `"interleaved"` only |
/// | `num_samples` | optional | samples per channel; must match the binary's size |
/// | `file` | optional | the binary, relative to the sidecar's folder unless absolute |
/// | `scenario`, `seed` | optional | simulator provenance (`"?"`, 0) |
/// | `intervals` | optional | list of {`start_sample`, `num_samples` (required, integers), `duration_s` (> 0), `depth_um` and `hall_code` (each a number, or one per channel; null = unknown)} |
///
/// Other fields are not read and may be anything: the simulator's export adds
/// `index`, `start_s`, `depth_end_um`, `sensor_depth_um` to each interval;
/// microdrive-session's recording adds `source`, `electrode` and, per
/// interval, `index`, `start_s`, `interval_id`, `cycle`, `complete`
/// (docs/session.md "The recording").
///
/// Without an `intervals` list (or with an empty one) the signal is cut into
/// consecutive intervals of rec_options_t.interval_s seconds; a last partial
/// interval is kept if it is at least half as long.
///
/// **Samples the tracker takes.** The firmware's signal chain works on int16
/// counts plus a gain (µV per count), so rec_read_interval() always delivers
/// int16 counts and rec_recording_t.count_uv is their gain:
///  - `int16`: the stored counts, count_uv = gain_uV (nothing is converted);
///  - `float32`: a stored value v stands for v · gain_uV µV (so without
///    `gain_uV`, or with 1, the file is in µV). It becomes the count
///    round(v · gain_uV / count_uv) with count_uv = min(gain_uV, 1 µV): the
///    values are whole counts of a coarser-than-1-µV unit as stored, else
///    steps of 1 µV (range ±32.8 mV). round() is to nearest, halves away from
///    zero, computed in double. A result outside -32768..32767 is clipped to
///    the nearest end and counted in rec_conversion_t.clipped; a NaN or
///    infinite value becomes 0 and is counted in .non_finite. Callers report
///    both counts; neither is ever dropped silently.
///
/// Errors: every function writes one line "PATH: reason" into err (no newline):
/// the file, the field or byte offset, and what is wrong. Control bytes (a
/// "file" field may name a path with any) are written as \xNN.
#ifndef RECORDING_H
#define RECORDING_H

#include <stddef.h>
#include <stdint.h>

#include "md_status.h"

#define REC_MAX_INTERVALS 4096u  ///< intervals of one recording
#define REC_MAX_CHANNELS 1024u   ///< channels of one recording
#define REC_PATH_MAX 1024u       ///< longest path of the binary
#define REC_ERR_MAX \
    (2u * REC_PATH_MAX + 256u)  ///< err buffer that holds any message whole (unless control bytes are escaped)
#define REC_FS_MIN_HZ 1000.0
#define REC_FS_MAX_HZ 200000.0
#define REC_F32_MAX_COUNT_UV 1.0  ///< float32: coarsest int16 step (µV per count)

/// Sample type of the binary.
typedef enum { REC_DTYPE_INT16 = 0, REC_DTYPE_FLOAT32 = 1 } rec_dtype_t;

/// One interval (sample indices are per channel).
typedef struct {
    uint64_t start_sample;
    uint64_t num_samples;
    double duration_s;  ///< the sidecar's, else num_samples / fs
    double depth_um;    ///< depth of rec_options_t.channel; NaN when the sidecar has none
    double hall_code;   ///< Hall sensor reading (raw code) of that channel; NaN when the sidecar has none
} rec_interval_t;

/// What to read.
typedef struct {
    double interval_s;  ///< cut length without an "intervals" list; <= 0: the list is required
    uint32_t channel;   ///< channel whose depth is kept; must exist (MD_E_ARG otherwise)
} rec_options_t;

/// A sidecar and where its samples are (about 160 kB: give it static storage).
typedef struct {
    char json_path[REC_PATH_MAX];
    char bin_path[REC_PATH_MAX];
    double fs_hz;
    uint32_t n_channels;
    rec_dtype_t dtype;
    double gain_uv;          ///< sidecar gain_uV: µV per unit of a stored sample
    double count_uv;         ///< µV per int16 count delivered by rec_read_interval
    char scenario[64];       ///< "?" when absent
    uint64_t seed;           ///< 0 when absent
    uint64_t total_samples;  ///< per channel, from the binary's size
    int interval_list;       ///< 1: intervals from the sidecar, 0: cut by interval_s
    uint32_t n_intervals;
    rec_interval_t iv[REC_MAX_INTERVALS];
} rec_recording_t;

/// Conversion counts of float32 samples (rec_read_interval adds to them).
typedef struct {
    uint64_t clipped;     ///< rounded value outside -32768..32767, set to the nearest end
    uint64_t non_finite;  ///< NaN or infinite value, set to 0
} rec_conversion_t;

/// Reads the sidecar at json_path, checks it and sizes the binary. Returns
/// MD_OK; MD_E_IO if a file cannot be opened or read; MD_E_FRAME if the
/// sidecar or the binary's size is invalid; MD_E_ARG on NULL arguments or an
/// opt->channel the recording does not have. The message is in err.
md_status_t rec_read_sidecar(const char *json_path, const rec_options_t *opt, rec_recording_t *rec, char *err,
                             size_t errlen);

/// Reads channel ch of interval k as int16 counts of rec->count_uv µV into
/// x[0 .. rec->iv[k].num_samples) (cap: room in x), adding float32
/// conversion counts to *conv. MD_E_ARG on a bad k, ch, cap or NULL;
/// MD_E_IO if the binary cannot be read (message in err).
md_status_t rec_read_interval(const rec_recording_t *rec, uint32_t k, uint32_t ch, int16_t *x, size_t cap,
                              rec_conversion_t *conv, char *err, size_t errlen);

/// "int16" or "float32".
const char *rec_dtype_name(rec_dtype_t dtype);

#endif
