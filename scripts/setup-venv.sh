#!/usr/bin/env bash
# Creates (or refreshes) the project's Python venv at .venv ($MD_VENV if set):
# requirements.txt, tests/python/requirements.txt and the project's own
# package python/ (importable as `microdrive`, installed editable).
# Idempotent: a venv whose stamp matches those files is left as is.
#   scripts/setup-venv.sh           make or refresh it
#   scripts/setup-venv.sh --check   exit 0 if it is ready, 1 if missing or stale (says which)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
venv="${MD_VENV:-$root/.venv}"
stamp="$venv/.requirements.sha256"
reqs=("$root/requirements.txt")
[ -f "$root/tests/python/requirements.txt" ] && reqs+=("$root/tests/python/requirements.txt")
want=$(cat "${reqs[@]}" "$root/python/pyproject.toml" | sha256sum | cut -d' ' -f1)
ready() { [ -x "$venv/bin/python" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; }
if [ "${1:-}" = "--check" ]; then
    ready && exit 0
    if [ -x "$venv/bin/python" ]; then
        echo "setup-venv: $venv is stale (requirements or python/pyproject.toml changed): run scripts/setup-venv.sh" >&2
    else
        echo "setup-venv: no venv at $venv: run scripts/setup-venv.sh" >&2
    fi
    exit 1
fi
ready && exit 0
if ! python3 -c 'import ensurepip' 2>/dev/null; then
    echo "setup-venv: python3 cannot make a venv (no ensurepip): install python3-venv (Debian/Ubuntu:" \
         "apt-get install python3-venv), then run this again" >&2
    exit 1
fi
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
for r in "${reqs[@]}"; do
    "$venv/bin/pip" install --quiet -r "$r"
done
# (setuptools warns about every editable install; its output is shown only on failure)
"$venv/bin/pip" install --quiet -e "$root/python" >"$venv/.pip-python.log" 2>&1 || {
    cat "$venv/.pip-python.log" >&2
    exit 1
}
echo "$want" > "$stamp"
echo "setup-venv: $venv ready" >&2
