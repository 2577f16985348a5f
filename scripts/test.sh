#!/usr/bin/env bash
# Run the test suite from the project venv (set up on first use).
# Usage: scripts/test.sh [pytest args...]   e.g. scripts/test.sh -k coning -x
# pytest's exit code is returned unchanged.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup_env.sh"
cd "$ROOT"
PY="$ROOT/.venv/bin/python"
args=(-q)
# default per-test timeout; a --timeout=N given by the caller takes precedence
if "$PY" -c 'import pytest_timeout' >/dev/null 2>&1; then
    args+=(-o timeout=300)
fi
exec "$PY" -m pytest "${args[@]}" test "$@"
