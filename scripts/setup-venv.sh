#!/usr/bin/env bash
# Creates (or refreshes) the project's Python venv at .venv from requirements.txt.
# Idempotent: a venv whose requirements are already installed is left as is.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
venv="${MD_VENV:-$root/.venv}"
stamp="$venv/.requirements.sha256"
reqs=("$root/requirements.txt")
[ -f "$root/tests/python/requirements.txt" ] && reqs+=("$root/tests/python/requirements.txt")
want=$(cat "${reqs[@]}" | sha256sum | cut -d' ' -f1)
if [ -x "$venv/bin/python" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    exit 0
fi
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
for r in "${reqs[@]}"; do
    "$venv/bin/pip" install --quiet -r "$r"
done
echo "$want" > "$stamp"
echo "setup-venv: $venv ready" >&2
