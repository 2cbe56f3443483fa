#!/bin/sh
# Static analysis of every firmware translation unit against the committed
# baseline (docs/static-analysis.md):
#
#   scripts/static-analysis.sh [--build build/dev] [--only cppcheck|clang-tidy|gcc]...
#                              [--files <path prefix>]... [--update-baseline] [-v]
#
# cppcheck (warning,style,performance,portability + MISRA C:2012 addon),
# clang-tidy (.clang-tidy), gcc -fanalyzer with -fcallgraph-info=su (a call
# graph cycle = recursion = failure). Uses <build>/compile_commands.json, so
# configure first (cmake --preset dev). Fails (exit 1) on any finding whose
# key tool|rule|file|function is not in tools/analysis/baseline.txt or whose
# count grew. Needs: cppcheck (2.10), clang-tidy (14), gcc (12), python3.
set -eu
here="$(cd "$(dirname "$0")/.." && pwd)"
for t in cppcheck clang-tidy python3; do
    if ! command -v "$t" >/dev/null 2>&1; then
        echo "static-analysis: $t not installed (apt-get install cppcheck clang-tidy)" >&2
        exit 2
    fi
done
exec python3 "$here/tools/analysis/sa.py" "$@"
