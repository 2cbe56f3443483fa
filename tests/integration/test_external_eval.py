#!/usr/bin/env python3
"""The external evaluation's CI subset has not regressed (label integration).

    test_external_eval.py --replay MHTC_REPLAY --work DIR

Runs tools/external_eval/external_eval.py check: one 60 s static recording made by SpikeInterface's
generate_ground_truth_recording (the first seed from 3000 up with 2..5 visible units at least 10 noise
levels apart on the chosen channel), mhtc-replay's MHTC (final-lineage and online labels) and the
whole-session oracle, scored against the ground truth; every figure against its bound in
tools/external_eval/thresholds.json (measured with `external_eval.py measure`, bounds a little worse).
Fails on a figure past its bound, a missing figure (e.g. the generator made another recording) or a
failed run. About 20 s on 2 cores.
"""
import argparse
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
TOOL = os.path.join(HERE, "..", "..", "tools", "external_eval", "external_eval.py")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--replay", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    return subprocess.run([sys.executable, TOOL, "check", "--replay", a.replay, "--work", a.work]).returncode


if __name__ == "__main__":
    sys.exit(main())
