#!/usr/bin/env python3
"""Runs a scenario over many seeds with microdrive-session and prints the
acceptance table (docs/session.md, "Evaluation").

    tools/session/evaluate.py --scenario scenarios/single_neuron.yaml --seeds 20 --bus inproc
        [--seed-start 1] [--cycles N | --duration-s S] [--jobs J] [--out DIR]
        [--build-dir build/release] [--json FILE] [--keep-logs]

Every session writes DIR/seed-<n>/report.json (frame logs without REC_DATA,
deleted after scoring unless --keep-logs). The table, per scenario:
isolation rate (electrodes isolated at least once), median final distance to
the dominant neuron's SNR peak (isolated electrodes, and all), neurons
damaged, re-isolation rate (isolated electrodes that isolated again after a
loss: the drift_away criterion), never-isolated rate (the empty_tissue
criterion), mean spike accuracy, ID consistency, Psi, time to isolation.
"""
import argparse
import concurrent.futures
import json
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def run_one(args, seed):
    out = os.path.join(args.out, f"seed-{seed}")
    cmd = [os.path.join(args.build_dir, "bin", "microdrive-session"), "--scenario", args.scenario, "--seed",
           str(seed), "--bus", args.bus, "--out", out, "--quiet", "--no-recording", "--no-lcm"]
    if args.cycles:
        cmd += ["--cycles", str(args.cycles)]
    elif args.duration_s:
        cmd += ["--duration-s", str(args.duration_s)]
    t0 = time.monotonic()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wall = time.monotonic() - t0
    report = None
    path = os.path.join(out, "report.json")
    if p.returncode in (0, 4) and os.path.exists(path):
        with open(path) as f:
            report = json.load(f)
    if not args.keep_logs:
        for name in ("candump.log", "truth.jsonl"):
            try:
                os.remove(os.path.join(out, name))
            except OSError:
                pass
    return seed, p.returncode, wall, report, p.stdout[-2000:]


def median(xs):
    return statistics.median(xs) if xs else None


def mean(xs):
    return statistics.fmean(xs) if xs else None


def fmt(x, spec=".2f"):
    return "-" if x is None else format(x, spec)


def summarise(results):
    els = [e for _, rc, _, r, _ in results if r for e in r["electrodes"]]
    iso = [e for e in els if e["isolated"]]
    dist_iso = [e["final_peak_distance_um"] for e in iso if e["final_peak_distance_um"] is not None]
    dist_all = [e["final_peak_distance_um"] for e in els if e["final_peak_distance_um"] is not None]
    acc = [e["tracking"]["accuracy"] for e in els if e["tracking"]["accuracy"] is not None]
    cons = [e["tracking"]["id_consistency"] for e in els if e["tracking"]["id_consistency"] is not None]
    return {
        "sessions": len(results),
        "sessions_failed": sum(1 for _, rc, _, r, _ in results if r is None),
        "electrodes": len(els),
        "isolation_rate": (len(iso) / len(els)) if els else None,
        "never_isolated_rate": (1 - len(iso) / len(els)) if els else None,
        "median_final_distance_um_isolated": median(dist_iso),
        "median_final_distance_um_all": median(dist_all),
        "neurons_damaged_total": sum(e["neurons_damaged"] for e in els),
        "neurons_damaged_at_insertion_total": sum(e.get("neurons_damaged_at_insertion", 0) for e in els),
        "sessions_with_damage": sum(1 for _, _, _, r, _ in results
                                    if r and any(e["neurons_damaged"] for e in r["electrodes"])),
        "reisolation_rate": (sum(1 for e in iso if e["reisolations"] > 0) / len(iso)) if iso else None,
        "median_time_to_isolation_s": median([e["time_to_isolation_s"] for e in iso if e["time_to_isolation_s"]]),
        "mean_held_fraction": mean([e["held_fraction"] for e in iso if e["held_fraction"] is not None]),
        "mean_accuracy": mean(acc),
        "mean_id_consistency": mean(cons),
        "mean_psi": mean([e["tracking"]["psi"] for e in els if e["tracking"]["psi"] is not None]),
        "median_wall_s": median([w for _, _, w, _, _ in results]),
    }


def print_table(name, s):
    rows = [
        ("sessions (failed)", f"{s['sessions']} ({s['sessions_failed']})"),
        ("electrodes", str(s["electrodes"])),
        ("isolation rate", fmt(s["isolation_rate"], ".0%")),
        ("never isolated (empty_tissue criterion)", fmt(s["never_isolated_rate"], ".0%")),
        ("median final distance, isolated (um)", fmt(s["median_final_distance_um_isolated"], ".1f")),
        ("median final distance, all (um)", fmt(s["median_final_distance_um_all"], ".1f")),
        ("neurons damaged (sessions with damage)", f"{s['neurons_damaged_total']} ({s['sessions_with_damage']})"),
        ("re-isolation rate (drift_away criterion)", fmt(s["reisolation_rate"], ".0%")),
        ("median time to isolation (s)", fmt(s["median_time_to_isolation_s"], ".0f")),
        ("mean held fraction", fmt(s["mean_held_fraction"])),
        ("mean spike accuracy", fmt(s["mean_accuracy"])),
        ("mean ID consistency", fmt(s["mean_id_consistency"])),
        ("mean Psi", fmt(s["mean_psi"], ".1f")),
        ("median wall time per session (s)", fmt(s["median_wall_s"], ".1f")),
    ]
    print(f"\n| {name} | |\n|---|---|")
    for k, v in rows:
        print(f"| {k} | {v} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--seeds", type=int, required=True)
    ap.add_argument("--seed-start", type=int, default=1)
    ap.add_argument("--bus", default="inproc")
    goal = ap.add_mutually_exclusive_group()
    goal.add_argument("--cycles", type=int)
    goal.add_argument("--duration-s", type=float)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", default=None)
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--json", default=None)
    ap.add_argument("--keep-logs", action="store_true")
    args = ap.parse_args()
    name = os.path.splitext(os.path.basename(args.scenario))[0]
    args.out = args.out or os.path.join(ROOT, "out", f"eval-{name}")
    os.makedirs(args.out, exist_ok=True)
    seeds = range(args.seed_start, args.seed_start + args.seeds)
    results = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as ex:
        for seed, rc, wall, report, tail in ex.map(lambda s: run_one(args, s), seeds):
            results.append((seed, rc, wall, report, tail))
            if report is None:
                print(f"seed {seed}: FAILED (exit {rc})\n{tail}", file=sys.stderr)
                continue
            line = ", ".join(
                f"e{e['electrode']}: {'isolated at ' + str(e['cycles_to_isolation']) if e['isolated'] else 'not isolated'}"
                f", dist {fmt(e['final_peak_distance_um'], '.1f')} um, damaged {e['neurons_damaged']}"
                f", re-iso {e['reisolations']}, acc {fmt(e['tracking']['accuracy'])}" for e in report["electrodes"])
            print(f"seed {seed} ({wall:.0f} s): {line}", file=sys.stderr)
    s = summarise(results)
    print_table(f"{name}, {args.seeds} seeds from {args.seed_start}, bus {args.bus}", s)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"scenario": name, "seeds": list(seeds), "bus": args.bus, "summary": s,
                       "reports": [r for _, _, _, r, _ in results]}, f, indent=2)
    return 1 if s["sessions_failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
