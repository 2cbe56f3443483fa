#!/usr/bin/env python3
"""Fault campaign: every fault scenario x seeds through microdrive-session,
each frame log checked by check_invariants.py; counts to docs/fault-campaign.md.

usage: campaign.py [--seeds N] [--bus inproc] [--kinds a,b] [--cycles N]
                   [--timeout-s S] [--max-log-mb M] [--session PATH] [--out DIR] [--doc PATH]

A run that does not end within --timeout-s (wall) or whose log passes
--max-log-mb is stopped and counted as `no_end`; its partial log is still
checked (an invariant violated in a prefix is violated).
"""
import argparse
import glob
import json
import os
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
CHECK = os.path.join(HERE, "check_invariants.py")


def run_session(a, scen, seed, out):
    os.makedirs(out, exist_ok=True)
    cmd = [a.session, "--scenario", scen, "--seed", str(seed), "--bus", a.bus, "--out", out,
           "--cycles", str(a.cycles), "--quiet", "--no-score"]
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    t0, log = time.time(), os.path.join(out, "candump.log")
    while p.poll() is None:
        time.sleep(0.2)
        big = os.path.exists(log) and os.path.getsize(log) > a.max_log_mb * 1e6
        if time.time() - t0 > a.timeout_s or big:
            os.killpg(p.pid, signal.SIGTERM)
            p.wait()
            return "no_end", time.time() - t0
    return ("ok" if p.returncode in (0, 4) else f"rc{p.returncode}"), time.time() - t0


def check(a, out):
    log = os.path.join(out, "candump.log")
    if not os.path.exists(log):
        return None
    cmd = [sys.executable, CHECK, log, "--json", os.path.join(out, "invariants.json")] + a.check_args
    p = subprocess.run(cmd, capture_output=True, text=True)
    try:
        return json.loads(p.stdout)
    except ValueError:
        return None


def write_doc(a, rows, path):
    invs = ["window", "step_cmd", "step_meas", "rec_motion", "unasked", "hb_lost", "estop", "restart"]
    lines = ["# Fault campaign", "",
             f"Regenerate: `.venv/bin/python tools/safety/campaign.py --seeds {a.seeds} --bus {a.bus} "
             f"--cycles {a.cycles} --timeout-s {a.timeout_s:g}` (fault scenarios in scenarios/faults/, "
             "invariants in docs/safety.md).", "",
             "| fault | runs | ended | passed | " + " | ".join(invs) + " |",
             "|---|---|---|---|" + "---|" * len(invs)]
    for kind, rs in rows.items():
        ended = sum(1 for r in rs if r["end"] == "ok")
        passed = sum(1 for r in rs if r["summary"] and r["summary"]["ok"])
        per = [sum(1 for r in rs if r["summary"] and r["summary"]["violations_by_invariant"].get(i, 0) > 0)
               for i in invs]
        lines.append(f"| {kind} | {len(rs)} | {ended} | {passed} | " + " | ".join(map(str, per)) + " |")
    lines += ["", "Invariant columns count runs with at least one violation of that invariant.",
              "`ended`: the session reached its goal (or went idle) before the timeout.", ""]
    with open(path, "w") as f:
        f.write("\n".join(lines))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--bus", default="inproc")
    p.add_argument("--kinds", default="", help="comma-separated subset of scenarios/faults/*.yaml names")
    p.add_argument("--cycles", type=int, default=20)
    p.add_argument("--timeout-s", type=float, default=300.0)
    p.add_argument("--max-log-mb", type=float, default=500.0)
    p.add_argument("--session", default=os.path.join(ROOT, "build", "release", "bin", "microdrive-session"))
    p.add_argument("--out", default="/tmp/microdrive-campaign")
    p.add_argument("--doc", default=os.path.join(ROOT, "docs", "fault-campaign.md"))
    p.add_argument("--check-args", default="--auto-start", help="extra check_invariants.py arguments")
    a = p.parse_args(argv)
    a.check_args = a.check_args.split()
    scens = sorted(glob.glob(os.path.join(ROOT, "scenarios", "faults", "*.yaml")))
    if a.kinds:
        want = set(a.kinds.split(","))
        scens = [s for s in scens if os.path.basename(s)[:-5] in want]
    if not os.access(a.session, os.X_OK):
        print(f"campaign: {a.session} not found (build microdrive-session or pass --session)", file=sys.stderr)
        return 2
    rows = {}
    for scen in scens:
        kind = os.path.basename(scen)[:-5]
        rows[kind] = []
        for seed in range(1, a.seeds + 1):
            out = os.path.join(a.out, f"{kind}-{seed}")
            end, wall = run_session(a, scen, seed, out)
            s = check(a, out)
            log = os.path.join(out, "candump.log")
            if os.path.exists(log):
                os.remove(log)   # logs are large; the summary is kept
            rows[kind].append({"seed": seed, "end": end, "wall_s": round(wall, 1), "summary": s})
            v = s["violations_by_invariant"] if s else "no log"
            print(f"{kind} seed {seed}: {end} {wall:.0f}s {v}", flush=True)
    write_doc(a, rows, a.doc)
    with open(os.path.join(a.out, "campaign.json"), "w") as f:
        json.dump(rows, f, indent=1)
    bad = any(r["summary"] is None or not r["summary"]["ok"] for rs in rows.values() for r in rs)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
