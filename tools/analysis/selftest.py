#!/usr/bin/env python3
"""Self-test of the analysis checkers (ctest analysis_recursion_detected).

Compiles small C programs with gcc -fcallgraph-info=su and checks that
scripts/stack-budget.py finds direct and mutual recursion (exit 1), accepts an
acyclic program (exit 0), that the worst path sums the frames of the
deepest chain, and that --root prints that sum and lists a call without a .ci.
A checker that cannot fail would prove nothing.
"""
import importlib.util
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SB = os.path.join(ROOT, "scripts", "stack-budget.py")

PROGRAMS = {
    "direct": ("int f(int n);\nint f(int n) { return n > 0 ? f(n - 1) + 1 : 0; }\n", 1),
    "mutual": ("int a(int n);\nint b(int n);\n"
               "int a(int n) { return n > 0 ? b(n - 1) : 0; }\n"
               "int b(int n) { return n > 0 ? a(n - 1) : 1; }\n", 1),
    "acyclic": ("int leaf(volatile int *p);\nint mid(void);\nint top(void);\n"
                "int leaf(volatile int *p) { volatile int big[64]; big[0] = *p; return big[0]; }\n"
                "int mid(void) { volatile int x = 1; return leaf(&x); }\n"
                "int ext(int n);\n"
                "int top(void) { return mid() + leaf(0) + ext(1); }\n", 0),
}


def ci_of(tmp, name, src):
    c = os.path.join(tmp, name + ".c")
    open(c, "w").write(src)
    obj = os.path.join(tmp, name + ".o")
    subprocess.run(["gcc", "-O0", "-fcallgraph-info=su", "-c", c, "-o", obj], check=True)
    return os.path.join(tmp, name + ".ci")


def main():
    failures = 0
    with tempfile.TemporaryDirectory() as tmp:
        for name, (src, want) in PROGRAMS.items():
            ci = ci_of(tmp, name, src)
            r = subprocess.run([sys.executable, SB, "--cycles-only", ci], capture_output=True, text=True)
            ok = r.returncode == want
            failures += not ok
            print(f"{'ok  ' if ok else 'FAIL'} {name}: exit {r.returncode} (want {want}) {r.stderr.strip()}")
        spec = importlib.util.spec_from_file_location("sb", SB)
        sb = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sb)
        g = sb.CallGraph()
        g.read_ci(os.path.join(tmp, "acyclic.ci"))
        budgets_file = os.path.join(tmp, "b.txt")
        open(budgets_file, "w").write("stack x 1\n")
        an = sb.Analysis(g, sb.Budgets(budgets_file), {})
        depth, path = an.worst("top")
        want = g.frame["top"][0] + g.frame["mid"][0] + g.frame["leaf"][0]
        ok = depth == want and [p[0] for p in path] == ["top", "mid", "leaf"] and g.frame["leaf"][0] > g.frame["mid"][0]
        failures += not ok
        print(f"{'ok  ' if ok else 'FAIL'} worst path top->mid->leaf = {depth} B (want {want})")
        r = subprocess.run([sys.executable, SB, "--root", "top", tmp], capture_output=True, text=True)
        ok = (r.returncode == 0 and f"worst-case stack of top: {want} B" in r.stdout
              and r.stdout.rstrip().endswith(": ext"))
        failures += not ok
        print(f"{'ok  ' if ok else 'FAIL'} --root top: exit {r.returncode}, {r.stdout.splitlines()[:1]} (want {want} B, ext)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
