#!/bin/sh
# Checks that every C source and header is laid out as .clang-format says
# (docs/style.md): clang-format --dry-run --Werror over firmware/, common/,
# host_sim/, tools/ and tests/ (cantools output in common/protocol/generated/
# has a .clang-format of its own that turns formatting off).
#
#   scripts/check-format.sh [--fix]
#
# --fix rewrites the files instead. Exit 0 clean, 1 files to reformat, 77 (a
# skip in ctest) when clang-format 14 is not installed: other major versions
# lay some constructs out differently, so their verdict would not be ours.
set -eu
root=$(cd "$(dirname "$0")/.." && pwd)
cf=
for c in clang-format-14 clang-format; do
    if command -v "$c" >/dev/null 2>&1 && "$c" --version | grep -q 'version 14\.'; then
        cf=$c
        break
    fi
done
if [ -z "$cf" ]; then
    echo "check-format: clang-format 14 not found (Debian 12: apt install clang-format); skipped" >&2
    exit 77
fi
cd "$root"
files=$(find firmware common host_sim tools tests -name '*.[ch]' -not -path '*/generated/*' | sort)
if [ "${1:-}" = "--fix" ]; then
    # shellcheck disable=SC2086 # one word per path; no path has blanks
    exec "$cf" -i $files
fi
# shellcheck disable=SC2086
if ! "$cf" --dry-run --Werror $files 2>"${TMPDIR:-/tmp}/check-format.$$"; then
    grep -o '^[^:]*\.[ch]' "${TMPDIR:-/tmp}/check-format.$$" | sort -u | sed 's/^/check-format: not formatted: /'
    rm -f "${TMPDIR:-/tmp}/check-format.$$"
    echo "check-format: run scripts/check-format.sh --fix" >&2
    exit 1
fi
rm -f "${TMPDIR:-/tmp}/check-format.$$"
echo "check-format: $(echo "$files" | wc -l) files clean"
