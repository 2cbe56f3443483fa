#!/bin/sh
# Run one Cortex-M7 ELF on QEMU's mps2-an500 board and return the program's
# exit status (semihosting SYS_EXIT_EXTENDED, see firmware/port/cortex_m).
#
#   run-qemu.sh [--expect-exit N] [--expect-output REGEX] [--arg WORD]... <elf>
#
# Without options the script's status is the program's (0 = pass). With
# --expect-exit it is 0 only if the program ended with status N (used by the
# tests that check that failures and faults are reported), and with
# --expect-output only if the output also matches REGEX (grep -E). Each
# --arg WORD is one word of the program's semihosting command line (after the
# program name; no commas).
# Env: MD_QEMU (default qemu-system-arm), MD_QEMU_TIMEOUT seconds (default 120;
# a hang ends with status 124).
set -u
expect_exit=""
expect_output=""
sh_args=""
while [ $# -gt 1 ]; do
    case "$1" in
        --expect-exit) expect_exit="$2"; shift 2 ;;
        --expect-output) expect_output="$2"; shift 2 ;;
        --arg) sh_args="$sh_args,arg=$2"; shift 2 ;;
        *) break ;;
    esac
done
if [ $# -ne 1 ] || [ ! -f "$1" ]; then
    echo "usage: $0 [--expect-exit N] [--expect-output REGEX] [--arg WORD]... <elf>" >&2
    exit 2
fi
elf="$1"
qemu="${MD_QEMU:-qemu-system-arm}"
limit="${MD_QEMU_TIMEOUT:-120}"

out="$(mktemp)"
trap 'rm -f "$out"' EXIT
# -nographic without a serial/monitor on stdio: the only console is
# semihosting, which QEMU writes to its stdout.
timeout --foreground -k 5 "$limit" "$qemu" -M mps2-an500 -nographic -monitor none -serial null \
    -semihosting-config "enable=on,target=native${sh_args:+,arg=$(basename "$1")$sh_args}" -kernel "$elf" </dev/null >"$out" 2>&1
status=$?
cat "$out"
if [ "$status" -eq 124 ]; then
    echo "run-qemu.sh: $elf timed out after ${limit}s" >&2
fi

if [ -n "$expect_output" ] && ! grep -Eq "$expect_output" "$out"; then
    echo "run-qemu.sh: output does not match /$expect_output/ (exit status $status)" >&2
    exit 1
fi
if [ -n "$expect_exit" ]; then
    if [ "$status" -eq "$expect_exit" ]; then
        echo "run-qemu.sh: exit status $status as expected"
        exit 0
    fi
    echo "run-qemu.sh: exit status $status, expected $expect_exit" >&2
    exit 1
fi
exit "$status"
