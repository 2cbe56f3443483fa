#!/usr/bin/env python3
"""Per-interval cost of a session's cycles, like for like: md-bench-m7 replays
the session's recording (every interval the controller recorded, in order,
through the same cycle stages) under QEMU -icount and its instruction counts
are put next to the CycleCost / ProcessCost the controller reported in
TLM_STATUS for the same interval (docs/pil.md).

    replay_cost.py SESSION_DIR [--image md-bench-m7.elf] [--qemu qemu-system-arm]
                   [--out DIR] [--json FILE] [--timeout S]

SESSION_DIR holds recording.json + recording.bin (one electrode: recording.json;
with several, pass --recording recording-e<k>.json) and candump.log. The plan
(the intervals, their depths, sample rate and gain) goes to DIR/plan.bin and
md-bench-m7's output to DIR/replay.txt (DIR: --out, else a temporary folder).

Checks first that the replay computed what the controller did: per interval
NumSpikes, DominantTrack, NumTracks, NumHypotheses and Snr (float32, to the
bit) of TLM_STATUS against the replay's. Then per interval: replay cycle
(push + end + pca + mhtc + quality + control) vs CycleCost, replay processing
(end .. control) vs ProcessCost, replay push vs CycleCost - ProcessCost (the
detection the controller measures per REC_DATA frame); their ratios' median,
range and how many intervals lie within 10 %.

Exit status: 0 compared (whatever the figures), 1 the replay and the session
disagree about what an interval held, or a tool failed; 2 usage.
"""
import argparse
import json
import os
import struct
import subprocess
import sys
import tempfile

from microdrive import canlog

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
STAGES = ("push", "end", "pca", "mhtc", "quality", "control")
PLAN_MAGIC = b"MDRP"
PLAN_VERSION = 1


def write_plan(rec_json, path):
    """plan.bin for md-bench-m7 --replay (tools/bench/bench_m7.c); returns (samples file, intervals)."""
    with open(rec_json) as f:
        rec = json.load(f)
    if rec.get("num_channels") != 1 or rec.get("dtype") != "int16":
        raise ValueError(f"{rec_json}: the replay takes one int16 channel (a session's recording)")
    fs = rec["sampling_frequency"]
    if fs != int(fs):
        raise ValueError(f"{rec_json}: sampling_frequency {fs}: whole Hz only (the controller's FE_INFO)")
    ivs = rec.get("intervals") or []
    if not ivs:
        raise ValueError(f"{rec_json}: no intervals list")
    samples = rec.get("file", "recording.bin")
    if not os.path.isabs(samples):
        samples = os.path.join(os.path.dirname(os.path.abspath(rec_json)), samples)
    with open(path, "wb") as f:
        f.write(PLAN_MAGIC + struct.pack("<IIId", PLAN_VERSION, int(fs), len(ivs), float(rec.get("gain_uV", 1.0))))
        for iv in ivs:
            depth = iv.get("depth_um")
            depth = float("nan") if depth is None else float(depth)
            f.write(struct.pack("<QIIdII", int(iv["start_sample"]), int(iv["num_samples"]),
                                int(iv.get("interval_id", 0)), depth, int(iv.get("cycle", 0)),
                                1 if iv.get("complete", True) else 0))
    return samples, ivs


def run_replay(qemu, image, plan, samples, out_txt, timeout):
    cmd = [qemu, "-M", "mps2-an500", "-nographic", "-monitor", "none", "-serial", "null", "-icount", "shift=0",
           "-semihosting-config",
           "enable=on,target=native,arg=md-bench-m7,arg=--replay,arg=" + plan.replace(",", ",,") +
           ",arg=" + samples.replace(",", ",,"),
           "-kernel", image]
    with open(out_txt, "w") as f:
        rc = subprocess.run(cmd, stdin=subprocess.DEVNULL, stdout=f, stderr=subprocess.STDOUT,
                            timeout=timeout).returncode
    with open(out_txt) as f:
        text = f.read()
    if rc != 0:
        raise RuntimeError(f"md-bench-m7 --replay exited {rc}:\n{text[-2000:]}")
    return text


def parse_replay(text):
    cal, rows = None, {}
    for line in text.splitlines():
        w = line.split()
        if w[:1] == ["cal"] and len(w) == 3:
            cal = (int(w[1]), int(w[2]))
        elif w[:1] == ["interval"] and len(w) > 6 and w[6] != "incomplete":
            kv = dict(zip(w[0::2], w[1::2]))
            rows[int(kv["cycle"])] = {
                "interval": int(kv["interval"]), "id": int(kv["id"]), "samples": int(kv["samples"]),
                "spikes": int(kv["spikes"]), "dominant": int(kv["dominant"]), "tracks": int(kv["tracks"]),
                "hyp": int(kv["hyp"]), "models": int(kv["models"]), "snr_bits": int(kv["snr_bits"], 16),
                "stages": {s: int(kv[s]) for s in STAGES}, "status": kv["status"]}
    return cal, rows


def read_status(candump, electrode):
    """TLM_STATUS of one electrode by cycle: the fields the check compares and the two costs."""
    out = {}
    for msg in canlog.messages(candump, ["TLM_STATUS"]):
        m = msg.signals
        if int(m["Electrode"]) != electrode:
            continue
        snr_bits, = struct.unpack("<I", struct.pack("<f", m["Snr"]))  # compared bit for bit
        out[int(m["Cycle"])] = {"spikes": int(m["NumSpikes"]), "dominant": int(m["DominantTrack"]),
                                "tracks": int(m["NumTracks"]), "hyp": int(m["NumHypotheses"]), "snr_bits": snr_bits,
                                "flags": int(m["Flags"]), "cycle_cost": int(m["CycleCost"]),
                                "process_cost": int(m["ProcessCost"])}
    return out


def median(v):
    v = sorted(v)
    n = len(v)
    return None if n == 0 else (v[n // 2] if n % 2 else (v[n // 2 - 1] + v[n // 2]) / 2)


def ratio_summary(pairs):
    """pairs: (replay, session); ratio session / replay."""
    r = [b / a for a, b in pairs if a > 0]
    return {"n": len(r), "median": median(r), "min": min(r) if r else None, "max": max(r) if r else None,
            "within_10pct": sum(1 for x in r if abs(x - 1.0) <= 0.10)}


def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("session")
    ap.add_argument("--recording", default="recording.json", help="sidecar in SESSION_DIR (default recording.json)")
    ap.add_argument("--image", default=os.environ.get("MD_BENCH_M7_IMAGE",
                                                      os.path.join(ROOT, "build", "cortex-m7", "bin", "md-bench-m7.elf")))
    ap.add_argument("--qemu", default=os.environ.get("MD_QEMU", "qemu-system-arm"))
    ap.add_argument("--out", help="folder for plan.bin and replay.txt (default: a temporary one)")
    ap.add_argument("--json", help="write the per-interval table and the summary here")
    ap.add_argument("--timeout", type=float, default=3600.0)
    ap.add_argument("--quiet", action="store_true", help="no per-interval lines")
    return ap.parse_args(argv)


def compare(ivs, rep, status):
    """Per interval processed by both (the replay and the session): the replay's stage counts next to the
    session's CycleCost and ProcessCost; and the cycles whose facts differ."""
    rows, mismatch = [], []
    for iv in ivs:
        c = int(iv.get("cycle", -1))
        r, s = rep.get(c), status.get(c)
        if r is None or s is None or s["flags"] & 0x3 or r["status"] != "OK":
            continue                                      # not processed by one of the two
        same = all(r[k] == s[k] for k in ("spikes", "dominant", "tracks", "hyp", "snr_bits"))
        if not same:
            mismatch.append(c)
        st = r["stages"]
        cycle = sum(st.values())
        process = cycle - st["push"]
        rows.append({"cycle": c, "interval_id": r["id"], "same_facts": same, "spikes": s["spikes"],
                     "hyp": s["hyp"], "models": r["models"], "replay": st, "replay_cycle": cycle,
                     "replay_process": process, "session_cycle": s["cycle_cost"],
                     "session_process": s["process_cost"],
                     "session_detect": s["cycle_cost"] - s["process_cost"]})
    return rows, mismatch


def print_rows(rows):
    """One line per interval: the replay's stages, the session's costs, their ratios."""
    print("cycle  id  spikes hyp | replay: push      end      pca       mhtc  quality control    cycle | "
          "session: cycle   process | ratio cycle process detect")
    for x in rows:
        st = x["replay"]
        print(f"{x['cycle']:5d} {x['interval_id']:3d} {x['spikes']:6d} {x['hyp']:3d} | "
              f"{st['push']:11d} {st['end']:8d} {st['pca']:8d} {st['mhtc']:10d} {st['quality']:8d} "
              f"{st['control']:7d} {x['replay_cycle']:10d} | {x['session_cycle']:10d} {x['session_process']:10d} | "
              f"{x['session_cycle'] / x['replay_cycle']:.4f} {x['session_process'] / x['replay_process']:.4f} "
              f"{x['session_detect'] / st['push']:.4f}{'' if x['same_facts'] else '  FACTS DIFFER'}")


def summarise(rows, cal, mismatch):
    """Medians, extremes and ratios of the two counts over the intervals."""
    return {
        "calibration": cal,
        "intervals": len(rows),
        "facts_differ": mismatch,
        "replay_cycle": {"median": median([x["replay_cycle"] for x in rows]), "max": max(x["replay_cycle"] for x in rows)},
        "replay_process": {"median": median([x["replay_process"] for x in rows]),
                           "max": max(x["replay_process"] for x in rows)},
        "replay_push": {"median": median([x["replay"]["push"] for x in rows])},
        "session_cycle": {"median": median([x["session_cycle"] for x in rows]), "max": max(x["session_cycle"] for x in rows)},
        "session_process": {"median": median([x["session_process"] for x in rows]),
                            "max": max(x["session_process"] for x in rows)},
        "session_detect": {"median": median([x["session_detect"] for x in rows])},
        "ratio_cycle": ratio_summary([(x["replay_cycle"], x["session_cycle"]) for x in rows]),
        "ratio_process": ratio_summary([(x["replay_process"], x["session_process"]) for x in rows]),
        "ratio_detect": ratio_summary([(x["replay"]["push"], x["session_detect"]) for x in rows]),
        "diff_cycle": {"median": median([x["session_cycle"] - x["replay_cycle"] for x in rows])},
        "diff_process": {"median": median([x["session_process"] - x["replay_process"] for x in rows]),
                         "min": min(x["session_process"] - x["replay_process"] for x in rows),
                         "max": max(x["session_process"] - x["replay_process"] for x in rows)},
        "diff_detect": {"median": median([x["session_detect"] - x["replay"]["push"] for x in rows]),
                        "min": min(x["session_detect"] - x["replay"]["push"] for x in rows),
                        "max": max(x["session_detect"] - x["replay"]["push"] for x in rows)},
    }


def print_summary(summary, rows, cal, mismatch):
    """The verdict on the facts, then the medians and ratios."""
    m = lambda v: "-" if v is None else f"{v / 1e6:.2f} M"  # noqa: E731
    print(f"replay_cost: {len(rows)} intervals processed by both; calibration {cal}; "
          f"facts (spikes, dominant, tracks, hypotheses, SNR bits) "
          f"{'identical in every interval' if not mismatch else 'DIFFER in cycles ' + str(mismatch[:10])}")
    print(f"replay_cost: cycle   replay median {m(summary['replay_cycle']['median'])} max {m(summary['replay_cycle']['max'])}"
          f" | session median {m(summary['session_cycle']['median'])} max {m(summary['session_cycle']['max'])}")
    print(f"replay_cost: process replay median {m(summary['replay_process']['median'])} "
          f"max {m(summary['replay_process']['max'])} | session median {m(summary['session_process']['median'])} "
          f"max {m(summary['session_process']['max'])}")
    for k in ("cycle", "process", "detect"):
        r = summary[f"ratio_{k}"]
        print(f"replay_cost: session/replay {k:7s}: median {r['median']:.4f}, range {r['min']:.4f}..{r['max']:.4f}, "
              f"{r['within_10pct']} of {r['n']} within 10 %")
    print(f"replay_cost: session - replay: process median {summary['diff_process']['median']:.0f} "
          f"(range {summary['diff_process']['min']}..{summary['diff_process']['max']}), detection median "
          f"{summary['diff_detect']['median']:.0f} (range {summary['diff_detect']['min']}..{summary['diff_detect']['max']}) "
          f"instructions")


def main(argv=None):
    args = parse_args(argv)
    rec_json = os.path.join(args.session, args.recording)
    try:
        with open(rec_json) as f:
            electrode = int(json.load(f).get("electrode", 0))
    except (OSError, ValueError) as exc:
        print(f"replay_cost: {rec_json}: {exc}", file=sys.stderr)
        return 2
    tmp = None
    out = args.out
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="replay-cost-")
        out = tmp.name
    os.makedirs(out, exist_ok=True)
    try:
        plan = os.path.join(out, "plan.bin")
        samples, ivs = write_plan(rec_json, plan)
        text = run_replay(args.qemu, args.image, os.path.abspath(plan), os.path.abspath(samples),
                          os.path.join(out, "replay.txt"), args.timeout)
    except (OSError, ValueError, RuntimeError, subprocess.TimeoutExpired) as exc:
        print(f"replay_cost: {exc}", file=sys.stderr)
        return 1
    cal, rep = parse_replay(text)
    status = read_status(os.path.join(args.session, "candump.log"), electrode)

    rows, mismatch = compare(ivs, rep, status)
    if not rows:
        print("replay_cost: no interval processed by both the replay and the session", file=sys.stderr)
        return 1
    if not args.quiet:
        print_rows(rows)
    summary = summarise(rows, cal, mismatch)
    print_summary(summary, rows, cal, mismatch)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"summary": summary, "intervals": rows}, f, indent=1)
            f.write("\n")
    return 1 if mismatch else 0


if __name__ == "__main__":
    sys.exit(main())
