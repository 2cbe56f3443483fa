#!/bin/sh
# A recording whose sidecar (recording.json) is not valid JSON must end the
# tool with exit status 1 and exactly one line on stderr,
# "TOOL: PATH: reason", naming the file and the byte offset of the error;
# never a crash or a sanitizer report (the exit status alone cannot tell:
# AddressSanitizer also exits 1, so the test checks the one line).
# usage: test_sidecar_cli.sh MHTC_REPLAY
set -eu
REPLAY=${1:?usage: test_sidecar_cli.sh MHTC_REPLAY}
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# check NAME FILE REASON JSON [BIN_BYTES]: writes W/NAME/recording.json (JSON)
# and a zero-filled W/NAME/recording.bin, runs the tool; the one stderr line
# must be "mhtc-replay: W/NAME/FILE: ..." and contain REASON.
check() {
    name=$1 file=$2 reason=$3 json=$4 bytes=${5:-4000}
    d="$W/$name"
    mkdir -p "$d"
    printf '%s' "$json" > "$d/recording.json"
    head -c "$bytes" /dev/zero > "$d/recording.bin"
    rc=0
    "$REPLAY" --recording "$d/recording.json" --out "$d/out" --quiet 2> "$d/stderr" || rc=$?
    [ "$rc" -eq 1 ] || { cat "$d/stderr" >&2; fail "$name: exit status $rc, expected 1"; }
    [ "$(wc -l < "$d/stderr")" -eq 1 ] || { cat "$d/stderr" >&2; fail "$name: stderr is not one line"; }
    grep -qF "mhtc-replay: $d/$file: " "$d/stderr" || { cat "$d/stderr" >&2; fail "$name: does not name $file"; }
    grep -qF -- "$reason" "$d/stderr" || { cat "$d/stderr" >&2; fail "$name: lacks '$reason'"; }
    echo "ok $name: $(cat "$d/stderr")"
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
echo "test_sidecar_cli: OK"
