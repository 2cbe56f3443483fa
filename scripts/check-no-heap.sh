#!/bin/sh
# Fail if any given binary defines or references a heap function.
#
#   scripts/check-no-heap.sh <elf-or-object>...
#
# The firmware never allocates: md_no_heap.h poisons malloc & co. in every
# firmware source, and this check covers what the preprocessor cannot see,
# i.e. heap use pulled in by a library function (printf, strdup, qsort of
# some libcs...). Works on ARM ELFs (arm-none-eabi-nm) and host binaries (nm),
# chosen per file from the ELF machine field; override with NM=<tool>.
# Not for sanitizer builds: ASan/UBSan runtimes define malloc themselves.
# Exit status: 0 clean, 1 heap symbol found, 2 usage or tool error.
set -u
if [ $# -eq 0 ]; then
    echo "usage: $0 <binary>..." >&2
    exit 2
fi

# Names (after stripping a @VERSION suffix) that mean "this binary has a heap".
HEAP_RE='^_?_?(malloc|calloc|realloc|reallocarray|free|cfree|memalign|aligned_alloc|posix_memalign|valloc|pvalloc|malloc_usable_size|_malloc_r|_calloc_r|_realloc_r|_reallocf_r|_free_r|_memalign_r|_valloc_r|_pvalloc_r|_malloc_usable_size_r|nano_malloc|nano_free|sbrk|_sbrk|_sbrk_r|libc_malloc|libc_free|libc_calloc|libc_realloc)$'

pick_nm() {
    if [ -n "${NM:-}" ]; then
        echo "$NM"
        return
    fi
    # ELF e_machine (offset 18, little-endian): 0x28 = ARM.
    machine="$(od -An -tx1 -j18 -N2 "$1" 2>/dev/null | tr -d ' \n')"
    if [ "$machine" = "2800" ]; then
        echo arm-none-eabi-nm
    else
        echo nm
    fi
}

status=0
for bin in "$@"; do
    if [ ! -f "$bin" ]; then
        echo "check-no-heap: $bin: no such file" >&2
        status=2
        continue
    fi
    nm_tool="$(pick_nm "$bin")"
    if ! syms="$("$nm_tool" "$bin" 2>&1)"; then
        echo "check-no-heap: $nm_tool failed on $bin: $syms" >&2
        status=2
        continue
    fi
    hits="$(printf '%s\n' "$syms" | awk -v re="$HEAP_RE" '
        { name = $NF; sub(/@.*/, "", name); if (name ~ re) print "  " $0 }')"
    if [ -n "$hits" ]; then
        echo "check-no-heap: FAIL $bin uses the heap:" >&2
        printf '%s\n' "$hits" >&2
        if [ -f "$bin.map" ]; then
            echo "  pulled in by (from $bin.map):" >&2
            grep -B1 -E '\((_?malloc|_?free|_?calloc|_?realloc|_malloc_r|_free_r|_sbrk)\)' "$bin.map" \
                | sed 's/^/    /' >&2
        fi
        [ "$status" -eq 0 ] && status=1
    else
        echo "check-no-heap: ok $bin"
    fi
done
exit "$status"
