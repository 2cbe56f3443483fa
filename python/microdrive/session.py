"""A microdrive session's outputs read into Python: the controller's telemetry from the frame log, and the
simulator's ground truth (truth.jsonl). Definitions of every field: docs/session.md and docs/protocol.md.

    from microdrive import session
    status, cycles, spikes, hyp = session.read_telemetry("out/candump.log")
    truth = session.read_truth("out/truth.jsonl")
"""
import json
from collections import defaultdict

from . import canlog

# TLM_SPIKES TrackNN: outlier or false cluster, no label (MD_TLM_TRACK_* of firmware/app/md_telemetry.h)
TRACK_OUTLIER, TRACK_UNLABELLED = -1, -2
TLM_NAMES = ("TLM_STATUS", "TLM_CYCLE", "TLM_SPIKES", "TLM_HYP")


def read_telemetry(path, db=None):
    """Telemetry of a frame log: TLM_STATUS per electrode in arrival order, TLM_CYCLE by (electrode, cycle)
    and phase, TLM_SPIKES parts by (electrode, cycle), ModelG of the rank-0 TLM_HYP by (electrode, cycle).
    db: the cantools database (default: the project's DBC)."""
    status = defaultdict(list)                 # e -> [status dict] in arrival order
    cycles = defaultdict(dict)                 # (e, cycle) -> {phase: dict}
    spikes = defaultdict(list)                 # (e, cycle) -> [(part, [(sample, track)])]
    hyp = {}                                   # (e, cycle) -> ModelG of rank 0
    for msg in canlog.messages(path, TLM_NAMES, db or canlog.load_dbc()):
        m = msg.signals
        e = int(m["Electrode"])
        if msg.name == "TLM_STATUS":
            status[e].append(m)
        elif msg.name == "TLM_CYCLE":
            cycles[(e, int(m["Cycle"]))][int(m["Phase"])] = m
        elif msg.name == "TLM_SPIKES":
            n = int(m["Count"])
            pairs = [(int(m[f"Sample{i:02d}"]), int(m[f"Track{i:02d}"])) for i in range(min(n, 11))]
            spikes[(e, int(m["Cycle"]))].append((int(m["Part"]), pairs))
        elif msg.name == "TLM_HYP" and int(m["Rank"]) == 0:
            hyp[(e, int(m["Cycle"]))] = int(m["ModelG"])
    return status, cycles, spikes, hyp


def read_truth(path):
    t = {"session": None, "neurons": defaultdict(dict), "spikes": defaultdict(list), "deaths": defaultdict(list),
         "states": {}, "intervals": defaultdict(list)}
    pending_state = {}
    with open(path) as f:
        lines = f.read().split("\n")
    for k, line in enumerate(lines):
        line = line.strip()
        if not line:
            continue
        try:
            r = json.loads(line)
        except json.JSONDecodeError:
            if k >= len(lines) - 2:   # the simulator was stopped in the middle of its last line
                t["truncated"] = True
                continue
            raise
        kind = r.get("type")
        if kind == "session":
            t["session"] = r
        elif kind == "neuron":
            t["neurons"][r["electrode"]][r["neuron"]] = r
        elif kind == "spike":
            t["spikes"][r["electrode"]].append((r["sample"], r["neuron"]))
        elif kind == "death":
            t["deaths"][r["electrode"]].append(r)
        elif kind == "state":
            pending_state[(r["label"], r["electrode"])] = r
        elif kind == "interval":
            e = r["electrode"]
            r["state"] = pending_state.get((f"rec e{e} i{r['interval']}", e))
            t["intervals"][e].append(r)
    for e in t["spikes"]:
        t["spikes"][e].sort()
    return t
