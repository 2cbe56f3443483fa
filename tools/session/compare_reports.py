#!/usr/bin/env python3
"""Compares session reports apart from "bus": exit 0 same, 1 different,
77 when none of them holds a single cycle (the controller has no cycle yet,
so there is nothing to compare: a skip, not a pass).

    compare_reports.py REPORT_A REPORT_B [...]
"""
import json
import sys


def load(path):
    with open(path) as f:
        r = json.load(f)
    r.pop("bus", None)
    return r


def main(paths):
    reports = [load(p) for p in paths]
    if all(sum(e["cycles"] for e in r["electrodes"]) == 0 for r in reports):
        print("compare_reports: no electrode completed a cycle in any session: nothing to compare (skip)")
        return 77
    same = True
    for p, r in zip(paths[1:], reports[1:]):
        if r != reports[0]:
            same = False
            print(f"compare_reports: {p} differs from {paths[0]}:")
            a, b = json.dumps(reports[0], indent=1).splitlines(), json.dumps(r, indent=1).splitlines()
            for x, y in zip(a, b):
                if x != y:
                    print(f"  {x.strip()}  <->  {y.strip()}")
    cycles = [e["cycles"] for e in reports[0]["electrodes"]]
    print(f"compare_reports: {len(paths)} reports {'identical' if same else 'DIFFERENT'} apart from bus "
          f"(cycles per electrode {cycles})")
    return 0 if same else 1


if __name__ == "__main__":
    if len(sys.argv) < 3:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1:]))
