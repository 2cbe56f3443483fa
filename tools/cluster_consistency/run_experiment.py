#!/usr/bin/env python3
"""Clustering-consistency experiment (thesis §3.5.2) over simulator exports.

For every scenario: export held-out calibration seeds and estimate the
process-noise scale q of Q = q^2 I from the true neurons' mean-waveform moves
between intervals (cluster-consistency --drift); then export the evaluation
seeds and cluster every interval with MAP (prior from interval k-1) and ML
(EM + Ward + BIC), and report the inconsistency Psi = sum_k |G^k - G^(k-1)|,
mean G, and how both compare with the true number of neurons in range.

Standard library only. Usage (from the repository root):
  tools/cluster_consistency/run_experiment.py --build build/release \
      [--seeds 1-5] [--calib-seeds 101-103] [--q-scales 1] [--jobs 2] \
      [--update-doc docs/clustering-consistency.md]
Prints the markdown tables; --update-doc replaces the generated block of
the document (between the BEGIN/END GENERATED markers).
"""
import argparse
import concurrent.futures as cf
import csv
import io
import math
import os
import shutil
import subprocess
import sys
import tempfile

SCENARIOS = ["crossing_clusters", "drift_away", "drifting_pair"]
BEGIN = "<!-- BEGIN GENERATED (tools/cluster_consistency/run_experiment.py) -->"
END = "<!-- END GENERATED -->"


def seed_list(text):
    out = []
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-")
            out.extend(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return out


def export(bindir, scenario, seed, workdir):
    out = os.path.join(workdir, f"{scenario}-{seed}")
    subprocess.run([os.path.join(bindir, "sim-export"), os.path.join("scenarios", scenario + ".yaml"), out,
                    "--seed", str(seed)], check=True, stdout=subprocess.DEVNULL)
    return out


def run_tool(bindir, rec, extra):
    r = subprocess.run([os.path.join(bindir, "cluster-consistency"), rec] + extra, check=True,
                       capture_output=True, text=True)
    return list(csv.DictReader(io.StringIO(r.stdout)))


def calibrate_job(bindir, scenario, seed, workdir):
    rec = export(bindir, scenario, seed, workdir)
    try:
        return [float(r["dq2_uv2"]) for r in run_tool(bindir, rec, ["--drift"])]
    finally:
        shutil.rmtree(rec, ignore_errors=True)


def eval_job(bindir, scenario, seed, workdir, q_values, map_evidence):
    rec = export(bindir, scenario, seed, workdir)
    try:
        return {q: run_tool(bindir, rec, ["--q-uv", f"{q:.6g}", "--map-evidence", map_evidence]) for q in q_values}
    finally:
        shutil.rmtree(rec, ignore_errors=True)


def psi(seq):
    return sum(abs(a - b) for a, b in zip(seq[1:], seq[:-1]))


def run_stats(rows):
    g_map = [int(r["g_map"]) for r in rows]
    g_ml = [int(r["g_ml"]) for r in rows]
    truth = [int(r["n_true"]) for r in rows]
    k = len(rows)

    def err(g):
        return sum(abs(a - b) for a, b in zip(g, truth)) / k

    def exact(g):
        return sum(1 for a, b in zip(g, truth) if a == b) / k

    return {
        "K": k, "g_map": g_map, "g_ml": g_ml, "truth": truth,
        "psi_map": psi(g_map), "psi_ml": psi(g_ml), "psi_true": psi(truth),
        "mean_map": sum(g_map) / k, "mean_ml": sum(g_ml) / k, "mean_true": sum(truth) / k,
        "err_map": err(g_map), "err_ml": err(g_ml), "exact_map": exact(g_map), "exact_ml": exact(g_ml),
        "acc_map": sum(float(r["acc_map"]) for r in rows) / k, "acc_ml": sum(float(r["acc_ml"]) for r in rows) / k,
        "spikes": sum(int(r["n_spikes"]) for r in rows) / k, "false": sum(int(r["n_false"]) for r in rows) / k,
    }


def rel(a, b):
    return "n/a" if b == 0 else f"{100.0 * (a - b) / b:+.0f} %"


def seq(s):
    return "".join(str(x) for x in s)


def aggregate(stats):
    k = sum(s["K"] for s in stats)
    agg = {"K": k, "runs": len(stats)}
    for key in ("psi_map", "psi_ml", "psi_true"):
        agg[key] = sum(s[key] for s in stats)
    for key in ("mean_map", "mean_ml", "mean_true", "err_map", "err_ml", "exact_map", "exact_ml", "acc_map",
                "acc_ml", "spikes", "false"):
        agg[key] = sum(s[key] * s["K"] for s in stats) / k
    return agg


def tables(results, q_by_scen, q_scales, calib, seeds):
    out = []
    out.append("### Calibrated process noise\n")
    out.append("| scenario | held-out seeds | neuron-interval pairs | q (µV per feature axis) |")
    out.append("|---|---|---|---|")
    for scen in SCENARIOS:
        out.append(f"| {scen} | {calib} | {q_by_scen[scen][1]} | {q_by_scen[scen][0]:.2f} |")
    out.append("")
    out.append("### Per run (q = calibrated value)\n")
    out.append("Ĝ per interval, one digit per interval (truth = neurons in range).\n")
    out.append("| scenario | seed | K | Ψ MAP | Ψ ML | MAP vs ML | Ψ truth | mean Ĝ MAP | mean Ĝ ML | mean N true "
               "| mean abs(Ĝ−N) MAP | ML | accuracy MAP | ML |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    seqs = []
    for scen in SCENARIOS:
        for seed in seeds:
            s = results[(scen, seed, 1.0)]
            out.append(f"| {scen} | {seed} | {s['K']} | {s['psi_map']} | {s['psi_ml']} | {rel(s['psi_map'], s['psi_ml'])} "
                       f"| {s['psi_true']} | {s['mean_map']:.2f} | {s['mean_ml']:.2f} | {s['mean_true']:.2f} "
                       f"| {s['err_map']:.2f} | {s['err_ml']:.2f} | {100 * s['acc_map']:.0f} % | {100 * s['acc_ml']:.0f} % |")
            seqs.append(f"{scen:17s} seed {seed:3d}  truth {seq(s['truth'])}\n"
                        f"{'':27s}MAP   {seq(s['g_map'])}\n{'':27s}ML    {seq(s['g_ml'])}")
    out.append("")
    out.append("```")
    out.extend(seqs)
    out.append("```")
    out.append("")
    out.append("### Aggregated\n")
    out.append("| scenario | q scale | runs | intervals | Ψ MAP | Ψ ML | MAP vs ML | Ψ truth | mean Ĝ MAP | mean Ĝ ML "
               "| mean N true | mean abs(Ĝ−N) MAP | ML | Ĝ = N MAP | ML | accuracy MAP | ML | detections per interval (false) |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for scale in q_scales:
        groups = [(scen, [results[(scen, sd, scale)] for sd in seeds]) for scen in SCENARIOS]
        groups.append(("**all**", [st for _, lst in groups for st in lst]))
        for name, lst in groups:
            a = aggregate(lst)
            out.append(f"| {name} | {scale:g} | {a['runs']} | {a['K']} | {a['psi_map']} | {a['psi_ml']} "
                       f"| {rel(a['psi_map'], a['psi_ml'])} | {a['psi_true']} | {a['mean_map']:.2f} | {a['mean_ml']:.2f} "
                       f"| {a['mean_true']:.2f} | {a['err_map']:.2f} | {a['err_ml']:.2f} | {100 * a['exact_map']:.0f} % "
                       f"| {100 * a['exact_ml']:.0f} % | {100 * a['acc_map']:.0f} % | {100 * a['acc_ml']:.0f} % "
                       f"| {a['spikes']:.0f} ({a['false']:.0f}) |")
    return "\n".join(out) + "\n"


def update_doc(path, text, command):
    with open(path, encoding="utf-8") as f:
        doc = f.read()
    a = doc.index(BEGIN) + len(BEGIN)
    b = doc.index(END)
    block = f"\n\nRegenerate: `{command}\n\n{text}\n"
    with open(path, "w", encoding="utf-8") as f:
        f.write(doc[:a] + block + doc[b:])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", required=True, help="build directory (its bin/ holds sim-export, cluster-consistency)")
    ap.add_argument("--seeds", default="1-5")
    ap.add_argument("--calib-seeds", default="101-103")
    ap.add_argument("--q-scales", default="1", help="comma list of factors applied to the calibrated q")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--map-evidence", default="laplace", choices=["laplace", "bic"],
                    help="evidence of the MAP method (thesis: laplace; bic is a diagnostic)")
    ap.add_argument("--update-doc", default=None)
    args = ap.parse_args()
    default_scenarios = ",".join(SCENARIOS)
    SCENARIOS[:] = [s for s in args.scenarios.split(",") if s]
    bindir = os.path.join(args.build, "bin")
    seeds = seed_list(args.seeds)
    calib = seed_list(args.calib_seeds)
    q_scales = [float(x) for x in args.q_scales.split(",")]
    if 1.0 not in q_scales:
        q_scales.insert(0, 1.0)
    workdir = tempfile.mkdtemp(prefix="cluster-consistency-")
    try:
        with cf.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            cal = {(sc, sd): pool.submit(calibrate_job, bindir, sc, sd, workdir) for sc in SCENARIOS for sd in calib}
            q_by_scen = {}
            for sc in SCENARIOS:
                vals = [v for sd in calib for v in cal[(sc, sd)].result()]
                if not vals:
                    sys.exit(f"no calibration data for {sc}")
                q_by_scen[sc] = (math.sqrt(sum(vals) / len(vals)), len(vals))
                print(f"{sc}: q = {q_by_scen[sc][0]:.2f} uV from {len(vals)} pairs", file=sys.stderr)
            jobs = {(sc, sd): pool.submit(eval_job, bindir, sc, sd, workdir,
                                          [q_by_scen[sc][0] * f for f in q_scales], args.map_evidence)
                    for sc in SCENARIOS for sd in seeds}
            results = {}
            for (sc, sd), fut in jobs.items():
                rows_by_q = fut.result()
                for f in q_scales:
                    results[(sc, sd, f)] = run_stats(rows_by_q[q_by_scen[sc][0] * f])
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    text = f"MAP evidence: {args.map_evidence}; ML: BIC.\n\n" + tables(results, q_by_scen, q_scales, f"{calib[0]}–{calib[-1]}" if len(calib) > 1 else str(calib[0]), seeds)
    print(text)
    if args.update_doc:
        cmd = (f"tools/cluster_consistency/run_experiment.py --build BUILD --seeds {args.seeds} "
               f"--calib-seeds {args.calib_seeds} --q-scales {args.q_scales} --map-evidence {args.map_evidence} "
               + ("" if args.scenarios == default_scenarios else f"--scenarios {args.scenarios} ") +
               f"--update-doc docs/clustering-consistency.md` (BUILD: a Release host build, e.g. "
               f"`cmake --preset release && cmake --build build/release` gives build/release)")
        update_doc(args.update_doc, text, cmd)


if __name__ == "__main__":
    main()
