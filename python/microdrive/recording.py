"""Recordings in the project's format (tools/recording/recording.h is the reference, docs/mhtc.md):
a headerless little-endian binary of interleaved samples, `recording.bin`, next to a JSON sidecar,
`recording.json`, with at least sampling_frequency, num_channels and dtype ("int16", or "float32" in
units of gain_uV uV)."""
import inspect
import json
import os

import numpy as np

CHUNK_S = 10.0   # seconds of signal read from a SpikeInterface recording at a time


class MicrodriveError(Exception):
    """A recording could not be written or read, or mhtc-replay could not be found or failed; the
    message names the file or executable and the reason."""


def _scaled_kwarg():
    """The keyword of BaseRecording.get_traces that asks for uV (renamed across SpikeInterface releases)."""
    import spikeinterface.core as si
    params = inspect.signature(si.BaseRecording.get_traces).parameters
    return "return_in_uV" if "return_in_uV" in params else "return_scaled"


def traces_uv(recording, channels=None, segment_index=0, start_frame=0, end_frame=None):
    """Traces of `recording` (a SpikeInterface BaseRecording, any dtype) in uV as float32,
    samples x channels. A recording with gains is scaled by SpikeInterface; one without gains
    (e.g. generate_drifting_recording's) is taken to be in uV already."""
    ids = recording.get_channel_ids()
    chan_ids = ids if channels is None else [ids[c] for c in channels]
    kw = {_scaled_kwarg(): True} if recording.has_scaleable_traces() else {}
    x = recording.get_traces(segment_index=segment_index, start_frame=start_frame, end_frame=end_frame,
                             channel_ids=chan_ids, **kw)
    return np.asarray(x, dtype=np.float32)


def write_samples(outdir, x_uv, sampling_frequency, gain_uV=None, extra=None):
    """Writes samples x channels `x_uv` (uV) as OUTDIR/recording.bin + recording.json.

    gain_uV None: float32 in uV (mhtc-replay rounds to 1 uV counts); a gain: int16 counts of gain_uV
    uV, rounded to nearest and clipped to -32768..32767, the count of clipped samples in the sidecar's
    "clipped_samples". `extra` entries are added to the sidecar. Returns the number of clipped samples
    (0 for float32)."""
    x_uv = np.asarray(x_uv)
    if x_uv.ndim == 1:
        x_uv = x_uv[:, np.newaxis]
    os.makedirs(outdir, exist_ok=True)
    clipped = 0
    if gain_uV is None:
        data, dtype, gain = x_uv.astype("<f4"), "float32", 1.0
    else:
        y = np.round(x_uv.astype(np.float64) / gain_uV)
        clipped = int(np.sum((y > 32767) | (y < -32768)))
        data, dtype, gain = np.clip(y, -32768, 32767).astype("<i2"), "int16", float(gain_uV)
    data.tofile(os.path.join(outdir, "recording.bin"))
    side = {"sampling_frequency": float(sampling_frequency), "num_channels": int(x_uv.shape[1]),
            "num_samples": int(x_uv.shape[0]), "dtype": dtype, "gain_uV": gain, "offset_uV": 0.0,
            "byte_order": "little", "layout": "interleaved"}
    if gain_uV is not None:
        side["clipped_samples"] = clipped
    side.update(extra or {})
    with open(os.path.join(outdir, "recording.json"), "w") as f:
        json.dump(side, f, indent=1)
    return clipped


def write_recording(recording, outdir, channel=0, segment_index=0):
    """Writes channel `channel` of a SpikeInterface recording (segment `segment_index`) as a float32
    recording in uV in OUTDIR, read in CHUNK_S pieces. Returns the sidecar's path."""
    nch = recording.get_num_channels()
    if not 0 <= channel < nch:
        raise MicrodriveError(f"channel {channel}: the recording has {nch} channel(s)")
    if not 0 <= segment_index < recording.get_num_segments():
        raise MicrodriveError(f"segment {segment_index}: the recording has {recording.get_num_segments()}")
    fs = recording.get_sampling_frequency()
    n = recording.get_num_samples(segment_index=segment_index)
    os.makedirs(outdir, exist_ok=True)
    step = max(1, int(CHUNK_S * fs))
    with open(os.path.join(outdir, "recording.bin"), "wb") as f:
        for s0 in range(0, n, step):
            x = traces_uv(recording, [channel], segment_index, s0, min(n, s0 + step))
            x.astype("<f4").tofile(f)
    side = {"sampling_frequency": float(fs), "num_channels": 1, "num_samples": int(n), "dtype": "float32",
            "gain_uV": 1.0, "offset_uV": 0.0, "byte_order": "little", "layout": "interleaved",
            "source": {"channel_id": str(recording.get_channel_ids()[channel]), "segment_index": segment_index}}
    path = os.path.join(outdir, "recording.json")
    with open(path, "w") as f:
        json.dump(side, f, indent=1)
    return path


def read_sidecar(path):
    """The sidecar at `path` (a recording.json or the folder holding it) as a dict, with "file" resolved
    to the binary's absolute path. Checks what SpikeInterface needs to open it; the full checks are
    mhtc-replay's (tools/recording)."""
    if os.path.isdir(path):
        path = os.path.join(path, "recording.json")
    try:
        with open(path) as f:
            side = json.load(f)
    except (OSError, ValueError) as e:
        raise MicrodriveError(f"{path}: cannot read the sidecar ({e})")
    for k in ("sampling_frequency", "num_channels", "dtype"):
        if k not in side:
            raise MicrodriveError(f"{path}: field {k!r} missing")
    if side["dtype"] not in ("int16", "float32"):
        raise MicrodriveError(f"{path}: dtype {side['dtype']!r}, expected \"int16\" or \"float32\"")
    b = side.get("file", "recording.bin")
    side["file"] = b if os.path.isabs(b) else os.path.join(os.path.dirname(os.path.abspath(path)), b)
    side["_path"] = os.path.abspath(path)
    return side


def read_recording(path):
    """A recording in the project's format (`recording.json` or its folder: a simulator export, a
    session's recording, one written here) as a SpikeInterface BinaryRecordingExtractor with gains to
    uV. Its sidecar's interval list, if any, is the annotation "intervals"."""
    import spikeinterface.core as si
    side = read_sidecar(path)
    rec = si.read_binary(side["file"], sampling_frequency=side["sampling_frequency"], dtype=side["dtype"],
                         num_channels=side["num_channels"], gain_to_uV=side.get("gain_uV", 1.0),
                         offset_to_uV=side.get("offset_uV", 0.0))
    if "num_samples" in side and rec.get_num_samples() != side["num_samples"]:
        raise MicrodriveError(f"{side['file']}: {rec.get_num_samples()} samples per channel, "
                              f"{side['_path']} says {side['num_samples']}")
    rec.annotate(intervals=list(side.get("intervals", [])))
    return rec
