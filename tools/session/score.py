#!/usr/bin/env python3
"""Scores one microdrive session against the simulator's ground truth.

Reads the session's frame log (candump -L, every frame; only the controller's
telemetry TLM_STATUS/TLM_CYCLE/TLM_SPIKES/TLM_HYP is used, read by name
with microdrive.canlog: cantools and common/protocol/microdrive.dbc) and truth.jsonl (written by
microdrive-sim --truth), and writes report.json. Every definition is in
docs/session.md ("report.json"); the short version:

* The session is cut deterministically: --cycles N keeps each electrode's first
  N cycles (TLM_STATUS order), --duration-s S the cycles whose interval started
  before S (TLM_CYCLE StartTime_us). So a run that went on a little longer
  (a socket bus, where processes are stopped from outside) scores the same.
* A cycle's interval is found in the truth by (electrode, start time): the
  truth's `interval` record gives its first sample on the electrode's sample
  clock, so detection k (TLM_SPIKES SampleNN) is at start_sample + k.
* Spikes match within 0.4 ms. Per interval, SpikeInterface's way: match
  counts for every (neuron, track) pair, agreement = m / (n_true + n_det - m),
  Hungarian assignment of neurons to tracks on agreement, accuracy of a neuron
  = TP / (TP + FN + FP) with its assigned track (0 if none). Averaged over
  (interval, neuron in range) pairs; in range = alive, true SNR at the
  interval's depth >= --snr-in-range (3.0) and at least one true spike.
"""
import argparse
import bisect
import json
import math
import os
import sys
from collections import Counter, defaultdict

from microdrive import canlog, session

DBC = canlog.DBC

SFSM_NEURON_ISOLATED = 3          # firmware/core/control/sfsm.h
TLM_F_GUARD_LIMITED = 0x0200      # firmware/app/md_cycle.h MD_TLM_F_GUARD_LIMITED
TLM_F_GUARD_RETRACT = 0x0400      # MD_TLM_F_GUARD_RETRACT
MATCH_WINDOW_S = 0.4e-3           # SpikeInterface's default delta_time
TRACK_OUTLIER, TRACK_UNLABELLED = session.TRACK_OUTLIER, session.TRACK_UNLABELLED

# One electrode's whole cycle on the target MCU: 48 M instructions (100 ms at
# 480 MHz, docs/benchmarks.md).
CYCLE_BUDGET = 48_000_000


# ---- reading: microdrive.session ---------------------------------------------

read_log = session.read_telemetry
read_truth = session.read_truth


# ---- matching ---------------------------------------------------------------

def hungarian_max(score):
    """Assignment of rows to columns maximising the summed score (rectangular
    allowed): list of (row, col). O(n^2 m), Kuhn-Munkres with potentials."""
    n = len(score)
    m = len(score[0]) if n else 0
    if n == 0 or m == 0:
        return []
    transpose = n > m
    if transpose:
        score = [list(r) for r in zip(*score)]
        n, m = m, n
    big = max(max(r) for r in score)
    cost = [[big - v for v in r] for r in score]
    inf = float("inf")
    u, v, p, way = [0.0] * (n + 1), [0.0] * (m + 1), [0] * (m + 1), [0] * (m + 1)
    for i in range(1, n + 1):
        p[0], j0 = i, 0
        minv, used = [inf] * (m + 1), [False] * (m + 1)
        while True:
            used[j0] = True
            i0, delta, j1 = p[j0], inf, 0
            for j in range(1, m + 1):
                if not used[j]:
                    cur = cost[i0 - 1][j - 1] - u[i0] - v[j]
                    if cur < minv[j]:
                        minv[j], way[j] = cur, j0
                    if minv[j] < delta:
                        delta, j1 = minv[j], j
            for j in range(m + 1):
                if used[j]:
                    u[p[j]] += delta
                    v[j] -= delta
                else:
                    minv[j] -= delta
            j0 = j1
            if p[j0] == 0:
                break
        while j0:
            j1 = way[j0]
            p[j0] = p[j1]
            j0 = j1
    pairs = [(p[j] - 1, j - 1) for j in range(1, m + 1) if p[j] != 0]
    return [(c, r) for r, c in pairs] if transpose else pairs


def count_matches(a, b, delta):
    """One-to-one matches between two sorted spike trains within delta samples."""
    i = j = n = 0
    while i < len(a) and j < len(b):
        d = b[j] - a[i]
        if abs(d) <= delta:
            n, i, j = n + 1, i + 1, j + 1
        elif d < 0:
            j += 1
        else:
            i += 1
    return n


def match_detections(true_spikes, dets, delta):
    """Each detection to at most one true spike (nearest first, one-to-one).
    Returns a list, per detection, of the true unit id or None."""
    pairs = []
    times = [s for s, _ in true_spikes]
    for k, (s, _) in enumerate(dets):
        lo = bisect.bisect_left(times, s - delta)
        hi = bisect.bisect_right(times, s + delta)
        for q in range(lo, hi):
            pairs.append((abs(times[q] - s), k, q))
    pairs.sort()
    det_unit, used_det, used_true = [None] * len(dets), set(), set()
    for _, k, q in pairs:
        if k in used_det or q in used_true:
            continue
        used_det.add(k)
        used_true.add(q)
        det_unit[k] = true_spikes[q][1]
    return det_unit


# ---- per electrode ----------------------------------------------------------

def select_cycles(status_list, cycles, args):
    """The electrode's cycles that count: deterministic cut (see module doc)."""
    out = []
    for s in status_list:
        c = int(s["Cycle"])
        ph = cycles.get(c, {})
        start = (ph.get(0) or ph.get(1) or {}).get("StartTime_us")
        if args.cycles:
            if len(out) >= args.cycles:
                break
        elif start is not None and start >= args.duration_s * 1e6:
            break
        out.append((c, s, ph))
    return out


class Interval:
    __slots__ = ("cycle", "status", "start_us", "end_us", "truth", "dets", "true_spikes", "in_range", "det_unit")


def build_intervals(e, sel, spikes, truth, fs_default):
    by_start = {r["t_us"]: r for r in truth["intervals"].get(e, [])}
    all_true = truth["spikes"].get(e, [])
    true_times = [s for s, _ in all_true]
    out = []
    for c, s, ph in sel:
        iv = Interval()
        iv.cycle, iv.status, iv.truth, iv.dets, iv.true_spikes, iv.in_range = c, s, None, [], [], set()
        rec = ph.get(1) or ph.get(0)
        iv.start_us = int(rec["StartTime_us"]) if rec else None
        iv.end_us = None
        if rec:
            fs = int(rec["SampleRate_hz"]) or fs_default
            iv.end_us = iv.start_us + int(round(int(rec["NumSamples"]) * 1e6 / fs))
            iv.truth = by_start.get(iv.start_us)
        if iv.truth is not None:
            s0, n = iv.truth["start_sample"], iv.truth["num_samples"]
            parts = sorted(spikes.get((e, c), []))
            iv.dets = sorted((s0 + k, trk) for _, pairs in parts for k, trk in pairs)
            lo, hi = bisect.bisect_left(true_times, s0), bisect.bisect_left(true_times, s0 + n)
            iv.true_spikes = all_true[lo:hi]
            present = {u for _, u in iv.true_spikes if u >= 0}
            st = iv.truth.get("state") or {}
            for nr in st.get("neurons", []):
                if nr["alive"] and nr["snr"] >= ARGS.snr_in_range and nr["neuron"] in present:
                    iv.in_range.add(nr["neuron"])
        out.append(iv)
    return out


def interval_accuracy(iv, delta):
    """Per neuron in range: SpikeInterface accuracy with its Hungarian track."""
    units = sorted(iv.in_range)
    tracks = sorted({t for _, t in iv.dets if t >= 0})
    train_u = {u: [s for s, x in iv.true_spikes if x == u] for u in units}
    train_t = {t: [s for s, x in iv.dets if x == t] for t in tracks}
    agree = []
    for u in units:
        row = []
        for t in tracks:
            m = count_matches(train_u[u], train_t[t], delta)
            row.append(m / (len(train_u[u]) + len(train_t[t]) - m))
        agree.append(row)
    acc = {u: 0.0 for u in units}
    for r, c in hungarian_max(agree) if tracks else []:
        acc[units[r]] = agree[r][c]
    return acc


def score_electrode(e, status_list, cycles, spikes, hyp, truth, args):
    fs = int((truth["session"] or {}).get("sample_rate_hz", 30000))
    delta = int(round(MATCH_WINDOW_S * fs))
    sel = select_cycles(status_list, cycles, args)
    ivs = build_intervals(e, sel, spikes, truth, fs)
    # detections -> true units, track -> neuron it mostly belongs to
    track_units = defaultdict(Counter)
    labels = defaultdict(list)                       # neuron -> per in-range interval label
    accs = []
    for iv in ivs:
        if iv.truth is None:
            continue
        iv.det_unit = match_detections(iv.true_spikes, iv.dets, delta)
        per_unit = defaultdict(Counter)
        for (s, trk), u in zip(iv.dets, iv.det_unit):
            if trk >= 0:
                track_units[trk][u] += 1
                if u is not None and u >= 0:
                    per_unit[u][trk] += 1
        for u in sorted(iv.in_range):
            labels[u].append(per_unit[u].most_common(1)[0][0] if per_unit[u] else None)
        accs.extend(interval_accuracy(iv, delta).values())
    track_neuron = {}
    for trk, cnt in track_units.items():
        best = [(n, u) for u, n in cnt.items() if u is not None and u >= 0]
        track_neuron[trk] = max(best)[1] if best else None
    spurious = sum(1 for trk, cnt in track_units.items()
                   if max([n for u, n in cnt.items() if u is not None and u >= 0] or [0]) * 2 < sum(cnt.values()))
    consistent = switches = total = 0
    ids = {}                                         # neuron -> distinct track IDs that held it
    for u, seq in labels.items():
        named = [x for x in seq if x is not None]
        total += len(seq)
        if named:
            major = Counter(named).most_common(1)[0][0]
            consistent += sum(1 for x in seq if x == major)
        switches += sum(1 for a, b in zip(named, named[1:]) if a != b)
        ids[u] = len(set(named))
    g = [hyp[(e, iv.cycle)] for iv in ivs if (e, iv.cycle) in hyp]
    tracking = {
        "accuracy": (sum(accs) / len(accs)) if accs else None,
        "accuracy_pairs": len(accs),
        "id_consistency": (consistent / total) if total else None,
        "id_switches": switches,
        "track_ids_per_neuron": {str(u): n for u, n in sorted(ids.items())},
        "spurious_tracks": spurious,
        "tracks": len(track_units),
        "psi": sum(abs(a - b) for a, b in zip(g[1:], g)) if g else None,
    }
    rep = isolation_metrics(e, ivs, track_neuron, truth)
    rep["tracking"] = tracking
    cost = cycle_cost(sel)
    if cost is not None:
        rep["cost"] = cost
    return rep, accs, (consistent, total)


def cycle_cost(sel):
    """TLM_STATUS CycleCost/ProcessCost of the counted cycles that processed an
    interval (not skipped, not a failed recording), against the per-electrode
    budget; None when the controller has no work counter (every cost 0)."""
    total = [int(s["CycleCost"]) for _, s, _ in sel if int(s["Flags"]) & 0x3 == 0]
    proc = [int(s["ProcessCost"]) for _, s, _ in sel if int(s["Flags"]) & 0x3 == 0]
    if not any(total):
        return None

    def median(v):
        v = sorted(v)
        n = len(v)
        return v[n // 2] if n % 2 else (v[n // 2 - 1] + v[n // 2]) / 2

    return {
        "unit": "instructions",
        "cycles_measured": len(total),
        "median": median(total),
        "max": max(total),
        "process_median": median(proc),
        "process_max": max(proc),
        "budget": CYCLE_BUDGET,
        "over_budget": sum(1 for v in total if v > CYCLE_BUDGET),
    }


def final_state(ivs):
    for iv in reversed(ivs):
        if iv.truth is not None and iv.truth.get("state"):
            return iv, iv.truth["state"]
    return None, None


def closest_approach(fstate, deaths):
    """Per neuron, the smallest tip-soma distance of the session: the
    simulator's running minimum in the last counted state, and the distance of
    every death (a neuron dies below the damage radius)."""
    out = {}
    for n in (fstate or {}).get("neurons", []):
        if "closest_um" in n:
            out[n["neuron"]] = round(float(n["closest_um"]), 3)
    for d in deaths:
        out[d["neuron"]] = round(min(out.get(d["neuron"], math.inf), float(d["distance_um"])), 3)
    return out


def isolation_metrics(e, ivs, track_neuron, truth):
    states = [int(iv.status["SfsmState"]) for iv in ivs]
    iso = [s == SFSM_NEURON_ISOLATED for s in states]
    first = iso.index(True) if any(iso) else None
    last_iv, fstate = final_state(ivs)
    neurons = {n["neuron"]: n for n in (fstate or {}).get("neurons", [])}
    dominant = None
    if first is not None:
        last_iso = max(k for k, v in enumerate(iso) if v)
        dominant = track_neuron.get(int(ivs[last_iso].status["DominantTrack"]))
    if dominant is None and neurons:
        dominant = max(neurons.values(), key=lambda n: (n["snr"], -n["neuron"]))["neuron"]
    dist = None
    if fstate is not None and dominant in neurons:
        dist = abs(fstate["tip_um"] - neurons[dominant]["snr_peak_depth_um"])
    end_us = max([iv.end_us for iv in ivs if iv.end_us is not None] or [0])
    deaths = [d for d in truth["deaths"].get(e, []) if d["t_s"] * 1e6 <= end_us]
    # A neuron that dies before the electrode's first interval has ended was
    # killed by the insertion (the tip placed at the start depth, the tissue
    # relaxing onto it), not by a decision: the controller had no data yet.
    control_us = ivs[0].end_us if ivs and ivs[0].end_us is not None else 0
    at_insertion = [d for d in deaths if d["t_s"] * 1e6 < control_us]
    deaths = [d for d in deaths if d["t_s"] * 1e6 >= control_us]
    damaged = len(deaths)
    closest = closest_approach(fstate, deaths)
    for d in at_insertion:
        closest.pop(d["neuron"], None)
    held, reiso = None, 0
    if first is not None:
        first_neuron = track_neuron.get(int(ivs[first].status["DominantTrack"]))
        after = range(first, len(ivs))
        held = sum(1 for k in after if iso[k] and first_neuron is not None and
                   track_neuron.get(int(ivs[k].status["DominantTrack"])) == first_neuron) / len(after)
        reiso = sum(1 for k in range(first + 1, len(ivs)) if iso[k] and not iso[k - 1])
    first_iv = ivs[first] if first is not None else None
    return {
        "electrode": e,
        "cycles": len(ivs),
        "isolated": first is not None,
        "cycles_to_isolation": (first + 1) if first is not None else None,
        "time_to_isolation_s": (first_iv.end_us / 1e6) if first_iv is not None and first_iv.end_us else None,
        "final_peak_distance_um": dist,
        "dominant_neuron": dominant,
        "final_tip_um": fstate["tip_um"] if fstate else None,
        "final_state": states[-1] if states else None,
        "neurons_damaged": damaged,
        "neurons_damaged_at_insertion": len(at_insertion),
        "closest_approach_um": min(closest.values()) if closest else None,
        "closest_approach_by_neuron": {str(k): v for k, v in sorted(closest.items())},
        "guard_limited_cycles": sum(1 for iv in ivs if int(iv.status["Flags"]) & TLM_F_GUARD_LIMITED),
        "guard_retractions": sum(1 for iv in ivs if int(iv.status["Flags"]) & TLM_F_GUARD_RETRACT),
        "held_fraction": held,
        "reisolations": reiso,
        "end_time_s": end_us / 1e6,
    }


def main(argv=None):
    global ARGS
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--log", required=True)
    ap.add_argument("--truth", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--bus", required=True)
    ap.add_argument("--end", default="goal")
    goal = ap.add_mutually_exclusive_group(required=True)
    goal.add_argument("--cycles", type=int)
    goal.add_argument("--duration-s", type=float)
    ap.add_argument("--snr-in-range", type=float, default=3.0)
    ap.add_argument("--dbc", default=DBC)
    ARGS = args = ap.parse_args(argv)
    try:
        import cantools
    except ImportError as e:
        sys.exit(f"score.py: the Python module {e.name!r} is missing from {sys.executable}; the project venv "
                 f"has it: run scripts/setup-venv.sh in the checkout (microdrive-session uses its .venv)")
    db = cantools.database.load_file(args.dbc)
    status, cycles, spikes, hyp = read_log(args.log, db)
    truth = read_truth(args.truth)
    n_el = int((truth["session"] or {}).get("electrodes", 0)) or (max(status) + 1 if status else 0)
    electrodes, all_acc, cons = [], [], [0, 0]
    for e in range(n_el):
        cyc_e = {c: v for (ee, c), v in cycles.items() if ee == e}
        rep, accs, (c_ok, c_tot) = score_electrode(e, status.get(e, []), cyc_e, spikes, hyp, truth, args)
        electrodes.append(rep)
        all_acc.extend(accs)
        cons[0] += c_ok
        cons[1] += c_tot
    tracking = {
        "accuracy": (sum(all_acc) / len(all_acc)) if all_acc else None,
        "accuracy_pairs": len(all_acc),
        "id_consistency": (cons[0] / cons[1]) if cons[1] else None,
        "id_switches": sum(r["tracking"]["id_switches"] for r in electrodes),
        "spurious_tracks": sum(r["tracking"]["spurious_tracks"] for r in electrodes),
        "psi": sum(r["tracking"]["psi"] or 0 for r in electrodes),
    }
    want = args.cycles if args.cycles else None
    report = {
        "scenario": os.path.splitext(os.path.basename(args.scenario))[0],
        "seed": args.seed,
        "bus": args.bus,
        "goal": {"cycles": args.cycles} if args.cycles else {"duration_s": args.duration_s},
        "end": args.end,
        "complete": all((r["cycles"] >= want) if want else True for r in electrodes) and args.end == "goal",
        "snr_in_range": args.snr_in_range,
        "electrodes": electrodes,
        "tracking": tracking,
    }
    with open(args.out, "w") as f:
        json.dump(report, f, indent=2, sort_keys=False, allow_nan=False)
        f.write("\n")
    return 0


ARGS = None

if __name__ == "__main__":
    sys.exit(main())
