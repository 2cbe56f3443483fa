#!/usr/bin/env python3
"""Tracking evaluation on simulator recordings with ground truth (docs/tracking-eval.md).

For every scenario x seed: `sim-export` writes a recording, `mhtc-replay` runs each
tracker on it, and the labels are scored against ground_truth.csv:

- a detected spike is a neuron's spike if a truth trough lies within 0.5 ms;
- a neuron is "present" in an interval with at least MIN_SPIKES matched spikes;
  its ID there is the majority track_id of those spikes (-1 = no track);
- ID consistency of a neuron = share of its present intervals whose ID equals its
  overall majority ID (a -1 majority scores 0); pooled over neurons and runs;
- spurious tracks = track IDs that are never the ID of a present neuron.

usage: run_eval.py BUILD_DIR [--seeds 1,2,3] [--scenarios a,b] [--trackers mhtc,map-nn,ml-nn,gnn]
                   [--work DIR] [--jobs N]
labels.csv is the final best hypothesis' lineage (delayed decision, offline);
labels_online.csv the leading hypothesis of each interval as it was then. Both are scored.
Prints a markdown table (stdout) and writes DIR/results.json. Standard library only.
"""
import argparse
import bisect
import collections
import concurrent.futures
import csv
import json
import os
import subprocess
import sys

Q_UV = 10.0  # process noise of the replay (--q-uv), set by --q-uv here
EXTRA = []   # further mhtc-replay options (--replay-args)
MATCH_MS = 0.5
MIN_SPIKES = 10
DEFAULT_SCENARIOS = ["intermittent_neuron", "appearing_neuron", "drifting_pair", "crossing_clusters", "drift_away"]
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def load_truth(rec_dir, channel=0):
    samples, neurons = [], []
    with open(os.path.join(rec_dir, "ground_truth.csv")) as f:
        for row in csv.DictReader(f):
            if int(row["channel"]) == channel:
                samples.append(int(row["sample_index"]))
                neurons.append(int(row["neuron_id"]))
    return samples, neurons


def score(rec_dir, out_dir, fs, labels="labels.csv"):
    samples, neurons = load_truth(rec_dir)
    tol = int(round(MATCH_MS * 1e-3 * fs))
    votes = collections.defaultdict(collections.Counter)  # (neuron, interval) -> Counter(track_id)
    all_ids = set()
    with open(os.path.join(out_dir, labels)) as f:
        for row in csv.DictReader(f):
            s, k, tid = int(row["sample_index"]), int(row["interval"]), int(row["track_id"])
            if tid > 0:
                all_ids.add(tid)
            i = bisect.bisect_left(samples, s - tol)
            best = None
            while i < len(samples) and samples[i] <= s + tol:
                if best is None or abs(samples[i] - s) < abs(samples[best] - s):
                    best = i
                i += 1
            if best is not None:
                votes[(neurons[best], k)][tid] += 1
    per_neuron = collections.defaultdict(list)
    for (u, k), c in votes.items():
        if sum(c.values()) >= MIN_SPIKES:
            per_neuron[u].append(c.most_common(1)[0][0])
    consistent = present = 0
    used_ids = set()
    for u, ids in per_neuron.items():
        major = collections.Counter(ids).most_common(1)[0][0]
        present += len(ids)
        consistent += sum(1 for t in ids if t == major and t > 0)
        used_ids.update(t for t in ids if t > 0)
    return {"present": present, "consistent": consistent, "spurious": len(all_ids - used_ids),
            "neurons": len(per_neuron), "ids": len(all_ids)}


def run_one(build, work, scenario, seed, tracker):
    rec_dir = os.path.join(work, f"{scenario}-s{seed}")
    out_dir = os.path.join(work, "out", f"{scenario}-s{seed}-{tracker}")
    cmd = [os.path.join(build, "bin", "mhtc-replay"), "--recording", os.path.join(rec_dir, "recording.json"),
           "--out", out_dir, "--tracker", tracker, "--quiet", "--q-uv", str(Q_UV)] + EXTRA
    subprocess.run(cmd, check=True)
    with open(os.path.join(rec_dir, "recording.json")) as f:
        fs = json.load(f)["sampling_frequency"]
    with open(os.path.join(out_dir, "summary.json")) as f:
        summ = json.load(f)
    r = score(rec_dir, out_dir, fs)
    online = score(rec_dir, out_dir, fs, "labels_online.csv")
    r.update(online_consistent=online["consistent"], online_spurious=online["spurious"])
    r.update(scenario=scenario, seed=seed, tracker=tracker, step_ms_median=summ["step_ms_median"])
    return r


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("build")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--scenarios", default=",".join(DEFAULT_SCENARIOS))
    ap.add_argument("--trackers", default="mhtc,map-nn,ml-nn,gnn")
    ap.add_argument("--work", default="/tmp/tracking-eval")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--q-uv", type=float, default=10.0)
    ap.add_argument("--replay-args", default="", help="extra mhtc-replay options, space separated")
    a = ap.parse_args()
    global Q_UV, EXTRA
    Q_UV = a.q_uv
    EXTRA = a.replay_args.split()
    seeds = [int(s) for s in a.seeds.split(",")]
    scenarios = a.scenarios.split(",")
    trackers = a.trackers.split(",")
    os.makedirs(a.work, exist_ok=True)
    for sc in scenarios:
        for seed in seeds:
            rec_dir = os.path.join(a.work, f"{sc}-s{seed}")
            if not os.path.exists(os.path.join(rec_dir, "recording.json")):
                subprocess.run([os.path.join(a.build, "bin", "sim-export"),
                                os.path.join(ROOT, "scenarios", sc + ".yaml"), rec_dir, "--seed", str(seed)],
                               check=True, stdout=subprocess.DEVNULL)
    jobs = [(sc, seed, t) for sc in scenarios for seed in seeds for t in trackers]
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as ex:
        results = list(ex.map(lambda j: run_one(a.build, a.work, *j), jobs))
    with open(os.path.join(a.work, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("| scenario | tracker | neuron-intervals | ID consistency | spurious tracks | ID consistency (online) "
          "| spurious (online) | track IDs | median step (ms) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for sc in scenarios + ["all"]:
        for t in trackers:
            rs = [r for r in results if r["tracker"] == t and (sc == "all" or r["scenario"] == sc)]
            pres = sum(r["present"] for r in rs)
            cons = sum(r["consistent"] for r in rs)
            med = sorted(r["step_ms_median"] for r in rs)[len(rs) // 2]
            name = f"**{sc}**" if sc == "all" else sc
            ocons = sum(r["online_consistent"] for r in rs)
            print(f"| {name} | {t} | {pres} | {cons / pres if pres else 0:.3f} | "
                  f"{sum(r['spurious'] for r in rs)} | {ocons / pres if pres else 0:.3f} | "
                  f"{sum(r['online_spurious'] for r in rs)} | {sum(r['ids'] for r in rs)} | {med:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
