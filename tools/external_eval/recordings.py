"""One-channel recordings made by SpikeInterface's own generators, in the project's recording format.

A generated multi-channel recording is reduced to one channel: the first channel (lowest index) on which
2..5 units are *visible*, i.e. whose mean waveform on that channel reaches VISIBLE_X times the channel's
noise level. Noise level = the median-absolute-deviation estimate median(|x|) / 0.6745 of the whole
channel's trace in uV (spikes included; the estimator the peer's and most sorters' thresholds use). A
unit's mean waveform on the channel is the average of the trace over its ground-truth spike times (up to
MAX_MEAN_SPIKES of them, evenly spread over the session), window [-1 ms, +2 ms] around the spike time,
and its amplitude is the largest |value| of that mean. With drift this is the session's mean waveform.

Written into the recording directory (the recording by microdrive.write_samples, python/microdrive):
  recording.bin      int16 little-endian, one channel (what mhtc-replay and the peer read)
  recording.json     sampling_frequency, num_channels (1), num_samples, dtype "int16", gain_uV,
                     offset_uV, clipped_samples, plus where it came from (generator, seed, channel,
                     noise_uV)
  ground_truth.csv   sample_index,unit_id of every ground-truth spike (all units)
  units.json         per unit: visible, amplitude_uV on the channel (and in noise levels), rate_hz,
                     spikes, nearest_visible_x_noise = L2 distance of its mean waveform on the channel
                     ([-1, +2] ms) to the nearest other visible unit's, divided by the noise level
"""
import csv
import json
import os

import numpy as np

import microdrive  # python/microdrive: the project's recording writer and replay runner

FS = 30000.0
GAIN_UV = 0.195              # uV per int16 step, the simulator's ADC gain (host_sim/model/signal.c)
VISIBLE_X = 6.0              # a unit is visible when its mean-waveform amplitude >= VISIBLE_X * noise
MIN_VISIBLE, MAX_VISIBLE = 2, 5
MAX_MEAN_SPIKES = 2000
CHUNK_S = microdrive.recording.CHUNK_S

# Eight contacts, two columns of four, 20 um pitch (generate_ground_truth_recording's own default probe
# layout, made explicit so that both generators use the same probe).
PROBE_KWARGS = dict(num_columns=2, num_contact_per_column=4, xpitch=20, ypitch=20, contact_shapes="circle",
                    contact_shape_params={"radius": 6})
NUM_CHANNELS = 8
FIRING_RATES = (2.0, 8.0)    # uniform per unit: generate_drifting_recording's default range, used for both


class RecordingError(Exception):
    """A recording could not be made or read (message names the file or seed and the reason)."""


def static_params(duration_s, seed):
    return dict(kind="static", generator="spikeinterface.core.generate_ground_truth_recording", seed=seed,
                duration_s=duration_s, sampling_frequency=FS, num_channels=NUM_CHANNELS, num_units=8,
                noise_uV=10.0, firing_rates_hz=list(FIRING_RATES))


def drifting_params(duration_s, seed):
    return dict(kind="drifting", generator="spikeinterface.generation.generate_drifting_recording", seed=seed,
                duration_s=duration_s, sampling_frequency=FS, num_channels=NUM_CHANNELS, num_units=5,
                noise_uV=10.0, firing_rates_hz=list(FIRING_RATES), drift_um=6.0, drift_mode="zigzag",
                drift_start_s=60.0 if duration_s > 120.0 else 0.0, drift_period_s=200.0 if duration_s > 120.0
                else duration_s)


def generate(params):
    """(recording, sorting) of SpikeInterface for `params` (static_params / drifting_params)."""
    import spikeinterface.core as si
    if params["kind"] == "static":
        return si.generate_ground_truth_recording(
            durations=[params["duration_s"]], sampling_frequency=params["sampling_frequency"],
            num_channels=params["num_channels"], num_units=params["num_units"],
            generate_probe_kwargs=PROBE_KWARGS,
            generate_sorting_kwargs=dict(firing_rates=tuple(params["firing_rates_hz"]), refractory_period_ms=4.0),
            noise_kwargs=dict(noise_levels=params["noise_uV"], strategy="on_the_fly"), seed=params["seed"])
    if params["kind"] == "drifting":
        import spikeinterface.generation as sg
        d = params["drift_um"]
        _, drifting, sorting = sg.generate_drifting_recording(
            num_units=params["num_units"], duration=params["duration_s"],
            sampling_frequency=params["sampling_frequency"], generate_probe_kwargs=PROBE_KWARGS,
            generate_displacement_vector_kwargs=dict(
                displacement_sampling_frequency=5.0, drift_start_um=[0, d], drift_stop_um=[0, -d],
                drift_step_um=1,
                motion_list=[dict(drift_mode=params["drift_mode"], non_rigid_gradient=None,
                                  t_start_drift=params["drift_start_s"], t_end_drift=None,
                                  period_s=params["drift_period_s"])]),
            generate_sorting_kwargs=dict(firing_rates=tuple(params["firing_rates_hz"]), refractory_period_ms=4.0),
            generate_noise_kwargs=dict(noise_levels=params["noise_uV"], spatial_decay=25.0), seed=params["seed"])
        return drifting, sorting
    raise RecordingError(f"seed {params.get('seed')}: unknown recording kind {params['kind']!r}")


def traces_uv(rec):
    """The whole recording as float32 uV, samples x channels (read in CHUNK_S pieces; a recording
    without gains, like generate_drifting_recording's, is in uV already: microdrive.traces_uv)."""
    n = rec.get_num_samples()
    out = np.empty((n, rec.get_num_channels()), dtype=np.float32)
    step = int(CHUNK_S * rec.get_sampling_frequency())
    for s0 in range(0, n, step):
        s1 = min(n, s0 + step)
        out[s0:s1] = microdrive.traces_uv(rec, start_frame=s0, end_frame=s1)
    return out


def mad_noise(x):
    """Noise level per column: median(|x|) / 0.6745 (uV)."""
    return np.median(np.abs(x), axis=0) / 0.6745


def mean_waveforms(x, trains, fs):
    """Per unit the mean of x (samples x channels) over its spike times, window [-1 ms, +2 ms]."""
    pre, post = int(round(1e-3 * fs)), int(round(2e-3 * fs))
    out = {}
    for u, t in trains.items():
        t = t[(t >= pre) & (t + post <= len(x))]
        if len(t) == 0:
            out[u] = np.zeros((pre + post, x.shape[1]), dtype=np.float32)
            continue
        if len(t) > MAX_MEAN_SPIKES:
            t = t[np.linspace(0, len(t) - 1, MAX_MEAN_SPIKES).astype(np.int64)]
        out[u] = np.mean(np.stack([x[i - pre:i + post] for i in t]), axis=0)
    return out


def choose_channel(amps, noise):
    """First channel with MIN_VISIBLE..MAX_VISIBLE visible units, or None. amps: units x channels."""
    vis = amps >= VISIBLE_X * noise[np.newaxis, :]
    for c in range(amps.shape[1]):
        if MIN_VISIBLE <= int(vis[:, c].sum()) <= MAX_VISIBLE:
            return c
    return None


def make(params, outdir):
    """Generate, choose the channel, write the recording directory. Returns the units.json content, or
    None when no channel has 2..5 visible units (nothing is written then)."""
    rec, sorting = generate(params)
    fs = rec.get_sampling_frequency()
    x = traces_uv(rec)
    noise = mad_noise(x)
    unit_ids = list(sorting.get_unit_ids())
    trains = {u: np.asarray(sorting.get_unit_spike_train(u), dtype=np.int64) for u in unit_ids}
    means = mean_waveforms(x, trains, fs)
    amps = np.array([np.abs(means[u]).max(axis=0) for u in unit_ids])
    ch = choose_channel(amps, noise)
    if ch is None:
        return None
    clipped = microdrive.write_samples(outdir, x[:, ch], fs, gain_uV=GAIN_UV, extra={
        "source": dict(params, channel=int(ch), channel_noise_uV=round(float(noise[ch]), 3),
                       noise_estimator="median(|x|)/0.6745 over the whole channel")})
    duration = len(x) / fs
    units = []
    vis = [i for i in range(len(unit_ids)) if amps[i, ch] >= VISIBLE_X * noise[ch]]
    for i, u in enumerate(unit_ids):
        # distance of this unit's mean waveform on the channel to the nearest other visible unit's,
        # L2 over the window, in noise levels: how separable the two are on this one channel
        near = [float(np.linalg.norm(means[u][:, ch] - means[unit_ids[j]][:, ch]) / noise[ch])
                for j in vis if j != i]
        units.append({"unit_id": str(u), "visible": i in vis,
                      "amplitude_uV": round(float(amps[i, ch]), 2),
                      "amplitude_x_noise": round(float(amps[i, ch] / noise[ch]), 2),
                      "nearest_visible_x_noise": round(min(near), 2) if near else None,
                      "spikes": int(len(trains[u])), "rate_hz": round(len(trains[u]) / duration, 3)})
    with open(os.path.join(outdir, "ground_truth.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["sample_index", "unit_id"])
        rows = sorted((int(t), str(u)) for u in unit_ids for t in trains[u])
        w.writerows(rows)
    info = {"params": params, "channel": int(ch), "noise_uV": float(noise[ch]),
            "visible_per_channel": [int(v) for v in (amps >= VISIBLE_X * noise[np.newaxis, :]).sum(axis=0)],
            "units": units, "clipped_samples": clipped}
    with open(os.path.join(outdir, "units.json"), "w") as f:
        json.dump(info, f, indent=1)
    return info


def load(recdir):
    """(sidecar, int16 samples, ground truth {unit_id: sample array}, units.json) of a written directory."""
    paths = {k: os.path.join(recdir, k) for k in ("recording.json", "recording.bin", "ground_truth.csv",
                                                   "units.json")}
    for k, p in paths.items():
        if not os.path.isfile(p):
            raise RecordingError(f"{p}: missing (expected in a recording directory written by this tool)")
    try:
        with open(paths["recording.json"]) as f:
            side = json.load(f)
    except (OSError, ValueError) as e:
        raise RecordingError(f"{paths['recording.json']}: not readable JSON ({e})")
    for k in ("sampling_frequency", "num_channels", "dtype", "gain_uV"):
        if k not in side:
            raise RecordingError(f"{paths['recording.json']}: field {k!r} missing")
    if side["dtype"] != "int16" or side["num_channels"] != 1:
        raise RecordingError(f"{paths['recording.json']}: need dtype int16 and num_channels 1, got "
                             f"{side['dtype']!r} and {side['num_channels']!r}")
    raw = np.fromfile(paths["recording.bin"], dtype="<i2")
    if "num_samples" in side and len(raw) != side["num_samples"]:
        raise RecordingError(f"{paths['recording.bin']}: {len(raw)} samples, recording.json says "
                             f"{side['num_samples']}")
    gt = {}
    with open(paths["ground_truth.csv"], newline="") as f:
        r = csv.reader(f)
        head = next(r, None)
        if head != ["sample_index", "unit_id"]:
            raise RecordingError(f"{paths['ground_truth.csv']}: header {head!r}, expected sample_index,unit_id")
        for ln, row in enumerate(r, start=2):
            try:
                gt.setdefault(row[1], []).append(int(row[0]))
            except (IndexError, ValueError):
                raise RecordingError(f"{paths['ground_truth.csv']}:{ln}: not 'sample_index,unit_id': {row!r}")
    with open(paths["units.json"]) as f:
        units = json.load(f)
    return side, raw, {u: np.asarray(t, dtype=np.int64) for u, t in gt.items()}, units
