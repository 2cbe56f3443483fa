#!/bin/sh
# A bad recording (a sidecar recording.json that is not JSON or has a bad
# field, a binary that does not fit it) must end the tool with exit status 1
# and exactly one line on stderr, "TOOL: PATH: reason", naming the file and
# the byte offset or field; never a crash or a sanitizer report (the exit
# status alone cannot tell: AddressSanitizer also exits 1, so the test checks
# the one line). Every error class of the reader itself: test_recording.
# Both tools read recordings with tools/recording; each case runs through
# both (cluster-consistency needs the sidecar's interval list, so the cases
# without one run through mhtc-replay alone).
# usage: test_sidecar_cli.sh MHTC_REPLAY [CLUSTER_CONSISTENCY]
set -eu
REPLAY=${1:?usage: test_sidecar_cli.sh MHTC_REPLAY [CLUSTER_CONSISTENCY]}
CC=${2:-}
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# expect TOOL DIR FILE STATUS REASON [ARGS...]: runs TOOL on DIR; it must exit
# with STATUS and write one stderr line "TOOL: DIR/FILE: ..." containing REASON.
expect() {
    tool=$1 d=$2 file=$3 status=$4 reason=$5
    shift 5
    rc=0
    case $tool in
        mhtc-replay) "$REPLAY" --recording "$d/recording.json" --out "$d/out" --quiet "$@" 2> "$d/stderr" || rc=$? ;;
        cluster-consistency) "$CC" "$d" "$@" > /dev/null 2> "$d/stderr" || rc=$? ;;
    esac
    [ "$rc" -eq "$status" ] || { cat "$d/stderr" >&2; fail "$tool $d: exit status $rc, expected $status"; }
    [ "$(wc -l < "$d/stderr")" -eq 1 ] || { cat "$d/stderr" >&2; fail "$tool $d: stderr is not one line"; }
    grep -qF "$tool: $d/$file: " "$d/stderr" || { cat "$d/stderr" >&2; fail "$tool $d: does not name $file"; }
    grep -qF -- "$reason" "$d/stderr" || { cat "$d/stderr" >&2; fail "$tool $d: lacks '$reason'"; }
    echo "ok $(cat "$d/stderr")"
}

# mkrec NAME JSON [BIN_BYTES]: W/NAME/recording.json and a zero-filled recording.bin
mkrec() {
    mkdir -p "$W/$1"
    printf '%s' "$2" > "$W/$1/recording.json"
    head -c "${3:-4000}" /dev/zero > "$W/$1/recording.bin"
}

# check NAME FILE REASON JSON [BIN_BYTES]: exit 1 and the one line from each tool
check() {
    mkrec "$1" "$4" "${5:-4000}"
    expect mhtc-replay "$W/$1" "$2" 1 "$3"
    if [ -n "$CC" ]; then expect cluster-consistency "$W/$1" "$2" 1 "$3"; fi
}

# not JSON: the offset is of the first byte the parser could not take
check nan recording.json 'at byte offset 23 (line 1, column 24), in "sampling_frequency": NaN is not a JSON number' \
    '{"sampling_frequency": NaN, "num_channels": 1, "dtype": "int16"}'
check infinity recording.json 'at byte offset 23 (line 1, column 24), in "sampling_frequency": Infinity is not a JSON number' \
    '{"sampling_frequency": Infinity, "num_channels": 1, "dtype": "int16"}'
check truncated recording.json 'at byte offset 30 (line 1, column 31): unexpected end of file' \
    '{"sampling_frequency": 30000, '
check second_line recording.json "at byte offset 48 (line 2, column 19), in \"num_channels\": unexpected character 'o'" \
    '{"sampling_frequency": 30000,
  "num_channels": one, "dtype": "int16"}'
check trailing recording.json 'at byte offset 67 (line 1, column 68): text after the JSON value' \
    '{"sampling_frequency": 30000, "num_channels": 1, "dtype": "int16"} x'
check empty recording.json 'empty file' ''
check array recording.json 'not a JSON object: the top level is an array' '[30000, 1, "int16"]'

# fields
check rate_missing recording.json 'field "sampling_frequency": missing' '{"num_channels": 1, "dtype": "int16"}'
check rate_negative recording.json 'field "sampling_frequency": must be > 0 Hz, got -30000' \
    '{"sampling_frequency": -30000, "num_channels": 1, "dtype": "int16"}'
check rate_zero recording.json 'field "sampling_frequency": must be > 0 Hz, got 0' \
    '{"sampling_frequency": 0, "num_channels": 1, "dtype": "int16"}'
check rate_string recording.json 'field "sampling_frequency": not a number (a string)' \
    '{"sampling_frequency": "30 kHz", "num_channels": 1, "dtype": "int16"}'
check channels recording.json 'field "num_channels": 1.5 is not an integer 1..1024' \
    '{"sampling_frequency": 30000, "num_channels": 1.5, "dtype": "int16"}'
check dtype recording.json 'field "dtype": "uint16" is not supported (int16 or float32, little-endian)' \
    '{"sampling_frequency": 30000, "num_channels": 1, "dtype": "uint16"}'
check gain recording.json 'field "gain_uV": must be > 0, got 0' \
    '{"sampling_frequency": 30000, "num_channels": 1, "dtype": "int16", "gain_uV": 0}'
check interval recording.json 'field "intervals[0].num_samples": missing' \
    '{"sampling_frequency": 30000, "num_channels": 1, "dtype": "int16", "intervals": [{"start_sample": 0}]}'

# the binary
check odd_size recording.bin '4001 bytes is not a whole number of 4-byte frames (2 channel(s) of int16)' \
    '{"sampling_frequency": 1000, "num_channels": 2, "dtype": "int16"}' 4001
check odd_size_f32 recording.bin '4002 bytes is not a whole number of 4-byte frames (1 channel(s) of float32)' \
    '{"sampling_frequency": 1000, "num_channels": 1, "dtype": "float32"}' 4002
check empty_bin recording.bin 'empty (0 bytes)' '{"sampling_frequency": 1000, "num_channels": 1, "dtype": "int16"}' 0
check no_bin other.bin 'cannot open: No such file or directory' \
    '{"sampling_frequency": 1000, "num_channels": 1, "dtype": "int16", "file": "other.bin"}'
check num_samples recording.json 'field "num_samples": 5000, but' \
    '{"sampling_frequency": 1000, "num_channels": 1, "dtype": "int16", "num_samples": 5000}'

# no interval list: mhtc-replay cuts the signal (here too short), cluster-consistency needs the list
mkrec no_list '{"sampling_frequency": 1000, "num_channels": 1, "dtype": "int16"}'
expect mhtc-replay "$W/no_list" recording.json 1 'no interval of 10 s fits in the 2000 samples per channel'
if [ -n "$CC" ]; then
    expect cluster-consistency "$W/no_list" recording.json 1 'field "intervals": missing'
fi
# a channel the recording lacks: an input error for mhtc-replay, a usage error (2) for cluster-consistency
mkrec channel '{"sampling_frequency": 1000, "num_channels": 2, "dtype": "int16", "intervals": [{"start_sample": 0, "num_samples": 500}]}'
expect mhtc-replay "$W/channel" recording.json 1 'channel 2 requested, but the recording has 2 channel(s)' --channel 2
if [ -n "$CC" ]; then
    expect cluster-consistency "$W/channel" recording.json 2 'channel 2 requested, but the recording has 2 channel(s)' \
        --channel 2
fi
echo "test_sidecar_cli: OK"
