#!/usr/bin/env python3
"""Worst-case stack, recursion and static RAM of a Cortex-M firmware image.

    scripts/stack-budget.py [--budgets tools/analysis/budgets.txt] <image.elf> [more.elf ...]
    scripts/stack-budget.py --cycles-only FILE.ci...      (recursion check only)
    scripts/stack-budget.py --root FUNCTION FILE.ci|DIR...  (one function's worst case)

Needs the image's objects compiled with -fcallgraph-info=su (GCC writes a
<object-stem>.ci next to every object; tests/analysis/CMakeLists.txt adds the
flag in the cortex-m7 build) and its linker map <image.elf>.map (every
Cortex-M7 link writes one). The map names the objects and archives linked;
their .ci files give every function's frame size and its direct calls.

For each image named in the budget file:
  * recursion: any cycle in the call graph fails (MISRA C:2012 17.2);
  * stack: worst path from the thread root (Reset_Handler) plus, on top of it,
    every interrupt/fault root once (each with the hardware exception frame):
    the conservative "every handler nested once" bound, held under the budget;
  * indirect calls: every call through a function pointer must have declared
    targets ("indirect <caller> <target>..."), calls hidden in assembly are
    declared as "edge <from> <to>", and every called function without a .ci
    (libc, libm, libgcc) needs a declared bound ("extern <name> <bytes>"),
    which is checked against the image's disassembly (prologue push/vpush/sub
    sp plus the deepest bl chain);
  * static RAM: .data + .bss of the ELF (arm-none-eabi-size), held under budget.
With --root, no image and no budget: the worst-case stack of FUNCTION (the
deepest call chain through the .ci files named, or every .ci below a folder
named), with the chain; calls to functions without a .ci (libc, libm) and
calls through function pointers count 0 bytes and are listed.
Exit status 0 within every budget, 1 over a budget or rule broken, 2 usage error.
"""
import argparse
import fnmatch
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_BUDGETS = os.path.join(ROOT, "tools", "analysis", "budgets.txt")

NODE_RE = re.compile(r'node:\s*\{\s*title:\s*"([^"]+)"\s*label:\s*"([^"]*)"')
EDGE_RE = re.compile(r'edge:\s*\{\s*sourcename:\s*"([^"]+)"\s*targetname:\s*"([^"]+)"(?:\s*label:\s*"([^"]*)")?')
FRAME_RE = re.compile(r"(\d+) bytes \(([\w,]+)\)")
INDIRECT = "__indirect_call"


def short(title):
    """'path/file.c:name' (static function) or 'name' -> 'name'."""
    return title.rsplit(":", 1)[-1]


class CallGraph:
    """Functions (by .ci title) with frame sizes and call edges."""

    def __init__(self):
        self.frame = {}      # title -> (bytes, qualifier) for defined functions
        self.where = {}      # title -> "file:line"
        self.edges = {}      # title -> {callee title: call site}
        self.titles = {}     # short name -> set of titles

    def read_ci(self, path):
        text = open(path, errors="replace").read()
        for title, label in NODE_RE.findall(text):
            self.titles.setdefault(short(title), set()).add(title)
            parts = label.split("\\n")
            m = FRAME_RE.search(label.replace("\\n", " "))
            if m:
                self.frame[title] = (int(m.group(1)), m.group(2))
                if len(parts) > 1:
                    self.where[title] = parts[1]
        for src, dst, site in EDGE_RE.findall(text):
            self.titles.setdefault(short(dst), set()).add(dst)
            self.edges.setdefault(src, {}).setdefault(dst, site)

    def resolve(self, name):
        """A declared name -> the defined title ('name' or 'file:name')."""
        if name in self.frame:
            return name
        cands = [t for t in self.titles.get(short(name), ()) if t in self.frame and t.endswith(name)]
        if len(cands) == 1:
            return cands[0]
        return name

    def callees(self, title):
        return self.edges.get(title, {})

    def cycles(self):
        """Every elementary cycle found by an iterative DFS (one per back edge)."""
        colour, found = {}, []
        for start in sorted(set(self.frame) | set(self.edges)):
            if colour.get(start):
                continue
            stack = [(start, iter(sorted(self.callees(start))))]
            path = [start]
            colour[start] = 1
            while stack:
                node, it = stack[-1]
                nxt = next(it, None)
                if nxt is None:
                    colour[node] = 2
                    stack.pop()
                    path.pop()
                    continue
                nxt = self.resolve(nxt) if nxt not in self.frame else nxt
                if nxt == INDIRECT:
                    continue
                if colour.get(nxt) == 1:
                    found.append([short(t) for t in path[path.index(nxt):]] + [short(nxt)])
                elif not colour.get(nxt):
                    colour[nxt] = 1
                    path.append(nxt)
                    stack.append((nxt, iter(sorted(self.callees(nxt)))))
        return found


class Budgets:
    def __init__(self, path):
        self.path = path
        self.images = {}      # image -> {"stack": n, "ram": n, "roots": [...], "isr": [...]}
        self.indirect = {}    # caller -> [targets]
        self.edge = {}        # from -> [to]
        self.extern = {}      # name -> bytes
        self.exception_frame = 0
        for n, raw in enumerate(open(path) if path else (), 1):
            line = raw.split("#", 1)[0].split()
            if not line:
                continue
            kw, args = line[0], line[1:]
            try:
                if kw in ("stack", "ram"):
                    self.images.setdefault(args[0], {"roots": [], "isr": []})[kw] = int(args[1], 0)
                elif kw in ("root", "isr", "report"):
                    self.images.setdefault(args[0], {"roots": [], "isr": []}).setdefault(
                        {"root": "roots", "isr": "isr", "report": "report"}[kw], []).extend(args[1:])
                elif kw == "indirect":  # "-" = no target can be set in the images
                    self.indirect.setdefault(args[0], []).extend(t for t in args[1:] if t != "-")
                elif kw == "edge":
                    self.edge.setdefault(args[0], []).extend(args[1:])
                elif kw == "extern":
                    self.extern[args[0]] = int(args[1], 0)
                elif kw == "exception_frame":
                    self.exception_frame = int(args[0], 0)
                elif kw == "ram_goal":
                    self.ram_goal = int(args[0], 0)
                else:
                    raise ValueError(kw)
            except (IndexError, ValueError):
                sys.exit(f"{path}:{n}: cannot parse: {raw.strip()}")


class Analysis:
    def __init__(self, graph, budgets, extern_measured, open_calls=False):
        """open_calls: calls without a .ci or a declared bound, and indirect calls
        without declared targets, count 0 bytes and are listed in self.uncounted
        (instead of being errors)."""
        self.g, self.b, self.measured = graph, budgets, extern_measured
        self.open_calls = open_calls
        self.uncounted = set()
        self.errors = []
        self.best = {}
        self.externals_used = {}
        self.indirect_seen = set()

    def children(self, title):
        kids = []
        for callee in self.g.callees(title):
            if callee == INDIRECT:
                targets = self.b.indirect.get(short(title), self.b.indirect.get(title))
                self.indirect_seen.add(short(title))
                if targets is None and self.open_calls:
                    self.uncounted.add(f"indirect call in {short(title)}")
                    continue
                if targets is None:
                    self.errors.append(f"indirect call in {short(title)} ({self.g.where.get(title, '?')}) "
                                       f"has no declared targets (add 'indirect {short(title)} <target>...')")
                    continue
                for t in targets:  # a target may be a pattern: test_* (Unity's RUN_TEST)
                    if any(ch in t for ch in "*?["):
                        kids += [f for f in self.g.frame if fnmatch.fnmatchcase(short(f), t)]
                    else:
                        kids.append(self.g.resolve(t))
            else:
                kids.append(self.g.resolve(callee) if callee not in self.g.frame else callee)
        kids += [self.g.resolve(t) for t in self.b.edge.get(short(title), [])]
        return kids

    def own(self, title):
        if title in self.g.frame:
            size, qual = self.g.frame[title]
            if "dynamic" in qual and "bounded" not in qual:
                self.errors.append(f"{short(title)}: unbounded dynamic stack ({qual})")
            return size
        name = short(title)
        if name in self.b.extern:
            self.externals_used[name] = self.b.extern[name]
            return self.b.extern[name]
        if self.open_calls:
            self.uncounted.add(name)
            return 0
        self.errors.append(f"call to {name}: no .ci and no declared bound (add 'extern {name} <bytes>')")
        return 0

    def worst(self, root):
        """(bytes, path) of the deepest call chain from root (iterative DFS)."""
        root = self.g.resolve(root)
        state, order = {}, [(root, False)]
        while order:
            fn, done = order.pop()
            if done:
                own = self.own(fn)
                kids = [(self.best[c][0], c) for c in self.children(fn) if c in self.best]
                sub, child = max(kids) if kids else (0, None)
                self.best[fn] = (own + sub, child)
                state[fn] = 2
                continue
            if state.get(fn) == 2 or fn in self.best:
                continue
            if state.get(fn) == 1:
                self.errors.append(f"recursion through {short(fn)}")
                continue
            state[fn] = 1
            order.append((fn, True))
            if fn in self.g.frame:
                for c in self.children(fn):
                    if state.get(c) != 2 and c not in self.best:
                        order.append((c, False))
        path, fn = [], root
        while fn is not None:
            f = self.g.frame.get(fn)
            path.append((short(fn), f[0] if f else self.b.extern.get(short(fn), 0),
                         "" if f else " (declared bound)"))
            fn = self.best[fn][1]
        return self.best[root][0], path


# ---- the image: linked objects, sizes, disassembly ------------------------------------

def linked_ci_files(elf):
    """.ci files of the objects and in-tree archives the map says were linked."""
    mapf = elf + ".map"
    if not os.path.isfile(mapf):
        sys.exit(f"stack-budget: {mapf} missing (the link writes it: -Wl,-Map)")
    build = os.path.dirname(os.path.dirname(os.path.abspath(elf)))  # <build>/bin/x.elf
    cis, missing = [], []
    for line in open(mapf, errors="replace"):
        if not line.startswith("LOAD "):
            continue
        obj = line[5:].strip()
        path = obj if os.path.isabs(obj) else os.path.join(build, obj)
        if obj.endswith((".obj", ".o")):
            ci = re.sub(r"\.(obj|o)$", ".ci", path)
            (cis if os.path.isfile(ci) else missing).append(ci)
        elif obj.endswith(".a") and os.path.abspath(path).startswith(build + os.sep):
            lib = os.path.basename(path)[3:-2]  # libmd_core.a -> md_core
            tdir = os.path.join(os.path.dirname(path), "CMakeFiles", lib + ".dir")
            found = [os.path.join(d, f) for d, _, fs in os.walk(tdir) for f in fs if f.endswith(".ci")]
            if not found:
                missing.append(tdir + "/*.ci")
            cis += found
    return sorted(set(cis)), missing


def tool(name):
    return os.environ.get("MD_ARM_PREFIX", "arm-none-eabi-") + name


def static_ram(elf):
    out = subprocess.run([tool("size"), "-A", "-d", elf], capture_output=True, text=True, check=True).stdout
    sec = {}
    for line in out.splitlines():
        p = line.split()
        if len(p) >= 2 and p[0].startswith(".") and p[1].isdigit():
            sec[p[0]] = int(p[1])
    return sec.get(".data", 0), sec.get(".bss", 0), sec


FUNC_RE = re.compile(r"^[0-9a-f]+ <([^>]+)>:$")
PUSH_RE = re.compile(r"\t(push|stmdb)(\.w)?\s+(sp!,\s*)?\{([^}]*)\}")
VPUSH_RE = re.compile(r"\tvpush\s+\{([^}]*)\}")
SUBSP_RE = re.compile(r"\tsub(s|\.w)?\s+sp,\s*(sp,\s*)?#(\d+)")
CALL_RE = re.compile(r"\t(bl|blx|b\.w|b)\s+[0-9a-f]+ <([^>+]+)>")


def reg_count(regs):
    n = 0
    for part in regs.split(","):
        part = part.strip()
        m = re.match(r"([rds])(\d+)-[rds](\d+)", part)
        n += (int(m.group(3)) - int(m.group(2)) + 1) if m else (1 if part else 0)
    return n


def measure_externals(elf, names):
    """Stack of library functions from the image's disassembly: prologue
    (push/stmdb 4 B per register, vpush 8 B per d-register, sub sp) plus the
    deepest chain of bl/b.w calls to other functions."""
    out = subprocess.run([tool("objdump"), "-d", "--no-show-raw-insn", elf],
                         capture_output=True, text=True, check=True).stdout
    own, calls, cur = {}, {}, None
    for line in out.splitlines():
        m = FUNC_RE.match(line)
        if m:
            cur = m.group(1)
            own[cur], calls[cur] = 0, set()
            continue
        if cur is None:
            continue
        m = PUSH_RE.search(line)
        if m and (m.group(1) == "push" or m.group(3)):
            own[cur] += 4 * reg_count(m.group(4))
        m = VPUSH_RE.search(line)
        if m:
            own[cur] += 8 * reg_count(m.group(1))
        m = SUBSP_RE.search(line)
        if m:
            own[cur] += int(m.group(3))
        m = CALL_RE.search(line)
        if m and m.group(2) != cur:
            calls[cur].add(m.group(2))
    memo = {}

    def depth(fn, seen=()):  # library call chains are shallow; guarded against cycles
        if fn in memo:
            return memo[fn]
        if fn in seen or fn not in own:
            return 0
        d = own[fn] + max([depth(c, seen + (fn,)) for c in calls[fn]] or [0])
        memo[fn] = d
        return d
    return {n: depth(n) for n in names if n in own}


def load_graph(elf, name):
    """The image's call graph from its objects' .ci files, or None (reported)."""
    cis, missing = linked_ci_files(elf)
    if missing:
        print(f"stack-budget: {name}: no -fcallgraph-info output for: " + ", ".join(
            os.path.relpath(m, ROOT) for m in missing), file=sys.stderr)
        print("  (build with -fcallgraph-info=su: tests/analysis/CMakeLists.txt adds it)", file=sys.stderr)
        return None
    g = CallGraph()
    for ci in cis:
        g.read_ci(ci)
    print(f"== {name}: {len(cis)} call-graph files, {len(g.frame)} functions")
    return g


def worst_stack(img, budgets, an, verbose):
    """Worst thread root plus every handler once (and its exception frame), printed."""
    total = 0
    for root in img["roots"]:
        depth, path = an.worst(root)
        total = max(total, depth)
        print(f"  thread root {root}: {depth} B")
        for fn, size, note in path:
            print(f"      {size:6d}  {fn}{note}")
    for root in img.get("report", []):
        depth, _ = an.worst(root)
        print(f"  (entry {root}: {depth} B, included above)")
    for root in img["isr"]:
        depth, path = an.worst(root)
        total += depth + budgets.exception_frame
        print(f"  handler {root}: {depth} B + exception frame {budgets.exception_frame} B")
        if verbose:
            for fn, size, note in path:
                print(f"      {size:6d}  {fn}{note}")
    return total


def check_declarations(an, budgets, measured, verbose):
    """Declared library bounds against the disassembly; unused indirect declarations."""
    for ext, declared in sorted(an.externals_used.items()):
        meas = measured.get(ext)
        if meas is None:
            print(f"  extern {ext}: declared {declared} B (not in the image: inlined or unused)")
        elif meas > declared:
            an.errors.append(f"extern {ext}: disassembly says {meas} B, declared bound {declared} B")
        elif verbose:
            print(f"  extern {ext}: declared {declared} B, disassembly {meas} B")
    for caller in sorted(set(budgets.indirect) - an.indirect_seen):
        print(f"  note: 'indirect {caller}' declared but no indirect call of it is on a checked path")


def check_ram(elf, img, budgets):
    """Static RAM (.data + .bss) against the image's budget, printed; True if within."""
    data, bss, _ = static_ram(elf)
    ram = data + bss
    rb = img.get("ram")
    verdict = "ok" if rb is not None and ram <= rb else "OVER BUDGET"
    goal = getattr(budgets, "ram_goal", None)
    print(f"  static RAM {ram} B (.data {data} + .bss {bss}) / budget {rb} B: {verdict}"
          + (f"  (project goal {goal} B)" if goal else ""))
    return verdict == "ok"


def check_image(elf, budgets, verbose):
    name = os.path.basename(elf)
    name = name[:-4] if name.endswith(".elf") else name
    pattern = next((p for p in budgets.images if fnmatch.fnmatchcase(name, p)), None)
    if pattern is None:
        print(f"stack-budget: {name}: no budget in {os.path.relpath(budgets.path, ROOT)}", file=sys.stderr)
        return False
    img = budgets.images[pattern]
    g = load_graph(elf, name)
    if g is None:
        return False
    measured = measure_externals(elf, list(budgets.extern))
    an = Analysis(g, budgets, measured)
    cyc = g.cycles()
    for c in cyc:
        print(f"stack-budget: {name}: RECURSION " + " -> ".join(c), file=sys.stderr)
    ok = not cyc
    total = worst_stack(img, budgets, an, verbose)
    check_declarations(an, budgets, measured, verbose)
    for e in sorted(set(an.errors)):
        print(f"stack-budget: {name}: {e}", file=sys.stderr)
        ok = False
    budget = img.get("stack")
    verdict = "ok" if budget is not None and total <= budget else "OVER BUDGET"
    print(f"  worst-case stack {total} B (thread + every handler once) / budget {budget} B: {verdict}")
    return check_ram(elf, img, budgets) and ok and verdict == "ok"


def ci_files(args):
    """The .ci files named, and every .ci below a folder named (sorted)."""
    files = []
    for arg in args:
        if os.path.isdir(arg):
            files += sorted(os.path.join(d, f) for d, _, fs in os.walk(arg) for f in fs if f.endswith(".ci"))
        else:
            files.append(arg)
    return files


def check_cycles(files):
    g = CallGraph()
    for f in files:
        g.read_ci(f)
    cyc = g.cycles()
    for c in cyc:
        print("RECURSION " + " -> ".join(c), file=sys.stderr)
    print(f"stack-budget: {len(files)} .ci files, {len(g.frame)} functions, {len(cyc)} cycle(s)")
    return 1 if cyc else 0


def report_root(root, files):
    """Worst-case stack of one function from .ci files alone (no image, no budget)."""
    g = CallGraph()
    for f in files:
        g.read_ci(f)
    if g.resolve(root) not in g.frame:
        print(f"stack-budget: {root}: not defined in the {len(files)} .ci files", file=sys.stderr)
        return 2
    an = Analysis(g, Budgets(None), {}, open_calls=True)
    depth, path = an.worst(root)
    print(f"worst-case stack of {root}: {depth} B ({len(files)} call-graph files, {len(g.frame)} functions)")
    for fn, size, _ in path:
        print(f"  {size:6d}  {fn}")
    print("not counted (0 B: no .ci, or a call through a pointer): " + (", ".join(sorted(an.uncounted)) or "none"))
    for e in sorted(set(an.errors)):
        print(f"stack-budget: {root}: {e}", file=sys.stderr)
    return 1 if an.errors else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--budgets", default=DEFAULT_BUDGETS)
    ap.add_argument("--cycles-only", action="store_true", help="arguments are .ci files: fail on a cycle")
    ap.add_argument("--root", metavar="FUNCTION", help="arguments are .ci files or folders: FUNCTION's worst case")
    ap.add_argument("--verbose", "-v", action="store_true")
    ap.add_argument("files", nargs="+")
    a = ap.parse_args()
    if a.cycles_only:
        return check_cycles(a.files)
    if a.root:
        return report_root(a.root, ci_files(a.files))
    budgets = Budgets(a.budgets)
    ok = True
    for elf in a.files:
        if not os.path.isfile(elf):
            print(f"stack-budget: {elf}: no such file", file=sys.stderr)
            return 2
        ok = check_image(elf, budgets, a.verbose) and ok
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
