"""microdrive.run_mhtc, the SpikeInterface front door (python/microdrive).

On a recording of spikeinterface.generate_ground_truth_recording (seed 1000): the returned sorting is a
NumpySorting whose unit ids are the track IDs and whose spike trains are exactly mhtc-replay's own
labels.csv (mhtc-replay run here by hand on the channel written in uV), it loads into
compare_sorter_to_ground_truth, and the per-interval table comes back with return_intervals. An int16
recording with gains gives the tracker the same uV. A missing executable is a clear error.
mhtc-replay: $MD_BUILD_DIR/bin (ctest sets it), else build/release/bin.
"""
import csv
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest
import spikeinterface.comparison as sc
import spikeinterface.core as si

import microdrive

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = pathlib.Path(os.environ.get("MD_BUILD_DIR", ROOT / "build" / "release")) / "bin"
DURATION_S, INTERVAL_S, CHANNEL = 40.0, 10.0, 1


@pytest.fixture(scope="module")
def generated():
    return si.generate_ground_truth_recording(durations=[DURATION_S], sampling_frequency=30000.0, num_channels=4,
                                              num_units=5, seed=1000)


@pytest.fixture(scope="module")
def result(generated):
    rec, _ = generated
    return microdrive.run_mhtc(rec, channel=CHANNEL, interval_s=INTERVAL_S, executable=str(BIN),
                               return_intervals=True)


def replay_by_hand(rec, tmp_path):
    """labels.csv of mhtc-replay run directly on the channel written as float32 uV: {track_id: samples}."""
    x = rec.get_traces(channel_ids=[rec.get_channel_ids()[CHANNEL]], return_in_uV=True).astype("<f4")
    x.tofile(tmp_path / "recording.bin")
    (tmp_path / "recording.json").write_text(json.dumps(
        {"sampling_frequency": rec.get_sampling_frequency(), "num_channels": 1, "dtype": "float32"}))
    subprocess.run([str(BIN / "mhtc-replay"), "--recording", str(tmp_path / "recording.json"), "--out",
                    str(tmp_path / "out"), "--interval", str(INTERVAL_S), "--quiet"], check=True)
    trains = {}
    with open(tmp_path / "out" / "labels.csv", newline="") as f:
        for row in csv.DictReader(f):
            if int(row["track_id"]) >= 0:
                trains.setdefault(int(row["track_id"]), []).append(int(row["sample_index"]))
    return trains


def test_sorting_is_mhtc_replays_labels(generated, result, tmp_path):
    rec, _ = generated
    sorting, _ = result
    assert isinstance(sorting, si.NumpySorting)
    assert sorting.get_sampling_frequency() == rec.get_sampling_frequency()
    want = replay_by_hand(rec, tmp_path)
    assert len(want) >= 1, "the tracker found no track on this channel: the comparison below would be empty"
    assert sorted(int(u) for u in sorting.get_unit_ids()) == sorted(want)
    for u in sorting.get_unit_ids():
        assert np.array_equal(sorting.get_unit_spike_train(u), np.array(sorted(want[int(u)])))


def test_compares_to_ground_truth(generated, result):
    _, gt = generated
    sorting, _ = result
    cmp = sc.compare_sorter_to_ground_truth(gt, sorting, delta_time=0.4)
    assert list(cmp.get_performance().index) == list(gt.get_unit_ids())
    assert cmp.match_event_count.shape == (len(gt.get_unit_ids()), len(sorting.get_unit_ids()))
    assert cmp.match_event_count.to_numpy().sum() > 0
    # spike times are samples of the whole recording (not of an interval): nearly every spike the
    # tracker labelled lies within 0.4 ms of a ground-truth spike (one channel of 4 sees several units,
    # so tracks may mix units; how well they separate is docs/external-eval.md's subject)
    truth = np.sort(np.concatenate([gt.get_unit_spike_train(u) for u in gt.get_unit_ids()]))
    t = np.sort(np.concatenate([sorting.get_unit_spike_train(u) for u in sorting.get_unit_ids()]))
    i = np.clip(np.searchsorted(truth, t), 1, len(truth) - 1)
    near = np.minimum(np.abs(truth[i] - t), np.abs(truth[i - 1] - t)) <= 0.4e-3 * 30000
    assert near.mean() >= 0.9


def test_interval_table(result):
    sorting, intervals = result
    assert [iv["interval"] for iv in intervals] == list(range(int(DURATION_S / INTERVAL_S)))
    assert [iv["start_sample"] for iv in intervals] == [int(k * INTERVAL_S * 30000) for k in range(len(intervals))]
    tracks = {c["track_id"] for iv in intervals for c in iv.get("clusters", []) if c.get("track_id", -1) >= 0}
    assert {int(u) for u in sorting.get_unit_ids()} <= tracks


def test_int16_with_gains_is_read_in_uv(generated, tmp_path):
    rec, _ = generated
    gain = 0.195
    x = rec.get_traces(return_in_uV=True)
    as_int16 = si.NumpyRecording(np.round(x / gain).astype(np.int16), rec.get_sampling_frequency())
    as_int16.set_channel_gains(gain)
    as_int16.set_channel_offsets(0.0)
    path = microdrive.write_recording(as_int16, tmp_path / "w", channel=CHANNEL)
    side = json.load(open(path))
    assert side["dtype"] == "float32" and side["gain_uV"] == 1.0
    written = np.fromfile(tmp_path / "w" / "recording.bin", dtype="<f4")
    assert np.allclose(written, np.round(x[:, CHANNEL] / gain) * gain, atol=1e-3)
    sorting = microdrive.run_mhtc(as_int16, channel=CHANNEL, interval_s=INTERVAL_S, executable=str(BIN))
    assert len(sorting.get_unit_ids()) >= 1


def test_missing_executable_is_a_clear_error(generated, tmp_path):
    rec, _ = generated
    with pytest.raises(microdrive.MicrodriveError, match="not an executable mhtc-replay"):
        microdrive.run_mhtc(rec, executable=str(tmp_path / "nowhere"))
