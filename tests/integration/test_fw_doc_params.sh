#!/bin/sh
# docs/protocol.md's parameter table must be what the firmware's table prints.
#   test_fw_doc_params.sh PATH/TO/microdrive-fw PATH/TO/docs/protocol.md
# Regenerate after changing firmware/app/md_params.c: replace the lines
# between the params:begin/end markers with `microdrive-fw --params-markdown`.
set -eu
fw=${1:?usage: test_fw_doc_params.sh FW DOC}
doc=${2:?usage: test_fw_doc_params.sh FW DOC}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$fw" --params-markdown >"$tmp/want"
sed -n '/<!-- params:begin -->/,/<!-- params:end -->/p' "$doc" | sed '1d;$d' >"$tmp/have"
[ -s "$tmp/have" ] || { echo "FAIL: no params:begin/end section in $doc" >&2; exit 1; }
if ! diff -u "$tmp/have" "$tmp/want"; then
    echo "FAIL: $doc parameter table differs from the firmware's (diff above: - doc, + firmware)" >&2
    exit 1
fi
echo "test_fw_doc_params: OK ($(wc -l <"$tmp/want") lines)"
