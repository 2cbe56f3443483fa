#!/usr/bin/env python3
"""Worst-case stack depth of the clustering entry points from GCC's
-fcallgraph-info=su output (docs/clustering.md).

usage: stack_usage.py <dir with .ci files> [entry ...]
Prints each entry's own frame and its deepest call chain through functions
whose frames are known (calls into libm/libc are listed as unknown leaves).
The clustering code has no recursion, so the call graph is a DAG."""
import re
import sys
from pathlib import Path

NODE = re.compile(r'node: \{ title: "([^"]+)" label: "([^"]*)"')
EDGE = re.compile(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')
BYTES = re.compile(r'(\d+) bytes \((static|dynamic[^)]*)\)')


def load(ci_dir):
    frames, calls = {}, {}
    for ci in Path(ci_dir).glob("*.ci"):
        text = ci.read_text()
        for title, label in NODE.findall(text):
            m = BYTES.search(label.replace("\\n", "\n"))
            if m:
                frames[title] = int(m.group(1))
                if m.group(2) != "static":
                    print(f"warning: {title} has a {m.group(2)} frame", file=sys.stderr)
        for src, dst in EDGE.findall(text):
            calls.setdefault(src, set()).add(dst)
    return frames, calls


def deepest(fn, frames, calls, memo, unknown):
    if fn in memo:
        return memo[fn]
    own = frames.get(fn)
    if own is None:
        unknown.add(fn)
        memo[fn] = (0, [fn + "?"])
        return memo[fn]
    best = (0, [])
    for callee in sorted(calls.get(fn, ())):
        best = max(best, deepest(callee, frames, calls, memo, unknown), key=lambda t: t[0])
    memo[fn] = (own + best[0], [f"{fn}({own})"] + best[1])
    return memo[fn]


def main():
    if len(sys.argv) < 2:
        print(__doc__)
        return 2
    frames, calls = load(sys.argv[1])
    entries = sys.argv[2:] or ["cluster_fit_models"]
    memo, unknown = {}, set()
    for e in entries:
        depth, chain = deepest(e, frames, calls, memo, unknown)
        print(f"{e}: own frame {frames.get(e, '?')} B, worst-case chain {depth} B")
        print("  " + " -> ".join(chain))
    print("largest frames:")
    for fn, b in sorted(frames.items(), key=lambda t: -t[1])[:8]:
        print(f"  {b:6d} B  {fn}")
    print("calls outside the measured code (frames not counted): " + ", ".join(sorted(unknown)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
