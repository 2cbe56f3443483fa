"""Labels, the whole-session oracle, and scoring against the ground truth.

Scoring: spikeinterface.comparison.compare_sorter_to_ground_truth with the ground truth restricted to the
visible units and the tracker's track IDs as the tested units (spikes with track_id -1 are unlabelled).
SpikeInterface matches each ground-truth unit to at most one track (Hungarian on the agreement scores,
spikes within delta_time = 0.4 ms); accuracy = tp / (tp + fn + fp) of the matched pair, 0 if unmatched. A
unit whose spikes are split over two track IDs (an ID switch) keeps only the matched track's spikes.

Per (unit, tracker) diagnostics that split the loss (computed here, same 0.4 ms tolerance):
  detected   share of the unit's spikes with a row in the tracker's labels.csv (any track_id)
  labelled   share with a row whose track_id >= 0
  ids        track IDs carrying >= 10 % of the unit's labelled spikes (> 1: split / ID switch)
"""
import csv
import os

import numpy as np

DELTA_MS = 0.4
IDS_SHARE = 0.10

# Window of the firmware's spike extraction at 30 kHz (spike_extract.h: d_w = round(1.15 ms * fs),
# pre_peak = round(0.4 ms * fs)); labels.csv sample_index is the window's minimum.
def window_bounds(fs):
    return int(round(0.4e-3 * fs)), int(round(1.15e-3 * fs))


class LabelsError(Exception):
    pass


def read_labels(path):
    """(sample_index, track_id) int64 arrays of a labels.csv (sample_index,interval,cluster,track_id)."""
    if not os.path.isfile(path):
        raise LabelsError(f"{path}: missing")
    with open(path, newline="") as f:
        r = csv.reader(f)
        head = next(r, None)
        if head != ["sample_index", "interval", "cluster", "track_id"]:
            raise LabelsError(f"{path}: header {head!r}, expected sample_index,interval,cluster,track_id")
        s, t = [], []
        for ln, row in enumerate(r, start=2):
            try:
                s.append(int(row[0]))
                t.append(int(row[3]))
            except (IndexError, ValueError):
                raise LabelsError(f"{path}:{ln}: not four integers: {row!r}")
    return np.asarray(s, dtype=np.int64), np.asarray(t, dtype=np.int64)


def oracle(raw, gain, fs, samples, k, seed=0):
    """Whole-session oracle: windows at `samples` (the firmware's window), 2-D PCA over the whole session,
    scikit-learn GaussianMixture with k components (the true visible-unit count), full covariances,
    n_init 5. Returns one label per sample (0..k-1) used as a fixed ID for the whole session."""
    from sklearn.decomposition import PCA
    from sklearn.mixture import GaussianMixture
    pre, dw = window_bounds(fs)
    ok = (samples - pre >= 0) & (samples - pre + dw <= len(raw))
    idx = samples[ok][:, np.newaxis] - pre + np.arange(dw)[np.newaxis, :]
    W = raw[idx].astype(np.float64) * gain
    labels = np.full(len(samples), -1, dtype=np.int64)
    if len(W) < max(k, 3):
        return labels
    F = PCA(n_components=2, random_state=seed).fit_transform(W)
    gm = GaussianMixture(n_components=k, covariance_type="full", n_init=5, random_state=seed).fit(F)
    labels[ok] = gm.predict(F)
    return labels


def _nearest(det, t, tol):
    """Index into sorted det of the detection nearest each t, -1 if none within tol samples."""
    if len(det) == 0:
        return np.full(len(t), -1, dtype=np.int64)
    j = np.searchsorted(det, t)
    j0, j1 = np.clip(j - 1, 0, len(det) - 1), np.clip(j, 0, len(det) - 1)
    pick = np.where(np.abs(det[j0] - t) <= np.abs(det[j1] - t), j0, j1)
    return np.where(np.abs(det[pick] - t) <= tol, pick, -1)


def score(gt, visible, samples, track_ids, fs):
    """Per visible unit: accuracy (SpikeInterface), detected, labelled, ids. gt: {unit: samples}."""
    import spikeinterface.core as si
    import spikeinterface.comparison as sc
    order = np.argsort(samples, kind="stable")
    samples, track_ids = samples[order], track_ids[order]
    gt_sort = si.NumpySorting.from_unit_dict([{u: gt[u] for u in visible}], sampling_frequency=fs)
    keep = track_ids >= 0
    if keep.any():
        tested = si.NumpySorting.from_samples_and_labels([samples[keep]], [track_ids[keep]], fs)
        cmp = sc.compare_sorter_to_ground_truth(gt_sort, tested, delta_time=DELTA_MS, exhaustive_gt=False)
        acc = cmp.get_performance()["accuracy"]
        accuracy = {u: float(acc.loc[u]) for u in visible}
    else:
        accuracy = {u: 0.0 for u in visible}
    tol = int(round(DELTA_MS * 1e-3 * fs))
    out = {}
    for u in visible:
        t = gt[u]
        j = _nearest(samples, t, tol)
        hit = j >= 0
        ids = track_ids[j[hit]]
        lab = ids[ids >= 0]
        n_ids = 0
        if len(lab):
            _, counts = np.unique(lab, return_counts=True)
            n_ids = int(np.sum(counts >= IDS_SHARE * len(lab)))
        out[u] = {"accuracy": accuracy[u], "detected": float(hit.mean()) if len(t) else 0.0,
                  "labelled": float(len(lab) / len(t)) if len(t) else 0.0, "ids": n_ids}
    return out
