#!/usr/bin/env bash
# Run the test suite from the project venv (set up on first use).
# Usage: scripts/test.sh [pytest args...]   e.g. scripts/test.sh -k coning -x
# The exit code is pytest's (see the two parts below).
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
# The tests run in two parts.  Most run on every core (at most 4 workers), one file per worker
# at a time (module fixtures are built once).  The ROS graph tests (test/ros but its layout,
# colcon and import tests, and the load bench's test) measure whether nodes keep up with their
# input, so they run after, alone on the machine.  A -n N given by the caller applies to the
# first part; -n 0 runs it in one process.
# The exit code is pytest's (the first part's if it failed, else the second's).
if "$PY" -c 'import xdist' >/dev/null 2>&1; then
    workers="$("$PY" -c 'import os; print(max(1, min(4, len(os.sched_getaffinity(0)))))')"
    serial=(test/ros test/bench/test_load_bench.py)
    # test/ros files that start no graph (the layout, the colcon install, imports) run in part 1
    no_graph=(test_layout.py test_colcon_layout.py test_core_without_ros.py)
    ignore=(--ignore=test/bench/test_load_bench.py)
    for f in test/ros/test_*.py; do
        case " ${no_graph[*]} " in *" $(basename "$f") "*) ;; *) ignore+=(--ignore="$f") ;; esac
    done
    serial_ignore=()
    for f in "${no_graph[@]}"; do serial_ignore+=(--ignore="test/ros/$f"); done
    rc=0
    "$PY" -m pytest "${args[@]}" -n "$workers" --dist loadfile test "${ignore[@]}" "$@" || rc=$?
    rc2=0
    "$PY" -m pytest "${args[@]}" "${serial[@]}" "${serial_ignore[@]}" "$@" || rc2=$?
    # 5: no test selected (a -k that matches only one part) is no failure of the other part
    if [ "$rc" -eq 5 ] && [ "$rc2" -ne 5 ]; then rc=0; fi
    if [ "$rc2" -eq 5 ] && [ "$rc" -ne 5 ]; then rc2=0; fi
    if [ "$rc" -ne 0 ]; then exit "$rc"; fi
    exit "$rc2"
fi
exec "$PY" -m pytest "${args[@]}" test "$@"
