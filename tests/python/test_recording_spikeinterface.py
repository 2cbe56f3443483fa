"""The simulator's exported recording loads in SpikeInterface.

Recording directory: $MD_SIM_RECORDING_DIR if set (an existing export);
otherwise the test runs the `sim-export` tool on scenarios/three_electrodes.yaml
into a temporary directory. The tool is $MD_SIM_EXPORT, else
$MD_BUILD_DIR/bin/sim-export, else the newest build/*/bin/sim-export.
"""
import csv
import glob
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest
import spikeinterface.core as si

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _exporter():
    if os.environ.get("MD_SIM_EXPORT"):
        return os.environ["MD_SIM_EXPORT"]
    if os.environ.get("MD_BUILD_DIR"):
        return os.path.join(os.environ["MD_BUILD_DIR"], "bin", "sim-export")
    found = sorted(glob.glob(str(ROOT / "build" / "*" / "bin" / "sim-export")), key=os.path.getmtime)
    if not found:
        pytest.fail("no sim-export: build the project first or set MD_SIM_EXPORT / MD_SIM_RECORDING_DIR")
    return found[-1]


@pytest.fixture(scope="module")
def recording_dir(tmp_path_factory):
    if os.environ.get("MD_SIM_RECORDING_DIR"):
        return pathlib.Path(os.environ["MD_SIM_RECORDING_DIR"])
    out = tmp_path_factory.mktemp("sim_export")
    scenario = ROOT / "scenarios" / "three_electrodes.yaml"
    subprocess.run([_exporter(), str(scenario), str(out), "--intervals", "3", "--interval-s", "2"],
                   check=True, capture_output=True, text=True)
    return out


@pytest.fixture(scope="module")
def meta(recording_dir):
    with open(recording_dir / "recording.json", encoding="utf-8") as f:
        return json.load(f)


def test_loads_with_right_rate_channels_and_length(recording_dir, meta):
    rec = si.read_binary(recording_dir / "recording.bin", sampling_frequency=meta["sampling_frequency"],
                         dtype=meta["dtype"], num_channels=meta["num_channels"],
                         gain_to_uV=meta["gain_uV"], offset_to_uV=meta["offset_uV"])
    assert rec.get_sampling_frequency() == pytest.approx(meta["sampling_frequency"])
    assert 20000 <= rec.get_sampling_frequency() <= 30000
    assert rec.get_num_channels() == meta["num_channels"]
    assert rec.get_num_samples() == meta["num_samples"]
    assert meta["num_samples"] == sum(iv["num_samples"] for iv in meta["intervals"])
    size = os.path.getsize(recording_dir / "recording.bin")
    assert size == meta["num_samples"] * meta["num_channels"] * 2


def test_traces_are_a_plausible_neural_signal(recording_dir, meta):
    rec = si.read_binary(recording_dir / "recording.bin", sampling_frequency=meta["sampling_frequency"],
                         dtype="int16", num_channels=meta["num_channels"],
                         gain_to_uV=meta["gain_uV"], offset_to_uV=0.0)
    raw = rec.get_traces(start_frame=0, end_frame=min(60000, rec.get_num_samples()))
    assert raw.dtype == np.int16
    # scale with the gains SpikeInterface stored (the keyword for scaled traces changed across versions)
    uv = raw.astype(np.float64) * rec.get_channel_gains()[np.newaxis, :]
    assert np.allclose(rec.get_channel_gains(), meta["gain_uV"])
    assert uv.shape[1] == meta["num_channels"]
    rms = np.sqrt(np.mean(uv ** 2, axis=0))
    # background of a few uV per channel, not silence and not saturation
    assert np.all(rms > 3.0) and np.all(rms < 100.0)


def test_ground_truth_points_into_the_recording(recording_dir, meta):
    with open(recording_dir / "ground_truth.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert rows, "three_electrodes has neurons within reach"
    samples = np.array([int(r["sample_index"]) for r in rows])
    channels = np.array([int(r["channel"]) for r in rows])
    assert samples.min() >= 0 and samples.max() < meta["num_samples"]
    assert channels.min() >= 0 and channels.max() < meta["num_channels"]
    assert np.all(np.diff(samples) >= 0)
    # as a SpikeInterface sorting (ground truth for a comparison)
    sorting = si.NumpySorting.from_samples_and_labels(
        [samples], [channels * 1000 + np.array([int(r["neuron_id"]) for r in rows])],
        sampling_frequency=meta["sampling_frequency"])
    assert sorting.get_num_units() >= 1
