#!/usr/bin/env python3
"""Evaluation suite: every shipped scenario x every tracker x many seeds, in-process sessions, one table.

    tools/eval/run_suite.py [--seeds 5] [--seed-start 1] [--scenarios a,b] [--with-stress] [--trackers 0,1,2,3]
                            [--param NAME=VALUE]... [--jobs 2] [--build-dir build/release] [--cache out/eval-suite]
                            [--max-duration-s S] [--force | --rerun-stale] [--safety]
                            [--md docs/evaluation.md] [--json FILE]

Scenario names are paths below scenarios/ without .yaml (`single_neuron`, `stress/dense_cells`); the default
is every scenarios/*.yaml, plus scenarios/stress/*.yaml with --with-stress. --param sets a controller
parameter in every run (cached apart). --safety writes the safety table instead (measured: docs/sfsm.md): per
scenario and tracker the neurons damaged and the closest approach of the tip to any neuron, with the
isolation figures next to them.

Each run is `microdrive-session --bus inproc --param tracker=N --no-lcm --no-plots --no-recording --quiet`
(tracker 0 MHTC, 1 MAP-NN, 2 ML-NN, 3 GNN; docs/evaluation.md) and is cached per (scenario, tracker, seed)
in CACHE/<scenario>/<tracker>/seed-<n>/ (report.json + run.json: command, exit, wall time, build id). A
rerun reuses every cached run whose goal matches: after a code change say so explicitly, --force (rerun
all) or --rerun-stale (rerun the runs made by another build). The table names the build(s) it comes from
and flags a mixed table. Running and summarising: microdrive.evaluation (python/), on tools/session/score.py's
reports. Children run under nice (--nice, default 10). Progress: one line per run on stderr.
Exit 0; 1 when a run failed (the table still written, failures counted).
"""
import argparse
import concurrent.futures
import datetime
import glob
import hashlib
import json
import os
import statistics
import sys
import threading

from microdrive import evaluation

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

TRACKERS = {0: "MHTC", 1: "MAP-NN", 2: "ML-NN", 3: "GNN"}

# The thesis's own figures (M. T. Wolf, Caltech 2008) next to which ours are shown. Ψ per interval: §3.5.2
# gives Ψ over 100 sessions, 21 914 intervals: 3516 for the MAP clustering (ch. 3, our MAP-NN tracker) and
# 17 646 for ML (our ML-NN). MHTC itself (ch. 4) is reported with figures only (Figs. 4.4-4.15), and the
# closed loop (ch. 5) with two example sessions (Figs. 5.5, 5.6).
THESIS_PSI_PER_INTERVAL = {1: 3516 / 21914, 2: 17646 / 21914}
THESIS_INTERVALS = 21914


# ---- running ----------------------------------------------------------------------------------------------

def build_id(session_bin):
    """Identity of the code under test: sha256 of the microdrive-session binary (the whole controller and
    simulator are linked into it)."""
    h = hashlib.sha256()
    with open(session_bin, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return {"binary_sha256": h.hexdigest()[:16]}


def scenario_duration_s(path):
    with open(path) as f:
        for line in f:
            if line.startswith("duration_s:"):
                return float(line.split(":", 1)[1].split("#")[0])
    return None


def goal_of(args, scen_path):
    """The session goal: the scenario's duration, capped by --max-duration-s."""
    d = scenario_duration_s(scen_path)
    if args.max_duration_s and (d is None or d > args.max_duration_s):
        d = args.max_duration_s
    return {"duration_s": d} if d else {}


def run_dir(args, scen, tracker, seed):
    variant = TRACKERS[tracker] + "".join(f"+{p}" for p in args.param)
    return os.path.join(args.cache, scen, variant, f"seed-{seed}")


def load_cached(d):
    try:
        with open(os.path.join(d, "run.json")) as f:
            run = json.load(f)
        with open(os.path.join(d, "report.json")) as f:
            return run, json.load(f)
    except (OSError, ValueError):
        return None, None


def run_one(args, job, bid):
    scen, scen_path, tracker, seed = job
    d = run_dir(args, scen, tracker, seed)
    goal = goal_of(args, scen_path)
    run, report = load_cached(d)
    fresh = run is not None and run.get("goal") == goal and run.get("exit") in (0, 4)
    if fresh and not args.force and not (args.rerun_stale and run.get("build") != bid):
        return job, run, report, True
    os.makedirs(d, exist_ok=True)
    for name in ("report.json", "run.json"):
        if os.path.exists(os.path.join(d, name)):
            os.remove(os.path.join(d, name))
    extra = ["--param", f"tracker={tracker}", "--no-plots"]
    for p in args.param:
        extra += ["--param", p]
    if goal:
        extra += ["--duration-s", f"{goal['duration_s']:g}"]
    cmd = evaluation.session_command(args.session, scen_path, seed, d, extra)
    rc, wall, report, tail = evaluation.run_session(args.session, scen_path, seed, d, extra, args.nice,
                                                    args.keep_logs)
    run = {"scenario": scen, "tracker": tracker, "seed": seed, "goal": goal, "exit": rc,
           "wall_s": round(wall, 2), "build": bid, "cmd": [os.path.relpath(c, ROOT) if os.path.isabs(c) else c
                                                           for c in cmd],
           "finished": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
           "tail": tail[-1500:] if report is None else ""}
    with open(os.path.join(d, "run.json"), "w") as f:
        json.dump(run, f, indent=1)
    return job, run, report, False


def progress_line(i, n, job, run, report, cached):
    scen, _, tracker, seed = job
    head = f"[{i}/{n}] {scen} {TRACKERS[tracker]} seed {seed}"
    if report is None:
        return f"{head}: FAILED (exit {run['exit']})\n{run.get('tail', '')}"
    els = ", ".join(
        f"e{e['electrode']} {'iso@' + str(e['cycles_to_isolation']) if e['isolated'] else 'not iso'}"
        f" acc {evaluation.fmt(e['tracking']['accuracy'])} psi {e['tracking']['psi']}"
        for e in report["electrodes"])
    took = "cached" if cached else f"{run['wall_s']:.0f} s"
    return f"{head}: {took}: {els}"


# ---- summarising --------------------------------------------------------------------------------------------

def summarise(runs):
    """evaluation.summarise plus the per-electrode figures it leaves out (spurious tracks, Ψ per interval)."""
    results = [(r["seed"], r["exit"], r["wall_s"], rep, "") for r, rep in runs]
    s = evaluation.summarise(results)
    els = [e for _, rep in runs if rep for e in rep["electrodes"]]
    s["mean_spurious_tracks"] = statistics.fmean([e["tracking"]["spurious_tracks"] for e in els]) if els else None
    cycles = sum(max(0, e["cycles"] - 1) for e in els if e["tracking"]["psi"] is not None)
    psi = sum(e["tracking"]["psi"] for e in els if e["tracking"]["psi"] is not None)
    s["psi_per_interval"] = (psi / cycles) if cycles else None
    s["mean_id_switches"] = statistics.fmean([e["tracking"]["id_switches"] for e in els]) if els else None
    ids = [max(e["tracking"].get("track_ids_per_neuron", {}).values(), default=0) for e in els]
    s["max_track_ids_per_neuron"] = max(ids, default=None)
    s["electrodes_over_two_track_ids"] = sum(1 for n in ids if n > 2)
    s["cycles"] = sum(e["cycles"] for e in els)
    closest = [e["closest_approach_um"] for e in els if e.get("closest_approach_um") is not None]
    s["closest_approach_min_um"] = min(closest) if closest else None
    s["closest_approach_p05_um"] = sorted(closest)[int(0.05 * len(closest))] if closest else None
    s["closest_approach_median_um"] = statistics.median(closest) if closest else None
    s["guard_limited_cycles"] = sum(e.get("guard_limited_cycles", 0) for e in els)
    s["guard_retractions"] = sum(e.get("guard_retractions", 0) for e in els)
    return s


def fmt(x, spec=".2f"):
    return evaluation.fmt(x, spec)


COLUMNS = [
    ("runs (failed)", lambda s: f"{s['sessions']} ({s['sessions_failed']})"),
    ("accuracy", lambda s: fmt(s["mean_accuracy"])),
    ("ID consistency", lambda s: fmt(s["mean_id_consistency"])),
    ("spurious tracks / electrode", lambda s: fmt(s["mean_spurious_tracks"], ".1f")),
    ("Ψ / interval", lambda s: fmt(s["psi_per_interval"], ".3f")),
    ("isolation rate", lambda s: fmt(s["isolation_rate"], ".0%")),
    ("median time to isolation (s)", lambda s: fmt(s["median_time_to_isolation_s"], ".0f")),
    ("median distance to peak, isolated (µm)", lambda s: fmt(s["median_final_distance_um_isolated"], ".1f")),
    ("neurons damaged (runs)", lambda s: f"{s['neurons_damaged_total']} ({s['sessions_with_damage']})"),
    ("scenario criterion", None),
    ("median wall (s)", lambda s: fmt(s["median_wall_s"], ".0f")),
]


SAFETY_COLUMNS = [
    ("runs (failed)", lambda s: f"{s['sessions']} ({s['sessions_failed']})"),
    ("neurons damaged (runs)", lambda s: f"{s['neurons_damaged_total']} ({s['sessions_with_damage']})"),
    ("killed by the insertion", lambda s: str(s.get("neurons_damaged_at_insertion_total", 0))),
    ("closest approach: min / 5 % / median (µm)", lambda s: " / ".join(
        fmt(s[k], ".1f") for k in ("closest_approach_min_um", "closest_approach_p05_um", "closest_approach_median_um"))),
    ("isolation rate", lambda s: fmt(s["isolation_rate"], ".0%")),
    ("median time to isolation (s)", lambda s: fmt(s["median_time_to_isolation_s"], ".0f")),
    ("median distance to peak, isolated (µm)", lambda s: fmt(s["median_final_distance_um_isolated"], ".1f")),
    ("guard: limited cycles / retractions", lambda s: f"{s['guard_limited_cycles']} / {s['guard_retractions']}"),
]


def build_line(args, builds):
    """The builds a table comes from, flagged when they are several or not the binary in --build-dir."""
    shas = [b["binary_sha256"] for b in builds if b]
    stale = any(sha != args.current_build["binary_sha256"] for sha in shas)
    line = f"microdrive-session sha256 {', '.join(shas)}"
    if len(shas) > 1:
        line += " (MIXED: rerun with --rerun-stale)"
    elif stale:
        line += (f" (NOT the build in {args.build_dir}, sha256 {args.current_build['binary_sha256']}: "
                 "cached runs; rerun with --rerun-stale)")
    return line, stale


def safety_markdown(args, table, builds, started, finished, n_runs, n_cached, n_failed):
    """The safety sweep: damage and closest approach per scenario and tracker."""
    total_runs = sum(s["sessions"] for _, s in table)
    damaged = sum(s["neurons_damaged_total"] for _, s in table)
    worst = min((s["closest_approach_min_um"] for _, s in table if s["closest_approach_min_um"] is not None),
                default=None)
    lines = [
        "# Safety sweep: neurons damaged and closest approach",
        "",
        "Generated by `tools/eval/run_suite.py --safety` (the command below); do not edit by hand. A neuron dies "
        "when the tip comes closer than the simulator's damage radius (12 µm by default, docs/simulator.md); the "
        "closest approach is the smallest tip-soma distance of a session over every neuron of an electrode "
        "(`closest_approach_um`, docs/session.md). The approach guard is described in docs/sfsm.md.",
        "",
        "```",
        " ".join(["tools/eval/run_suite.py"] + args.argv),
        "```",
        "",
        f"Runs {n_runs} ({n_cached} from the cache, {n_failed} failed), {started} to {finished} UTC, "
        f"build(s): {build_line(args, builds)[0]}.",
        "",
        f"**Neurons damaged: {damaged} in {total_runs} sessions; smallest closest approach "
        f"{fmt(worst, '.1f')} µm.**",
        "",
        "| scenario | tracker | " + " | ".join(c for c, _ in SAFETY_COLUMNS) + " |",
        "|---|---|" + "---|" * len(SAFETY_COLUMNS),
    ]
    for (n, t), s in table:
        lines.append(f"| {n} | {TRACKERS[t]} | " + " | ".join(f(s) for _, f in SAFETY_COLUMNS) + " |")
    lines.append("")
    return "\n".join(lines)


def criterion(scen, s):
    """The scenario's own acceptance figure (docs/session.md, 'Evaluation')."""
    if scen == "empty_tissue":
        return f"never isolated {fmt(s['never_isolated_rate'], '.0%')}"
    if scen == "drift_away":
        return f"re-isolated {fmt(s['reisolation_rate'], '.0%')}"
    return f"held {fmt(s['mean_held_fraction'])}"


def markdown(args, table, builds, started, finished, n_runs, n_cached, n_failed):
    lines = []
    w = lines.append
    w("# Evaluation: MHTC against the baseline trackers over every scenario")
    w("")
    w("Generated by `tools/eval/run_suite.py` (the command below); do not edit by hand. Definitions of every "
      "figure: docs/session.md (\"report.json\"); trackers: `tracker` parameter (docs/protocol.md).")
    w("")
    w("```")
    w(" ".join(["tools/eval/run_suite.py"] + args.argv))
    w("```")
    w("")
    w(f"- runs: {n_runs} (scenario × tracker × seed), {n_failed} failed, {n_cached} taken from the cache; seeds "
      f"{args.seed_start}..{args.seed_start + args.seeds - 1}; in-process bus, `--param tracker=N`; session goal: "
      f"each scenario's `duration_s`" + (f", capped at {args.max_duration_s:g} s simulated" if args.max_duration_s
                                         else ""))
    w(f"- build(s): {build_line(args, builds)[0]}")
    w(f"- run from {started} to {finished} (UTC), {args.jobs} parallel jobs under nice {args.nice}")
    w("")
    w("Per scenario and tracker, pooled over seeds and electrodes: accuracy = mean spike accuracy per (interval, "
      "in-range neuron) pair (TP/(TP+FN+FP) with the Hungarian-assigned track); ID consistency = share of "
      "(neuron, in-range interval) pairs labelled with the neuron's majority track; spurious tracks = tracks most "
      "of whose detections match no single neuron, per electrode; Ψ / interval = Σ|Ĝᵏ − Ĝᵏ⁻¹| over the number "
      "of interval transitions (thesis §3.5.2 sums it over sessions); isolation rate = electrodes isolated at "
      "least once; time to isolation and distance to the dominant neuron's SNR peak at the end (isolated "
      "electrodes), medians; damage = neurons killed by an electrode. Scenario criterion: empty_tissue = share "
      "of electrodes never isolated (should be 100 %), drift_away = share of isolated electrodes that isolated "
      "again after a loss, otherwise the mean fraction of cycles held isolated after the first isolation.")
    w("")
    w("| scenario | tracker | " + " | ".join(c for c, _ in COLUMNS) + " |")
    w("|---|---|" + "---|" * len(COLUMNS))
    for (scen, tracker), s in table:
        cells = [criterion(scen, s) if f is None else f(s) for _, f in COLUMNS]
        w(f"| {scen} | {TRACKERS[tracker]} | " + " | ".join(cells) + " |")
    w("")
    thesis_section(w, table)
    return "\n".join(lines) + "\n"


def thesis_section(w, table):
    """The few figures of the thesis that have a counterpart here, next to ours (all scenarios pooled)."""
    w("## Next to the thesis")
    w("")
    w("The thesis evaluates on macaque recordings without ground truth, so only a few of its figures have a "
      "counterpart here:")
    w("")
    w("| figure | thesis | here (all scenarios pooled) |")
    w("|---|---|---|")
    pooled = {}
    for (scen, tracker), s in table:
        p = pooled.setdefault(tracker, [0.0, 0])
        if s["psi_per_interval"] is not None:
            # re-weight by transitions: psi_per_interval * transitions
            trans = s["_transitions"]
            p[0] += s["psi_per_interval"] * trans
            p[1] += trans
    for tracker in sorted(pooled):
        psi, trans = pooled[tracker]
        thesis = THESIS_PSI_PER_INTERVAL.get(tracker)
        thesis_txt = {1: f"MAP clustering: Ψ = 3516 over {THESIS_INTERVALS} intervals = {thesis:.3f} (§3.5.2)"
                      if thesis else "",
                      2: f"ML clustering: Ψ = 17 646 over {THESIS_INTERVALS} intervals = {thesis:.3f} (§3.5.2)"
                      if thesis else ""}.get(tracker, "no figure (ch. 4 reports MHTC's tracks as plots, "
                                                      "Figs. 4.4-4.15)" if tracker == 0 else "no figure")
        w(f"| Ψ / interval, {TRACKERS[tracker]} | {thesis_txt} | "
          f"{fmt(psi / trans if trans else None, '.3f')} over {trans} transitions |")
    w("| MAP vs ML consistency | Ψ 80 % lower with MAP than ML (§3.5.2) | "
      + ratio_text(pooled) + " |")
    w("| time to isolation | Fig. 5.5: isolation at interval k = 7 (one example session) | "
      "see 'median time to isolation' per scenario (intervals of ~10 s plus moves) |")
    w("| re-isolation | Fig. 5.6: SNR drops over 6 intervals, retraction re-isolates (one example) | "
      "drift_away criterion above |")
    w("| cost per interval | §4.6: 2-20 s per interval (non-optimised MATLAB, mean ~10 s) | docs/benchmarks.md |")
    w("")


def ratio_text(pooled):
    def per(t):
        psi, trans = pooled.get(t, [0.0, 0])
        return psi / trans if trans else None
    a, b = per(1), per(2)
    if a is None or b is None or b <= 0:
        return "-"
    return f"MAP-NN Ψ {100 * (1 - a / b):.0f} % lower than ML-NN"


# ---- main ---------------------------------------------------------------------------------------------------

def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--seed-start", type=int, default=1)
    ap.add_argument("--scenarios", default="", help="comma-separated names (default: every scenarios/*.yaml)")
    ap.add_argument("--with-stress", action="store_true", help="add every scenarios/stress/*.yaml")
    ap.add_argument("--param", action="append", default=[], help="NAME=VALUE for every run (repeatable)")
    ap.add_argument("--safety", action="store_true", help="write the safety table (neurons damaged, closest approach)")
    ap.add_argument("--trackers", default="0,1,2,3")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--cache", default=os.path.join(ROOT, "out", "eval-suite"))
    ap.add_argument("--max-duration-s", type=float, default=None)
    rerun = ap.add_mutually_exclusive_group()
    rerun.add_argument("--force", action="store_true", help="rerun every run (ignore the cache)")
    rerun.add_argument("--rerun-stale", action="store_true", help="rerun the runs made by another build")
    ap.add_argument("--md", default=None, help="write the markdown table here (e.g. docs/evaluation.md)")
    ap.add_argument("--json", default=None, help="write the summaries here")
    ap.add_argument("--keep-logs", action="store_true")
    args = ap.parse_args(argv)
    args.argv = [a if not os.path.isabs(a) else os.path.relpath(a, ROOT) for a in argv]
    return args


def scenario_names(args):
    names = [n for n in args.scenarios.split(",") if n] or sorted(
        os.path.splitext(os.path.basename(p))[0] for p in glob.glob(os.path.join(ROOT, "scenarios", "*.yaml")))
    if args.with_stress:
        names += sorted("stress/" + os.path.splitext(os.path.basename(p))[0]
                        for p in glob.glob(os.path.join(ROOT, "scenarios", "stress", "*.yaml")))
    return names


def jobs_of(args):
    names = scenario_names(args)
    trackers = [int(t) for t in args.trackers.split(",") if t]
    for t in trackers:
        if t not in TRACKERS:
            raise SystemExit(f"run_suite: unknown tracker {t} (0..3)")
    jobs = []
    for n in names:
        path = os.path.join(ROOT, "scenarios", f"{n}.yaml")
        if not os.path.exists(path):
            raise SystemExit(f"run_suite: no scenario {path}")
        for t in trackers:
            for seed in range(args.seed_start, args.seed_start + args.seeds):
                jobs.append((n, path, t, seed))
    # the longest sessions first, so that the last minutes are not one long run on one core
    cost = {n: (scenario_duration_s(os.path.join(ROOT, "scenarios", f"{n}.yaml")) or 0) for n in names}
    jobs.sort(key=lambda j: -cost[j[0]] * (3 if j[0] == "three_electrodes" else 1))
    return names, trackers, jobs


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    args.session = os.path.join(args.build_dir, "bin", "microdrive-session")
    if not os.access(args.session, os.X_OK):
        raise SystemExit(f"run_suite: no {args.session} (build first, or --build-dir)")
    names, trackers, jobs = jobs_of(args)
    bid = build_id(args.session)
    args.current_build = bid
    started = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    print(f"run_suite: {len(jobs)} runs ({len(names)} scenarios x {len(trackers)} trackers x {args.seeds} seeds), "
          f"{args.jobs} jobs, microdrive-session sha256 {bid['binary_sha256']}, cache {args.cache}", file=sys.stderr)
    done = {}
    lock = threading.Lock()
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as ex:
        futs = [ex.submit(run_one, args, j, bid) for j in jobs]
        for i, fut in enumerate(concurrent.futures.as_completed(futs), 1):
            job, run, report, cached = fut.result()
            with lock:
                done[job] = (run, report, cached)
                print(progress_line(i, len(jobs), job, run, report, cached), file=sys.stderr, flush=True)
    finished = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    table, builds = [], []
    for n in names:
        for t in trackers:
            runs = [(done[j][0], done[j][1]) for j in jobs if j[0] == n and j[2] == t]
            s = summarise(runs)
            s["_transitions"] = sum(max(0, e["cycles"] - 1) for _, rep in runs if rep for e in rep["electrodes"]
                                    if e["tracking"]["psi"] is not None)
            table.append(((n, t), s))
            for r, _ in runs:
                if r.get("build") not in builds:
                    builds.append(r.get("build"))
    n_failed = sum(1 for r, rep, _ in done.values() if rep is None)
    n_cached = sum(1 for _, _, c in done.values() if c)
    if len(builds) > 1 or build_line(args, builds)[1]:
        print(f"run_suite: WARNING: the table comes from {build_line(args, builds)[0]}", file=sys.stderr)
    write = safety_markdown if args.safety else markdown
    md = write(args, table, builds, started, finished, len(jobs), n_cached, n_failed)
    if args.md:
        with open(args.md, "w") as f:
            f.write(md)
        print(f"run_suite: wrote {args.md}", file=sys.stderr)
    else:
        sys.stdout.write(md)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"builds": builds, "summaries": [{"scenario": n, "tracker": TRACKERS[t], **s}
                                                       for (n, t), s in table]}, f, indent=1)
    return 1 if n_failed else 0


if __name__ == "__main__":
    sys.exit(main())
