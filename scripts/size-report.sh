#!/bin/sh
# Static memory of a Cortex-M firmware image.
#
#   scripts/size-report.sh <elf> [<map>]
#
# Prints (1) the image's flash and static RAM from its sections:
#     flash      = .isr_vector + .text + .rodata + ARM unwind + .init_array + .data (load image)
#     static RAM = .data + .bss        (the stack and the zero-size heap separately)
# and (2), if a linker map is given (default <elf>.map), the same per object
# file and per library, so each module's share of RAM and flash is visible.
# Budgets for a percentage line: MD_FLASH_BUDGET / MD_RAM_BUDGET in bytes
# (default 2 MiB / 1 MiB, an STM32H743-class Cortex-M7; the QEMU board itself
# has 4 MiB + 4 MiB). Informational: the exit status is 0 unless a tool fails.
set -eu
if [ $# -lt 1 ] || [ ! -f "$1" ]; then
    echo "usage: $0 <elf> [<map>]" >&2
    exit 2
fi
elf="$1"
map="${2:-$elf.map}"
size_tool="${SIZE:-arm-none-eabi-size}"
flash_budget="${MD_FLASH_BUDGET:-2097152}"
ram_budget="${MD_RAM_BUDGET:-1048576}"

echo "== size report: $(basename "$elf")"
"$size_tool" -A -d "$elf" | awk -v fb="$flash_budget" -v rb="$ram_budget" '
    $1 == ".isr_vector" || $1 == ".text" || $1 == ".rodata" || $1 == ".ARM.extab" ||
    $1 == ".ARM.exidx" || $1 == ".init_array" { flash += $2; code[$1] = $2 }
    $1 == ".data"  { data = $2 }
    $1 == ".bss"   { bss = $2 }
    $1 == ".stack" { stack = $2 }
    $1 == ".heap"  { heap = $2 }
    $1 == ".psram" { psram = $2 }
    END {
        flash += data
        printf "  text %d  rodata %d  data %d  bss %d  (bytes)\n", code[".text"] + code[".isr_vector"], code[".rodata"], data, bss
        printf "  flash      %8d B  (%.1f%% of %d)\n", flash, 100.0 * flash / fb, fb
        printf "  static RAM %8d B  (%.1f%% of %d)  = .data %d + .bss %d\n", data + bss, 100.0 * (data + bss) / rb, rb, data, bss
        printf "  stack      %8d B  reserved (high-water mark: printed by the image at exit)\n", stack
        printf "  heap       %8d B\n", heap
        if (psram > 0) printf "  PSRAM      %8d B\n", psram
    }'

if [ ! -f "$map" ]; then
    echo "  (no map file $map: per-module table skipped)"
    exit 0
fi

# Per-module table from the map: input sections of the allocated output
# sections, attributed to their object file (archive members as lib(member)).
awk '
    /^Linker script and memory map/ { on = 1; next }
    !on { next }
    /^OUTPUT\(/ { exit }
    /^\.[A-Za-z_]/ { out = $1; pending = ""; next }
    function hex(s,   i, v) {
        s = tolower(s)
        sub(/^0x/, "", s)
        v = 0
        for (i = 1; i <= length(s); i++) v = v * 16 + index("0123456789abcdef", substr(s, i, 1)) - 1
        return v
    }
    function module(f,   m) {
        m = f
        sub(/^.*\//, "", m)
        return m
    }
    function add(sz, f,   cls) {
        if (sz + 0 == 0 || f == "") return
        if (out == ".data" || out == ".bss") ram[module(f)] += sz
        if (out == ".data" || out == ".text" || out == ".rodata" || out == ".isr_vector" ||
            out == ".ARM.exidx" || out == ".ARM.extab" || out == ".init_array") flash[module(f)] += sz
        seen[module(f)] = 1
    }
    /^ [.*A-Za-z_]/ {
        if ($1 == "*fill*" || $1 ~ /^\*\(/ ) { pending = ""; next }
        if (NF >= 4 && $2 ~ /^0x/) { add(hex($3), $4); pending = "" }
        else if (NF == 1) pending = $1
        next
    }
    /^  +0x/ {
        if (pending != "" && NF >= 3) add(hex($2), $3)
        pending = ""
        next
    }
    END {
        for (m in seen) {
            lib = m
            if (lib ~ /\(/) sub(/\(.*$/, "", lib); else lib = "(objects)"
            libram[lib] += ram[m]; libflash[lib] += flash[m]
            printf "M %10d %10d  %s\n", ram[m], flash[m], m
        }
        for (l in libram) printf "L %10d %10d  %s\n", libram[l], libflash[l], l
    }' "$map" > "$map.modules.tmp"

echo "  -- per library (static RAM = .data+.bss, flash incl. .data load image)"
printf "     %10s %10s  %s\n" "RAM B" "flash B" "library"
grep '^L' "$map.modules.tmp" | sort -k2,2nr -k3,3nr | awk '{ printf "     %10d %10d  %s\n", $2, $3, $4 }'
echo "  -- per object file with static RAM (largest first)"
grep '^M' "$map.modules.tmp" | awk '$2 > 0' | sort -k2,2nr | head -n 25 |
    awk '{ printf "     %10d %10d  %s\n", $2, $3, $4 }'
echo "  -- largest flash users"
grep '^M' "$map.modules.tmp" | sort -k3,3nr | head -n 10 |
    awk '{ printf "     %10d %10d  %s\n", $2, $3, $4 }'
rm -f "$map.modules.tmp"
