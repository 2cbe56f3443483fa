#!/usr/bin/env python3
"""Worst-case stack depth of a function from GCC's -fcallgraph-info=su output.

usage: stack_depth.py ROOT_FUNCTION FILE.ci...
Reads the VCG graphs (node titles carry "file:line:col:name" and labels carry
"N bytes (static|dynamic...)"), follows call edges and prints the deepest path.
No recursion may exist (the firmware forbids it); a cycle is reported as an error.
Calls to functions without a .ci entry (libm, libc) count 0 bytes and are listed.
"""
import re
import sys


def parse(files):
    frames, edges = {}, {}
    node_re = re.compile(r'node:\s*\{\s*title:\s*"([^"]+)"\s*label:\s*"([^"]*)"')
    edge_re = re.compile(r'edge:\s*\{\s*sourcename:\s*"([^"]+)"\s*targetname:\s*"([^"]+)"')
    for fn in files:
        text = open(fn).read()
        for title, label in node_re.findall(text):
            name = title.split(":")[-1]
            m = re.search(r"(\d+) bytes \((\w+)", label.replace("\\n", " "))
            if m:
                frames[name] = (int(m.group(1)), m.group(2))
            else:
                frames.setdefault(name, None)
        for src, dst in edge_re.findall(text):
            edges.setdefault(src.split(":")[-1], set()).add(dst.split(":")[-1])
    return frames, edges


def deepest(root, frames, edges):
    best, state = {}, {}
    order = [(root, False)]
    while order:  # iterative post-order DFS (no recursion)
        fn, done = order.pop()
        if done:
            f = frames.get(fn)
            own = f[0] if f else 0
            kids = [(best[c][0], c) for c in edges.get(fn, ())]
            sub, child = max(kids) if kids else (0, None)
            best[fn] = (own + sub, child)
            state[fn] = 2
            continue
        if state.get(fn) == 2:
            continue
        if state.get(fn) == 1:
            raise SystemExit(f"cycle through {fn}")
        state[fn] = 1
        order.append((fn, True))
        for c in edges.get(fn, ()):
            if state.get(c) != 2:
                order.append((c, False))
    return best


def main():
    root, files = sys.argv[1], sys.argv[2:]
    frames, edges = parse(files)
    best = deepest(root, frames, edges)
    print(f"worst-case stack of {root}: {best[root][0]} bytes")
    fn = root
    while fn is not None:
        f = frames.get(fn)
        print(f"  {fn}: {f[0] if f else 0} B ({f[1] if f else 'external'})")
        fn = best[fn][1]
    return 0


if __name__ == "__main__":
    sys.exit(main())
