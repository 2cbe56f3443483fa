"""Closed-loop sessions over seeds: run one, summarise many, and hold figures against regression bounds.

    from microdrive import evaluation
    rc, wall_s, report, tail = evaluation.run_session("build/release/bin/microdrive-session",
                                                      "scenarios/single_neuron.yaml", seed=1, out="out/s1")
    summary = evaluation.summarise([(1, rc, wall_s, report, tail)])

The evaluation suite (tools/eval/run_suite.py) and its regression checks (tools/eval/regression.py,
tools/external_eval/external_eval.py's bounds, tests/integration/test_session_regression.py) use these;
every figure is defined in docs/session.md ("report.json").
"""
import datetime
import json
import os
import statistics
import subprocess
import time

SESSION_FLAGS = ("--bus", "inproc", "--no-lcm", "--no-recording", "--quiet")


def session_command(session_bin, scenario, seed, out, extra=()):
    """The command line of one in-process session without LCM, recording or output (extra: more options,
    e.g. --duration-s S, --param NAME=VALUE)."""
    return [session_bin, "--scenario", scenario, "--seed", str(seed), "--out", out, *SESSION_FLAGS, *extra]


def run_session(session_bin, scenario, seed, out, extra=(), nice=0, keep_logs=False):
    """Runs session_command(...) with `nice`. Returns (exit status, wall time s, report.json as a dict or
    None, the last 2000 characters of its output). The frame log and the truth are deleted unless keep_logs."""
    cmd = session_command(session_bin, scenario, seed, out, extra)
    t0 = time.monotonic()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                       preexec_fn=(lambda: os.nice(nice)) if nice else None)
    wall = time.monotonic() - t0
    report = None
    path = os.path.join(out, "report.json")
    if p.returncode in (0, 4) and os.path.exists(path):
        with open(path) as f:
            report = json.load(f)
    if not keep_logs:
        for name in ("candump.log", "truth.jsonl"):
            if os.path.exists(os.path.join(out, name)):
                os.remove(os.path.join(out, name))
    return p.returncode, wall, report, p.stdout[-2000:]


def median(xs):
    return statistics.median(xs) if xs else None


def mean(xs):
    return statistics.fmean(xs) if xs else None


def fmt(x, spec=".2f"):
    return "-" if x is None else format(x, spec)


def summarise(results):
    """The acceptance figures of sessions [(seed, exit, wall_s, report or None, output tail)]."""
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


# ---- regression bounds ----------------------------------------------------------------------------------------

def make_bounds(figures, margin_of):
    """{key: {"measured": v, "min"|"max": bound}} for figures {key: value}; margin_of(key) gives
    (direction, margin). Figures that are None are left out."""
    checks = {}
    for key, v in figures.items():
        if v is None:
            continue
        direction, margin = margin_of(key)
        bound = v - margin if direction == "min" else v + margin
        checks[key] = {"measured": round(v, 4), direction: round(bound, 4)}
    return checks


def write_thresholds(path, about, command, build, checks):
    """Write a thresholds file: what it is, the command that measured it, the build, the date, the bounds."""
    doc = {
        "about": about,
        "command": command,
        "build": build,
        "measured_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="minutes"),
        "checks": checks,
    }
    with open(path, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


def check_bounds(checks, got, prefix="regression"):
    """Print one ok/FAIL line per bound of `checks` against the figures `got`; return the failure count.
    A figure that is missing from `got` fails."""
    fails = 0
    for key, c in sorted(checks.items()):
        v = got.get(key)
        if "min" in c:
            ok, rule = v is not None and v >= c["min"], f">= {c['min']}"
        else:
            ok, rule = v is not None and v <= c["max"], f"<= {c['max']}"
        fails += not ok
        print(f"{'ok  ' if ok else 'FAIL'} {key}: {v if v is None else round(v, 4)} (bound {rule}, measured "
              f"{c['measured']})")
    print(f"{prefix}: {len(checks) - fails} passed, {fails} failed")
    return fails
