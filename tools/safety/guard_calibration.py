#!/usr/bin/env python3
"""Measurements behind the approach guard's defaults (docs/sfsm.md).

Runs closed-loop sessions with the guard computed but not applied
(`--param guard_enable=0`) and pairs every interval's robust amplitude
(TLM_STATUS GuardAmp) with the ground truth: for each advance of at least
`--baseline-um`, the growth g = ln(a / a_prev) / travel, and the nearest live
neuron ahead of the tip (lateral distance r, axial distance x still to go).
Prints the distribution of g and of the amplitude for approaches towards
neurons the tip would kill (r below the damage radius) and towards neurons it
passes safely, and for stand-still intervals the amplitude climb against the
neuron's approach.

    tools/safety/guard_calibration.py --scenario scenarios/stress/dense_cells.yaml \\
        --seeds 101-110 --out out/guard-cal [--jobs 2] [--bin-dir build/release/bin]
"""
import argparse
import concurrent.futures
import json
import math
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))

from microdrive import canlog, session  # a session's telemetry and truth


def parse_seeds(text):
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out.extend(range(int(a), int(b or a) + 1))
    return out


def run_session(bin_dir, scenario, seed, out_dir, params):
    if os.path.exists(os.path.join(out_dir, "candump.log")) and os.path.exists(os.path.join(out_dir, "truth.jsonl")):
        return out_dir
    cmd = [os.path.join(bin_dir, "microdrive-session"), "--scenario", scenario, "--seed", str(seed),
           "--bus", "inproc", "--out", out_dir, "--no-lcm", "--no-plots", "--no-recording", "--quiet",
           "--no-score", "--param", "guard_enable=0"]
    for p in params:
        cmd += ["--param", p]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return out_dir


def intervals(run_dir, db):
    """Per electrode: [(depth, amp, [(r, x, alive, neuron)])] in cycle order."""
    status, _, _, _ = session.read_telemetry(os.path.join(run_dir, "candump.log"), db)
    truth = session.read_truth(os.path.join(run_dir, "truth.jsonl"))
    out = {}
    for e, sl in status.items():
        lateral = {n: math.hypot(v["x_um"], v["y_um"]) for n, v in truth["neurons"][e].items()}
        ivs = truth["intervals"][e]
        rows = []
        for k, m in enumerate(sl):
            st = ivs[k]["state"] if k < len(ivs) else None
            if st is None:
                continue
            ns = [(lateral[n["neuron"]], n["depth_um"] - st["tip_um"], n["alive"], n["neuron"]) for n in st["neurons"]]
            rows.append((float(m["Depth_um"]), float(m["GuardAmp"]), ns))
        out[e] = rows
    return out


def nearest_ahead(ns, x_max):
    """The live neuron the tip approaches most closely within x_max ahead (smallest r)."""
    ahead = [(r, x, n) for r, x, alive, n in ns if alive and -5.0 < x <= x_max]
    return min(ahead, default=None)


def quantiles(v, qs=(0.05, 0.5, 0.95)):
    if not v:
        return "-"
    v = sorted(v)
    return " ".join(f"{v[min(len(v) - 1, int(q * len(v)))]:.4f}" for q in qs)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", action="append", required=True)
    ap.add_argument("--seeds", default="101-110")
    ap.add_argument("--out", required=True)
    ap.add_argument("--bin-dir", default=os.path.join(ROOT, "build", "release", "bin"))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--param", action="append", default=[])
    ap.add_argument("--baseline-um", type=float, default=15.0)
    ap.add_argument("--damage-um", type=float, default=12.0)
    ap.add_argument("--safe-um", type=float, default=20.0, help="lateral distance counted as passing safely")
    ap.add_argument("--x-max", type=float, default=60.0, help="axial look-ahead for the approached neuron")
    args = ap.parse_args(argv)
    db = canlog.load_dbc()
    jobs = []
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as ex:
        for sc in args.scenario:
            name = os.path.splitext(os.path.basename(sc))[0]
            for seed in parse_seeds(args.seeds):
                d = os.path.join(args.out, f"{name}-s{seed}")
                jobs.append(ex.submit(run_session, args.bin_dir, sc, seed, d, args.param))
        done = 0
        for j in concurrent.futures.as_completed(jobs):
            j.result()
            done += 1
            print(f"guard-cal: {done}/{len(jobs)} sessions", file=sys.stderr)
    danger, safe, climb_danger, climb_safe = [], [], [], []
    for j in jobs:
        for rows in intervals(j.result(), db).values():
            for k in range(1, len(rows)):
                depth, amp, ns = rows[k]
                # growth against the newest interval at least baseline_um shallower
                prev = next((rows[i] for i in range(k - 1, max(-1, k - 9), -1)
                             if depth - rows[i][0] >= args.baseline_um), None)
                near = nearest_ahead(ns, args.x_max)
                if prev is not None and prev[1] > 0 and amp > 0 and near is not None:
                    g = math.log(amp / prev[1]) / (depth - prev[0])
                    row = (g, amp, near[0], near[1])
                    (danger if near[0] < args.damage_um else safe if near[0] >= args.safe_um else []).append(row)
                pdepth, pamp, _ = rows[k - 1]
                if abs(depth - pdepth) < 3.0 and pamp > 0 and near is not None:
                    (climb_danger if near[0] < args.damage_um else climb_safe).append((amp / pamp - 1.0, amp, near[1]))
    report = {
        "advances_towards_killable": len(danger),
        "advances_towards_safe": len(safe),
        "g_killable_x_le_50": quantiles([g for g, a, r, x in danger if x <= 50]),
        "g_killable_x_gt_50": quantiles([g for g, a, r, x in danger if x > 50]),
        "g_safe": quantiles([g for g, a, r, x in safe]),
        "g_safe_amp_ge_12": quantiles([g for g, a, r, x in safe if a >= 12]),
        "amp_killable_x_le_25": quantiles([a for g, a, r, x in danger if x <= 25]),
        "still_climb_killable_x_le_30": quantiles([c for c, a, x in climb_danger if x <= 30]),
        "still_climb_safe": quantiles([c for c, a, x in climb_safe]),
    }
    print(json.dumps(report, indent=2))
    with open(os.path.join(args.out, "calibration.json"), "w") as f:
        json.dump({"report": report, "danger": danger, "safe": safe}, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
