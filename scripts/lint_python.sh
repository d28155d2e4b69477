#!/usr/bin/env bash
# The Python of this repository linted: pyflakes' rules (`ruff check --select F`: undefined
# names, unused imports and variables, redefinitions, f-strings without fields) over the
# interop suites, their peer programs (tests/interop/peers/) and scripts/*.py. ruff from
# PyPI by hash (scripts/requirements-lint.txt) into target/tools/lint, quick when installed.
#   bash scripts/lint_python.sh
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/tools/lint
req=scripts/requirements-lint.txt
key=$(sha256sum <"$req" | cut -c1-64)
if [ "$(cat "$venv/key" 2>/dev/null)" != "$key" ]; then
    rm -rf "$venv"
    python3 -m venv "$venv"
    if ! "$venv/bin/pip" install -q --disable-pip-version-check --no-input --no-deps --require-hashes -r "$req" \
            >target/lint_setup.log 2>&1; then
        tail -n 20 target/lint_setup.log >&2
        echo "lint_python.sh: could not install ruff ($req): pip's log above" >&2
        exit 1
    fi
    echo "$key" >"$venv/key"
fi
"$venv/bin/ruff" check --no-cache --select F --target-version py311 --output-format concise tests scripts
