#!/usr/bin/env python3
"""The evaluation suite's headline numbers have not regressed (label integration).

    test_eval_regression.py --build-dir DIR --work DIR

Runs tools/eval/regression.py check: the CI subset of tools/eval/run_suite.py (single_neuron, drifting_pair,
empty_tissue; MHTC and MAP-NN; 6 seeds; 300 simulated seconds each) on this build, every figure against its
bound in tools/eval/thresholds.json (measured on the code of the committed docs/evaluation.md, bounds a little
worse). Fails on any figure past its bound, a failed session, or a missing figure.
"""
import argparse
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REGRESSION = os.path.join(HERE, "..", "..", "tools", "eval", "regression.py")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build-dir", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    return subprocess.run([sys.executable, REGRESSION, "check", "--build-dir", a.build_dir, "--work", a.work]).returncode


if __name__ == "__main__":
    sys.exit(main())
