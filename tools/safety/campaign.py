#!/usr/bin/env python3
"""Fault campaign: every fault scenario x seeds through microdrive-session,
each frame log checked by check_invariants.py; counts to docs/fault-campaign.md.

usage: campaign.py [--seeds N] [--first-seed S] [--bus inproc] [--kinds a,b] [--cycles N]
                   [--timeout-s S] [--max-log-mb M] [--session PATH] [--out DIR]
                   [--doc PATH | --no-doc] [--jobs J] [--check-args "..."]

Every run: `microdrive-session --scenario scenarios/faults/<kind>.yaml --seed S --bus B
--cycles N --no-recording --no-score --no-lcm --no-plots --quiet`, then
`check_invariants.py candump.log --truth truth.jsonl` (the true tip must stay in the window
too). The fault counters the session prints (bus faults injected per kind, frames and
heartbeats a silent node did not send, controller restarts; model faults by their effect)
are summed per kind so the table shows that every fault really happened.

A run that does not end within --timeout-s (wall) or whose log passes --max-log-mb is
stopped and counted as `no_end`; its partial log is still checked (an invariant violated
in a prefix is violated). Exit status 1 if any run violated an invariant or left no log.
"""
import argparse
import concurrent.futures
import glob
import json
import os
import re
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
CHECK = os.path.join(HERE, "check_invariants.py")
FINDINGS = os.path.join(HERE, "campaign_findings.md")   # hand-written analysis, appended to the doc
INVARIANTS = ["window", "step_cmd", "step_meas", "step_true", "rec_motion", "unasked", "hb_lost", "estop", "restart",
              "neuron_damaged"]

# fault counters printed by microdrive-session at the end of an in-process run
RE_BUS = re.compile(r"bus fault \d+: frames seen (\d+), loss (\d+), corrupt (\d+), dup (\d+), "
                    r"delay (\d+), reorder (\d+), hold full (\d+)")
RE_SILENT = re.compile(r"node silence: frames swallowed act (\d+), hall (\d+), fe (\d+); heartbeats not sent (\d+)")
RE_RESTART = re.compile(r"controller restarts: (\d+) of (\d+)")
RE_MODEL = re.compile(r"model faults: hall glitches (\d+), hall stuck reads (\d+), actuator stalls (\d+), "
                      r"actuator slips (\d+), storm events (\d+), saturated samples (\d+)")


def injected(stderr):
    """{counter: value} from the session's fault lines."""
    c = {}
    for m in RE_BUS.finditer(stderr):
        for name, v in zip(("loss", "corrupt", "dup", "delay", "reorder"), m.groups()[1:6]):
            c[name] = c.get(name, 0) + int(v)
    for m in RE_SILENT.finditer(stderr):
        c["silenced frames"] = sum(int(v) for v in m.groups()[:3])
        c["silenced heartbeats"] = int(m.group(4))
    for m in RE_RESTART.finditer(stderr):
        c["restarts"] = int(m.group(1))
    for m in RE_MODEL.finditer(stderr):
        for name, v in zip(("hall glitches", "hall stuck reads", "actuator stalls", "actuator slips",
                            "storm events", "saturated samples"), m.groups()):
            c[name] = int(v)
    return c


def run_session(a, scen, seed, out):
    os.makedirs(out, exist_ok=True)
    cmd = [a.session, "--scenario", scen, "--seed", str(seed), "--bus", a.bus, "--out", out,
           "--cycles", str(a.cycles), "--quiet", "--no-score", "--no-recording", "--no-lcm", "--no-plots"]
    errf = open(os.path.join(out, "session.err"), "w+")
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=errf, start_new_session=True)
    t0, log = time.time(), os.path.join(out, "candump.log")
    end = None
    while p.poll() is None:
        time.sleep(0.1)
        big = os.path.exists(log) and os.path.getsize(log) > a.max_log_mb * 1e6
        if time.time() - t0 > a.timeout_s or big:
            os.killpg(p.pid, signal.SIGTERM)
            p.wait()
            end = "no_end"
    if end is None:
        end = "ok" if p.returncode in (0, 4) else f"rc{p.returncode}"
    errf.seek(0)
    stderr = errf.read()
    errf.close()
    return end, time.time() - t0, stderr


def check(a, out):
    log = os.path.join(out, "candump.log")
    if not os.path.exists(log):
        return None
    cmd = [sys.executable, CHECK, log, "--json", os.path.join(out, "invariants.json")] + a.check_args
    truth = os.path.join(out, "truth.jsonl")
    if os.path.exists(truth):
        cmd += ["--truth", truth]
    p = subprocess.run(cmd, capture_output=True, text=True)
    try:
        return json.loads(p.stdout)
    except ValueError:
        return None


def one_run(a, scen, kind, seed):
    out = os.path.join(a.out, f"{kind}-{seed}")
    end, wall, stderr = run_session(a, scen, seed, out)
    s = check(a, out)
    log = os.path.join(out, "candump.log")
    if os.path.exists(log) and not a.keep_logs and (s is not None and s["ok"]):
        os.remove(log)   # logs are large; the summary is kept (failing runs keep theirs)
    m = re.search(r"simulated time ([0-9.]+) s", stderr)
    return {"seed": seed, "end": end, "wall_s": round(wall, 1), "summary": s, "injected": injected(stderr),
            "sim_s": float(m.group(1)) if m else None, "out": out}


def build_line(session):
    """Which code made the figures: the session binary's hash (the controller and the simulator are linked
    into it)."""
    import hashlib
    with open(session, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()[:16]
    return f"Build: `{os.path.relpath(session, ROOT)}` sha256 {digest}."


def write_doc(a, rows, path):
    cmd = (f".venv/bin/python tools/safety/campaign.py --seeds {a.seeds} --bus {a.bus} --cycles {a.cycles}"
           + (f" --first-seed {a.first_seed}" if a.first_seed != 1 else ""))
    lines = ["# Fault campaign", "",
             f"Regenerate: `nice -n 10 {cmd}` after building `microdrive-session` "
             "(fault scenarios in scenarios/faults/, invariants and the fault hooks in docs/safety.md). "
             "The script overwrites this file.", "", build_line(a.session), "",
             f"Each run: one fault scenario, one seed ({a.first_seed}..{a.first_seed + a.seeds - 1}), "
             f"`--bus {a.bus} --cycles {a.cycles}`; its frame log and truth checked by "
             "tools/safety/check_invariants.py " + " ".join(a.check_args + ["--truth truth.jsonl"]) + ".", "",
             "| fault | runs | ended | passed | " + " | ".join(INVARIANTS) + " | sim s (min) | injected (sum over runs) |",
             "|---|---|---|---|" + "---|" * len(INVARIANTS) + "---|---|"]
    tot_runs = tot_pass = 0
    for kind, rs in rows.items():
        ended = sum(1 for r in rs if r["end"] == "ok")
        passed = sum(1 for r in rs if r["summary"] and r["summary"]["ok"])
        tot_runs, tot_pass = tot_runs + len(rs), tot_pass + passed
        per = [sum(1 for r in rs if r["summary"] and r["summary"]["violations_by_invariant"].get(i, 0) > 0)
               for i in INVARIANTS]
        inj = {}
        for r in rs:
            for k, v in r["injected"].items():
                inj[k] = inj.get(k, 0) + v
        inj_s = ", ".join(f"{k} {v}" for k, v in inj.items() if v) or "none"
        sims = [r["sim_s"] for r in rs if r["sim_s"] is not None]
        sim_min = f"{min(sims):.0f}" if sims else "?"
        lines.append(f"| {kind} | {len(rs)} | {ended} | {passed} | " + " | ".join(map(str, per))
                     + f" | {sim_min} | {inj_s} |")
    lines += ["", f"**{tot_pass} of {tot_runs} runs passed every invariant.**", "",
              "Invariant columns count runs with at least one violation of that invariant. "
              "`ended`: the session reached its goal or went idle before the timeout. "
              "`sim s (min)`: the shortest simulated time among the runs (the fault windows must fall "
              "inside it). `injected`: the fault counters microdrive-session prints at the end (bus "
              "faults per kind, frames and heartbeats of silent nodes, restarts, and the model faults "
              "that acted: Hall glitches / stuck reads, actuator stalls / slips, storm transients, "
              "saturated samples).", ""]
    bad = [(kind, r) for kind, rs in rows.items() for r in rs if not (r["summary"] and r["summary"]["ok"])]
    if bad:
        lines += ["## Violations (first three per run)", ""]
        for kind, r in bad:
            if r["summary"] is None:
                lines.append(f"- {kind} seed {r['seed']}: no log / checker failed")
                continue
            for v in r["summary"]["violations"][:3]:
                lines.append(f"- {kind} seed {r['seed']}: `{v['invariant']}` at {v['t']} s: {v['what']}")
        lines.append("")
    if os.path.exists(FINDINGS):
        with open(FINDINGS) as f:
            lines += [f.read()]
    with open(path, "w") as f:
        f.write("\n".join(lines))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--first-seed", type=int, default=1)
    p.add_argument("--bus", default="inproc")
    p.add_argument("--kinds", default="", help="comma-separated subset of scenarios/faults/*.yaml names")
    p.add_argument("--cycles", type=int, default=12, help="long enough to pass every fault window (90 s)")
    p.add_argument("--timeout-s", type=float, default=300.0)
    p.add_argument("--max-log-mb", type=float, default=500.0)
    p.add_argument("--session", default=os.path.join(ROOT, "build", "release", "bin", "microdrive-session"))
    p.add_argument("--out", default="/tmp/microdrive-campaign")
    p.add_argument("--doc", default=os.path.join(ROOT, "docs", "fault-campaign.md"))
    p.add_argument("--no-doc", action="store_true", help="do not write the doc (CI)")
    p.add_argument("--jobs", type=int, default=1, help="runs in parallel")
    p.add_argument("--keep-logs", action="store_true")
    p.add_argument("--doc-from", help="only rewrite the doc from a campaign.json of an earlier run "
                   "(with the same --seeds/--cycles/--first-seed)")
    p.add_argument("--check-args", default="", help="extra check_invariants.py arguments (the in-process launcher "
                   "starts the controller with a logged NMT start, so --auto-start is not needed)")
    a = p.parse_args(argv)
    a.check_args = a.check_args.split()
    if a.doc_from:
        with open(a.doc_from) as f:
            write_doc(a, json.load(f), a.doc)
        return 0
    scens = sorted(glob.glob(os.path.join(ROOT, "scenarios", "faults", "*.yaml")))
    if a.kinds:
        want = set(a.kinds.split(","))
        scens = [s for s in scens if os.path.basename(s)[:-5] in want]
    if not os.access(a.session, os.X_OK):
        print(f"campaign: {a.session} not found (build microdrive-session or pass --session)", file=sys.stderr)
        return 2
    jobs = [(scen, os.path.basename(scen)[:-5], seed) for scen in scens
            for seed in range(a.first_seed, a.first_seed + a.seeds)]
    rows = {os.path.basename(s)[:-5]: [] for s in scens}
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        futs = {ex.submit(one_run, a, scen, kind, seed): kind for scen, kind, seed in jobs}
        for fu in concurrent.futures.as_completed(futs):
            kind, r = futs[fu], fu.result()
            rows[kind].append(r)
            v = r["summary"]["violations_by_invariant"] if r["summary"] else "no log"
            ok = "PASS" if r["summary"] and r["summary"]["ok"] else "FAIL"
            print(f"{kind} seed {r['seed']}: {ok} {r['end']} {r['wall_s']:.0f}s sim {r['sim_s']} "
                  f"injected {r['injected']} {v}", flush=True)
    for rs in rows.values():
        rs.sort(key=lambda r: r["seed"])
    if not a.no_doc:
        write_doc(a, rows, a.doc)
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "campaign.json"), "w") as f:
        json.dump(rows, f, indent=1)
    bad = any(r["summary"] is None or not r["summary"]["ok"] for rs in rows.values() for r in rs)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
